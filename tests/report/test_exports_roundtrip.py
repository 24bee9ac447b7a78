"""Exports a controller takes, read back by independent readers: the URDF by yourdfpy, the
ur_description kinematics by PyYAML, the DH table (standard DH, converted from the model's
modified DH) by a parser here; each one's forward kinematics equals the model's at the
exported point to 1e-9 of the model's units, at random joint angles, for the shipped UR10
model and the shipped UR5 model. The model's kinematics are composed here by hand from its
own constants and the exported point (studies/kinematics.py, modified DH), not from the
export's code."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.report.export_point import export_point
from calib_dsl.studies.kinematics import chain, dh_matrix
from tests.cli_run import run

ROOT = Path(__file__).resolve().parents[2]
TOL_MM = 1e-9


@pytest.fixture(scope="module")
def yourdfpy():
    """Imported by the test that reads a URDF back, not at collection (it pulls trimesh)."""
    return pytest.importorskip("yourdfpy", reason="yourdfpy reads the URDF back "
                               "(pip install -e '.[dev]')")


def result_of(model: Path, tmp: Path) -> Path:
    """A result JSON over the model's domains (a prior `lsq +- w` as its width about 0):
    what an export reads, without a solve."""
    m = elaborate(model, simulate_rows=1)
    params = {}
    for name, v in m.dag.variables.items():
        lo, hi = (v.prior[0] - v.prior[1], v.prior[0] + v.prior[1]) if v.prior else (v.lo, v.hi)
        # (an unbounded domain, a reading's, stays the result: inf - inf would be NaN)
        inside = ([lo + 0.3 * (hi - lo), hi - 0.1 * (hi - lo)]
                  if math.isfinite(hi - lo) else [lo, hi])
        params[name] = {"kind": v.kind, "domain": [lo, hi], "result": inside, "true": None}
    path = tmp / "r.json"
    path.write_text(json.dumps({"model": str(model), "status": "contracted",
                                "parameters": params}))
    return path


@pytest.fixture(scope="module", params=["ur10", "ur5"])
def exported(request, tmp_path_factory) -> tuple[str, dict[str, float], Path]:
    """(robot, the model's values at the exported point, the result JSON)."""
    tmp = tmp_path_factory.mktemp(request.param)
    model = ROOT / "models" / f"{request.param}_tracker.cal"
    path = result_of(model, tmp)
    point = export_point(json.loads(path.read_text()))
    return request.param, {**consts(model), **point}, path


def consts(model: Path) -> dict[str, float]:
    """The model's `const NAME = EXPR;` values (pi included), read from its files."""
    robot = model.name.split("_")[0]
    files = [ROOT / "models" / "robots" / f"{robot}.cal", ROOT / "models" / f"{robot}_priors.cal",
             model]
    values: dict[str, float] = {"pi": math.pi}
    for f in files:
        for name, expr in re.findall(r"const (\w+) = ([^;]+);", f.read_text()):
            try:
                values[name] = float(eval(expr, {"__builtins__": {}}, values))  # noqa: S307
            except NameError:  # (a const of the other robot's file)
                continue
    return values


def model_forward(v: dict[str, float], q: np.ndarray, base: bool) -> np.ndarray:
    """The model's tool point frame (N,4,4) in mm: [base: T(x,y,z) Rx Ry Rz] then the six MDH
    joints Rx(alpha) Tx(d) Rz(theta + q) Tz(r), then T(tx, ty, tz)."""
    m = np.repeat(np.eye(4)[None], len(q), axis=0)
    if base:
        c, s = np.cos([v["base_rx"], v["base_ry"], v["base_rz"]]), \
            np.sin([v["base_rx"], v["base_ry"], v["base_rz"]])
        rx = np.array([[1, 0, 0], [0, c[0], -s[0]], [0, s[0], c[0]]])
        ry = np.array([[c[1], 0, s[1]], [0, 1, 0], [-s[1], 0, c[1]]])
        rz = np.array([[c[2], -s[2], 0], [s[2], c[2], 0], [0, 0, 1]])
        b = np.eye(4)
        b[:3, :3], b[:3, 3] = rx @ ry @ rz, (v["base_x"], v["base_y"], v["base_z"])
        m = m @ b
    m = m @ chain([(v[f"alpha{j}"], v[f"d{j}"], v[f"theta{j}"] + q[:, j - 1], v[f"r{j}"])
                   for j in range(1, 7)])
    tool = np.eye(4)
    tool[:3, 3] = (v["tx"], v["ty"], v["tz"])
    return m @ tool


def joints(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-math.pi, math.pi, (12, 6))


def test_urdf_read_by_yourdfpy(exported, tmp_path, yourdfpy):
    robot, values, path = exported
    res = run("export", path, "--format", "urdf", "-o", tmp_path / "r.urdf")
    assert res.exit_code == 0, res.output
    urdf = yourdfpy.URDF.load(str(tmp_path / "r.urdf"), build_scene_graph=True,
                              load_meshes=False)
    assert urdf.actuated_joint_names == [f"q{j}" for j in range(1, 7)]
    limited = robot == "ur10"  # (models/robots/ur10.cal declares +-2 pi; ur5.cal none)
    for name in urdf.actuated_joint_names:
        joint = urdf.robot.joints[[j.name for j in urdf.robot.joints].index(name)]
        assert joint.type == ("revolute" if limited else "continuous")
        if limited:
            assert (joint.limit.lower, joint.limit.upper) == pytest.approx((-2 * math.pi,
                                                                             2 * math.pi))
    q = joints(1)
    got = []
    for row in q:
        urdf.update_cfg(dict(zip(urdf.actuated_joint_names, row, strict=True)))
        got.append(urdf.get_transform("tool0", "base_link"))
    want = model_forward(values, q, base=False)
    np.testing.assert_allclose(np.array(got)[:, :3, 3] * 1000, want[:, :3, 3], atol=TOL_MM)
    np.testing.assert_allclose(np.array(got)[:, :3, :3], want[:, :3, :3], atol=TOL_MM / 1000)
    cell = run("export", path, "--format", "cell", "-o", tmp_path / "c.urdf")
    assert cell.exit_code == 0
    world = yourdfpy.URDF.load(str(tmp_path / "c.urdf"), build_scene_graph=True,
                               load_meshes=False)
    base = world.get_transform(f"{robot}_base_link", "world")
    placed = base @ np.array(got)
    placed[:, :3, 3] *= 1000
    np.testing.assert_allclose(placed[:, :3, 3], model_forward(values, q, True)[:, :3, 3],
                               atol=TOL_MM * 10)  # (3.6 m from the tracker: 15 digits)


def test_ur_kinematics_read_by_yaml(exported, tmp_path):
    import yaml

    _, values, path = exported
    res = run("export", path, "--format", "ur-kinematics")
    assert res.exit_code == 0, res.output
    k = yaml.safe_load(res.output)["kinematics"]
    assert list(k) == ["shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3",
                       "hash"]
    q = joints(2)
    m = np.repeat(np.eye(4)[None], len(q), axis=0)
    for j, link in enumerate(list(k)[:6]):
        o = k[link]  # URDF's origin: T(x, y, z) Rz(yaw) Ry(pitch) Rx(roll), then Rz(q)
        rpy = dh_matrix(0, 0, o["yaw"], 0)[0] @ np.array(
            [[math.cos(o["pitch"]), 0, math.sin(o["pitch"]), 0], [0, 1, 0, 0],
             [-math.sin(o["pitch"]), 0, math.cos(o["pitch"]), 0], [0, 0, 0, 1]]) @ \
            dh_matrix(o["roll"], 0, 0, 0)[0]
        rpy[:3, 3] = (o["x"], o["y"], o["z"])
        m = m @ rpy @ dh_matrix(0, 0, q[:, j], 0)
    tool = model_forward(values, q, base=False)
    flange = m.copy()
    flange[:, :3, 3] *= 1000
    tip = flange[:, :3, :3] @ np.array([values["tx"], values["ty"], values["tz"]]) + \
        flange[:, :3, 3]
    np.testing.assert_allclose(tip, tool[:, :3, 3], atol=TOL_MM)


def dh_blocks(text: str) -> dict[str, list[dict[str, float]]]:
    """The table's rows per convention (the values; '+-' columns skipped)."""
    out: dict[str, list[dict[str, float]]] = {}
    convention, header = None, None
    for line in text.splitlines():
        if line.startswith("# standard DH"):
            convention = "dh"
        elif line.startswith("# modified DH"):
            convention = "mdh"
        elif line.startswith("# 6-DOF"):
            convention = "xyz"
        elif line.startswith("frame"):
            header = line.split()
        elif convention and header and line and not line.startswith(("#", "robot")):
            cells = line.split()
            out.setdefault(convention, []).append(
                {header[i]: float(cells[i]) for i in range(2, len(cells), 2)})
    return out


def test_standard_dh_table_from_the_modified_dh_model(exported):
    _, values, path = exported
    res = run("export", path, "--format", "dh-table", "--convention", "dh")
    assert res.exit_code == 0, res.output
    rows = dh_blocks(res.output)["dh"]
    assert len(rows) == 6
    q = joints(3)
    m = np.repeat(np.eye(4)[None], len(q), axis=0)
    for j, r in enumerate(rows):  # Rz(theta + q) Tz(d) Tx(a) Rx(alpha)
        m = m @ dh_matrix(0, 0, r["theta"] + q[:, j], r["d"]) @ dh_matrix(r["alpha"], r["a"],
                                                                         0, 0)
    tool = np.eye(4)
    tool[:3, 3] = (values["tx"], values["ty"], values["tz"])
    np.testing.assert_allclose((m @ tool)[:, :3, 3], model_forward(values, q, False)[:, :3, 3],
                               atol=TOL_MM)
    assert "nominal" in res.output  # r1 (d of joint 1 in standard DH) is fixed by the model
