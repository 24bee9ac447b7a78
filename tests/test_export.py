"""Exports of a solve's result: the result as the next run's search domains (`solve
--export-domains`, `export --format cal`), and midpoints with guaranteed half-widths for a
controller (`export --format dh-table|urdf|json`), checked against the model's kinematics."""

from __future__ import annotations

import json
import math
import re
import shutil
import xml.etree.ElementTree as ET
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from calib_dsl import cli
from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.pipeline import load, solve
from calib_dsl.report.as_json import result_json
from calib_dsl.report.export import domains_cal
from calib_dsl.report.export_point import export_point
from calib_dsl.studies.kinematics import chain, dh_matrix, rx90_frames

ROOT = Path(__file__).resolve().parents[1]
RX90 = ROOT / "models" / "rx90_lengths.cal"


def run(*args: object):
    return CliRunner().invoke(cli.main, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def rx90(tmp_path_factory) -> tuple[Path, dict, Path]:
    """The RX90 Test A solved once: its JSON, and the domains it exported."""
    tmp = tmp_path_factory.mktemp("rx90")
    out, domains = tmp / "r.json", tmp / "domains.cal"
    res = run("solve", RX90, "--json", out, "--export-domains", domains, "--no-identify")
    assert res.exit_code == 0, res.output
    return out, json.loads(out.read_text()), domains


def interval(p: dict) -> tuple[float, float]:
    return tuple(float(x) for x in p["result"])  # type: ignore[return-value]


@pytest.mark.slow
def test_recalibration_round_trip(rx90, tmp_path):
    """The model with the exported domains in place of its own declarations, solved again:
    every result within the first (no wider), and every true value inside."""
    _, first, domains = rx90
    shutil.copy(ROOT / "models" / "rx90_robot.cal", tmp_path)
    shutil.copy(domains, tmp_path / "domains.cal")
    body = [ln for ln in RX90.read_text().splitlines()
            if not ln.startswith(("param ", "const known"))]
    (tmp_path / "again.cal").write_text('include "domains.cal";\n' + "\n".join(body) + "\n")
    prog = load(tmp_path / "again.cal", data=ROOT / "models" / "data" / "rx90_50.csv")
    second = result_json(prog, solve(prog), "tight")["parameters"]
    truth = load(RX90).true_values  # the data's (stated, or the domains' centres)
    assert list(second) == list(first["parameters"])
    for name, p in first["parameters"].items():
        lo, hi = interval(p)
        lo2, hi2 = interval(second[name])
        assert lo <= lo2 and hi2 <= hi, name  # no wider: the domains are the results exactly
        assert second[name]["domain"] == [lo, hi], name
        assert lo2 <= truth[name] <= hi2, name


def test_exported_domains_read_back_as_the_result_exactly(tmp_path):
    """A family's elements and point results too: each declared domain is the result's
    floats, not one float wider (the round trip above depends on it)."""
    data = {"model": "m.cal", "parameters": {
        "a": {"kind": "param", "result": [0.1, 0.30000000000000004], "true": 0.2},
        "b[1]": {"kind": "var", "result": [5e-324, 5e-324], "true": None},
        "b[2]": {"kind": "var", "result": [-1.0000000000000002, "+oo"], "true": None},
        "c": {"kind": "param", "result": [1.0, 2.0], "true": 7.0}}}
    text = domains_cal(data)
    assert "true 0.2" in text and "true 7" not in text  # a true value outside is dropped
    (tmp_path / "m.cal").write_text(text + "a + c >= 0;\n")
    model = elaborate(tmp_path / "m.cal")
    prog = load(tmp_path / "m.cal")
    box = dict(zip(prog.slots.names, zip(prog.slots.lo, prog.slots.hi, strict=True),
                   strict=False))
    assert (model.dag.variables["a"].lo, model.dag.variables["a"].hi) == (0.1,
                                                                          0.30000000000000004)
    assert box["b[1]"] == (5e-324, 5e-324)
    assert box["b[2]"] == (-1.0000000000000002, math.inf)


def dh_rows(text: str) -> dict[str, dict[str, tuple[float, str]]]:
    """The DH table's rows: frame -> entry -> (midpoint, half-width text)."""
    rows, header = {}, None
    for line in text.splitlines():
        if not line.strip() or line.startswith(("#", "robot ")):
            continue
        cells = line.split()
        if cells[0] == "frame":
            header = cells
            continue
        assert header is not None
        rows[cells[0]] = {header[i]: (float(cells[i]), cells[i + 1])
                          for i in range(2, len(cells), 2)}
        rows[cells[0]]["motion"] = cells[1]  # type: ignore[assignment]
    return rows


@pytest.mark.slow
def test_dh_table_kinematics_equal_the_models_at_the_midpoints(rx90):
    path, data, _ = rx90
    res = run("export", path, "--format", "dh-table")
    assert res.exit_code == 0, res.output
    assert "lengths in m, angles in rad" in res.output
    rows = dh_rows(res.output)
    assert list(rows) == ["base1"] + [f"joint{j}" for j in range(1, 7)]
    assert all(rows[f"joint{j}"]["motion"] == "revolute" for j in range(1, 7))
    mids = export_point(data)  # the midpoints, as the short decimals written
    q = np.random.default_rng(5).uniform(-np.pi, np.pi, (10, 6))
    frames = [(rows["base1"]["alpha"][0], rows["base1"]["d"][0], rows["base1"]["theta"][0],
               rows["base1"]["r"][0])]
    for j in range(1, 7):
        e = rows[f"joint{j}"]
        frames.append((e["alpha"][0], e["d"][0], e["theta"][0] + q[:, j - 1], e["r"][0]))
    np.testing.assert_allclose(chain(frames), chain(rx90_frames(q, mids)), atol=1e-13)
    # an entry that is one parameter: midpoint +- half-width holds its whole result
    for frame, entry, name in (("base1", "r", "r0"), ("joint3", "d", "d3"),
                               ("joint4", "r", "r4"), ("joint1", "alpha", "alpha1")):
        m, h = rows[frame][entry]
        lo, hi = interval(data["parameters"][name])
        assert Fraction(m) - Fraction(h) <= Fraction(lo) and Fraction(hi) <= \
            Fraction(m) + Fraction(h), (frame, entry)
        assert float(h) < 1.05 * (hi - lo) / 2 + 1e-9  # rounded up, not blown up


def urdf_forward(root: ET.Element, q: np.ndarray, until: str = "flange_joint") -> np.ndarray:
    """The pose of joint `until`'s child: each joint's origin, then its motion, in chain
    order (the tool frames after the flange are not on the way)."""
    def origin(j: ET.Element) -> np.ndarray:
        o = j.find("origin")
        x, y, z = (float(v) for v in o.get("xyz").split())
        r, p, w = (float(v) for v in o.get("rpy").split())
        rz = dh_matrix(0, 0, w, 0)[0]
        ry = np.array([[math.cos(p), 0, math.sin(p), 0], [0, 1, 0, 0],
                       [-math.sin(p), 0, math.cos(p), 0], [0, 0, 0, 1]])
        rx = dh_matrix(r, 0, 0, 0)[0]
        t = np.eye(4)
        t[:3, 3] = (x, y, z)
        return t @ rz @ ry @ rx

    m = np.repeat(np.eye(4)[None], len(q), axis=0)
    moving = 0
    for j in root.findall("joint"):
        m = m @ origin(j)
        if j.get("type") != "fixed":  # a turn about z, or a move along it (prismatic)
            s = float(j.find("axis").get("xyz").split()[2])
            m = m @ (dh_matrix(0, 0, 0, s * q[:, moving]) if j.get("type") == "prismatic"
                     else dh_matrix(0, 0, s * q[:, moving], 0))
            moving += 1
        if j.get("name") == until:
            break
    return m


@pytest.mark.slow
def test_urdf_is_well_formed_with_one_joint_per_axis(rx90):
    path, data, _ = rx90
    res = run("export", path, "--format", "urdf")
    assert res.exit_code == 0, res.output
    root = ET.fromstring(res.output.split("\n", 1)[1])  # (after the XML declaration)
    assert root.tag == "robot" and root.get("name") == "rx90"
    joints = root.findall("joint")
    assert [j.get("type") for j in joints] == ["continuous"] * 6 + ["fixed"] * 4
    assert [j.get("name") for j in joints] == [f"q{k}" for k in range(1, 7)] + [
        "flange_joint", "tool1_joint", "tool2_joint", "tool3_joint"]  # (three tool points)
    links = {lk.get("name") for lk in root.findall("link")}
    assert all(j.find("parent").get("link") in links and j.find("child").get("link") in links
               for j in joints)
    mids = export_point(data)
    q = np.random.default_rng(6).uniform(-np.pi, np.pi, (10, 6))
    cell = run("export", path, "--format", "cell")  # where the robot stands: its base frame
    placed = urdf_forward(ET.fromstring(cell.output.split("\n", 1)[1]), q[:, :0]) @ \
        urdf_forward(root, q)
    np.testing.assert_allclose(placed, chain(rx90_frames(q, mids)), atol=1e-13)


@pytest.mark.slow
def test_json_export_states_units_and_covers_each_result(rx90):
    path, data, _ = rx90
    res = run("export", path, "--format", "json")
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert out["units"] == {"length": "m", "angle": "rad"}
    assert out["parameters"]["r0"]["unit"] == "m" and out["parameters"]["alpha1"]["unit"] == "rad"
    assert "unit" not in out["parameters"]["b1x"]  # a tool point: not a frame entry
    for name, p in out["parameters"].items():
        lo, hi = interval(data["parameters"][name])
        assert p["value"] - p["half_width"] <= lo and hi <= p["value"] + p["half_width"]
    frames = out["robots"][0]["frames"]
    assert [f["motion"] for f in frames] == ["fixed"] + ["revolute"] * 6
    assert frames[1]["joint"] == "q1" and frames[1]["entries"]["theta"]["unit"] == "rad"


def test_a_6dof_base_gets_its_own_block_in_mm(tmp_path):
    """The UR10 model (mm, a 6-DOF base): two blocks, units from the model."""
    model = elaborate(ROOT / "models" / "ur10_tracker.cal", simulate_rows=1)
    params = {}
    for name, v in model.dag.variables.items():
        lo, hi = (v.prior[0] - v.prior[1], v.prior[0] + v.prior[1]) if v.prior else (v.lo, v.hi)
        params[name] = {"kind": v.kind, "result": [lo, hi], "true": None}
    path = tmp_path / "r.json"
    path.write_text(json.dumps({"model": str(ROOT / "models" / "ur10_tracker.cal"),
                                "status": "contracted", "parameters": params}))
    res = run("export", path, "--format", "dh-table")
    assert res.exit_code == 0, res.output
    assert "lengths in mm, angles in rad" in res.output
    assert "# 6-DOF frames: T(x, y, z) Rx(rx) Ry(ry) Rz(rz)" in res.output
    rows = dh_rows(res.output)
    assert set(rows) == {"base1"} | {f"joint{j}" for j in range(1, 7)}
    assert set(rows["base1"]) == {"x", "y", "z", "rx", "ry", "rz", "motion"}
    urdf = run("export", path, "--format", "urdf")
    assert urdf.exit_code == 0
    root = ET.fromstring(urdf.output.split("\n", 1)[1])
    r1 = rows["joint1"]["r"][0]  # mm in the table, m in the URDF
    z = float(root.findall("joint")[0].find("origin").get("xyz").split()[2])
    assert z == pytest.approx(r1 / 1000)


@pytest.mark.parametrize("data, message", [
    ({"status": "infeasible", "parameters": {}}, "proved the data inconsistent"),
    ({"model": "m.cal", "min_error": {"name": "e", "bracket": [0.5, 0.52]}},
     "a --min-error result: export a solve at a bound the bracket proves consistent, calibc "
     "solve --json FILE -D e=0.52"),
    ({"status": "contracted", "parameters": {"x": {"result": [0, 1], "kind": "param",
                                                   "true": None}}}, "does not name its model"),
    ({"status": "contracted", "model": "nowhere.cal",
      "parameters": {"x": {"result": [0, 1]}}}, "nowhere.cal"),
])
def test_export_user_errors(tmp_path, data, message):
    path = tmp_path / "r.json"
    path.write_text(json.dumps(data))
    res = run("export", path, "--format", "dh-table")
    assert res.exit_code == 2 and message in res.output and "Traceback" not in res.output


def test_export_of_a_model_without_robot(tmp_path):
    model = ROOT / "models" / "examples" / "circle_fit.cal"
    out = tmp_path / "r.json"
    assert run("solve", model, "--json", out).exit_code == 0
    res = run("export", out, "--format", "urdf")
    assert res.exit_code == 2 and "has no robot" in res.output
    res = run("export", out, "--format", "json")
    assert res.exit_code == 0 and json.loads(res.output)["robots"] == []
    res = run("export", out, "--format", "cal")
    assert res.exit_code == 0 and res.output.count("param ") == 3


STANDARD_DH = """param l1 in [0.9, 1.1]; param l2 in [0.4, 0.6]; param off in [-0.1, 0.1];
param h in [0.1, 0.3];
robot arm(q1, q2, q3) dh {
  joint theta = q1 + off, d = h, a = l1, alpha = pi / 2;
  joint theta = -q2, a = l2;
  joint theta = 0.3, d = q3;
}
var x;
x == dot(arm(0, 0, 0) at (0, 0, 0), (1, 0, 0));
"""


def test_standard_dh_with_a_reversed_and_a_prismatic_joint(tmp_path):
    """The URDF of a standard-DH arm (motion before the frame's fixed part), one joint
    entering as -q and one prismatic, composes to the DH chain at the midpoints."""
    (tmp_path / "m.cal").write_text(STANDARD_DH)
    params = {n: {"kind": "param", "result": r, "true": None} for n, r in
              {"l1": [0.95, 1.05], "l2": [0.5, 0.52], "off": [0.01, 0.03],
               "h": [0.2, 0.2]}.items()}
    params["x"] = {"kind": "var", "result": [0, 2], "true": None}
    path = tmp_path / "r.json"
    path.write_text(json.dumps({"model": str(tmp_path / "m.cal"), "status": "contracted",
                                "parameters": params}))
    table = run("export", path, "--format", "dh-table")
    assert table.exit_code == 0, table.output
    rows = dh_rows(table.output)
    assert [rows[f"joint{j}"]["motion"] for j in (1, 2, 3)] == ["revolute", "revolute(-q)",
                                                                "prismatic"]
    assert rows["joint1"]["theta"][0] == pytest.approx(0.02)
    urdf = run("export", path, "--format", "urdf")
    root = ET.fromstring(urdf.output.split("\n", 1)[1])
    assert [j.get("type") for j in root.findall("joint")] == ["continuous", "continuous",
                                                             "prismatic", "fixed", "fixed"]
    q = np.random.default_rng(7).uniform(-1, 1, (8, 3))

    def rz(t):
        return dh_matrix(0, 0, t, 0)

    def dh(theta, d, a, alpha):  # Rz(theta) Tz(d) Tx(a) Rx(alpha)
        return rz(theta) @ dh_matrix(0, 0, 0, d) @ dh_matrix(0, a, 0, 0) @ \
            dh_matrix(alpha, 0, 0, 0)

    expected = (dh(q[:, 0] + 0.02, 0.2, 1.0, np.pi / 2) @ dh(-q[:, 1], 0, 0.51, 0)
                @ dh(0.3, q[:, 2], 0, 0))
    np.testing.assert_allclose(urdf_forward(root, q), expected, atol=1e-12)


@pytest.mark.slow
def test_no_float_noise_and_fixed_entries_marked_nominal(rx90, tmp_path):
    """Every value is a short decimal (no 0.30000000000000004), every entry the model fixes
    is marked nominal, and --point lsq needs a least-squares estimate in the result."""
    path, data, _ = rx90
    res = run("export", path, "--format", "dh-table")
    values = [c for line in res.output.splitlines() if line.startswith(("base", "joint"))
              for c in line.split()[2::2]]
    assert values and all(len(v.lstrip("-").replace(".", "").rstrip("0")) <= 15
                          for v in values)
    assert "nominal" in res.output
    urdf = run("export", path, "--format", "urdf").output
    assert not re.search(r"\.\d*(0{9,}|9{9,})\d", urdf)  # float noise: ...0000001, ...99999
    res = run("export", path, "--format", "urdf", "--point", "lsq")
    assert res.exit_code == 2 and "calibc solve --lsq" in res.output
    with_lsq = {**data, "parameters": {n: {**p, "least_squares": 0.5 * sum(interval(p))}
                                       for n, p in data["parameters"].items()}}
    (tmp_path / "l.json").write_text(json.dumps(with_lsq))
    res = run("export", tmp_path / "l.json", "--format", "urdf", "--point", "lsq")
    assert res.exit_code == 0 and res.output == urdf  # (the same point, the same file)


@pytest.mark.slow
def test_the_certified_centre_is_a_point_of_the_inner_intervals(rx90):
    """--point centre writes the certified centre the JSON states: a vector proven to
    satisfy every constraint, inside every certified inner interval."""
    path, data, _ = rx90
    for name, p in data["parameters"].items():
        a, b = p["inner"]
        assert a <= p["certified"] <= b, name
    res = run("export", path, "--format", "json", "--point", "centre")
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)["parameters"]
    assert out["r0"]["value"] == pytest.approx(data["parameters"]["r0"]["certified"], abs=1e-6)
    assert res.output != run("export", path, "--format", "json").output
