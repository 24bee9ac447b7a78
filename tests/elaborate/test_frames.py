"""Frames beyond modified DH: a 6-DOF transform (translation, then X-Y-Z Euler angles) for a
base or a tool, and standard-DH joints, in both formulations, against an independent numpy
computation; standard DH agrees with modified DH on the same robot (the UR10)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.compile.group import compile_model
from calib_dsl.elaborate.chains import FORMULATIONS, Frame, forward_point, standard_dh, xyz_euler
from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.ir.dag import Dag
from calib_dsl.propagate.fixpoint import propagate
from calib_dsl.studies.evaluate import evaluate


# -- an independent reference: 4x4 matrices in numpy ---------------------------------------
def rot(axis: str, t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    m = np.eye(4)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    m[i, i], m[j, j], m[i, j], m[j, i] = c, c, -s, s
    return m


def trans(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def six_dof(x, y, z, rx, ry, rz) -> np.ndarray:
    return trans(x, y, z) @ rot("x", rx) @ rot("y", ry) @ rot("z", rz)


def mdh(alpha, d, theta, r) -> np.ndarray:
    return rot("x", alpha) @ trans(d, 0, 0) @ rot("z", theta) @ trans(0, 0, r)


def sdh(theta, d, a, alpha) -> np.ndarray:
    return rot("z", theta) @ trans(0, 0, d) @ trans(a, 0, 0) @ rot("x", alpha)


# the UR10's nominal kinematics (mm, rad): modified DH, and the same robot in standard DH
UR10_MDH = [(0.0, 0.0, 127.3), (math.pi / 2, 0.0, 0.0), (0.0, -612.0, 0.0),
            (0.0, -572.3, 163.941), (math.pi / 2, 0.0, 115.7), (-math.pi / 2, 0.0, 92.2)]
UR10_SDH = [(127.3, 0.0, math.pi / 2), (0.0, -612.0, 0.0), (0.0, -572.3, 0.0),
            (163.941, 0.0, math.pi / 2), (115.7, 0.0, -math.pi / 2), (92.2, 0.0, 0.0)]

pose = st.tuples(*[st.floats(-2000, 2000)] * 3, *[st.floats(-math.pi, math.pi)] * 3)
joints = st.lists(st.floats(-math.pi, math.pi), min_size=6, max_size=6)


@pytest.mark.parametrize("formulation", FORMULATIONS)
@settings(max_examples=60, deadline=None)
@given(base=pose, tool=pose, q=joints)
def test_six_dof_base_and_tool_around_modified_dh(formulation, base, tool, q):
    dag = Dag()
    c = dag.const
    frames = [xyz_euler(*(c(v) for v in base))]
    for (alpha, d, r), qj in zip(UR10_MDH, q, strict=True):
        frames.append(Frame(c(alpha), c(d), dag.op("add", c(0.0), c(qj)), c(r)))
    frames.append(xyz_euler(*(c(v) for v in tool)))
    out = forward_point(dag, frames, (c(0.0), c(0.0), c(0.0)), formulation)
    values = evaluate(dag, {}, default=0.0)
    got = np.array([values[o] for o in out], dtype=float)
    ref = six_dof(*base)
    for (alpha, d, r), qj in zip(UR10_MDH, q, strict=True):
        ref = ref @ mdh(alpha, d, qj, r)
    ref = ref @ six_dof(*tool)
    np.testing.assert_allclose(got, ref[:3, 3], atol=1e-9, rtol=1e-12)


@pytest.mark.parametrize("formulation", FORMULATIONS)
@settings(max_examples=60, deadline=None)
@given(q=joints, point=st.tuples(*[st.floats(-200, 200)] * 3))
def test_standard_dh_agrees_with_modified_dh(formulation, q, point):
    """The UR10 written both ways: the same tool point position, to 1e-9 mm."""
    dag = Dag()
    c = dag.const
    sdh_frames = [standard_dh(c(qj), c(d), c(a), c(alpha))
                  for (d, a, alpha), qj in zip(UR10_SDH, q, strict=True)]
    mdh_frames = [Frame(c(alpha), c(d), c(qj), c(r))
                  for (alpha, d, r), qj in zip(UR10_MDH, q, strict=True)]
    p = tuple(c(v) for v in point)
    a = forward_point(dag, sdh_frames, p, formulation)
    b = forward_point(dag, mdh_frames, p, formulation)
    values = evaluate(dag, {}, default=0.0)
    ref = np.eye(4)
    for (d, a_, alpha), qj in zip(UR10_SDH, q, strict=True):
        ref = ref @ sdh(qj, d, a_, alpha)
    want = (ref @ np.array([*point, 1.0]))[:3]
    # standard DH's last frame is modified DH's (the two conventions share the flange)
    np.testing.assert_allclose([values[o] for o in a], want, atol=1e-9)
    np.testing.assert_allclose([values[o] for o in b], want, atol=1e-9)


MODEL = """units mm, rad;
robot ur10(q1, q2, q3, q4, q5, q6) dh {{
  base x = {bx}, y = {by}, z = {bz}, rx = {brx}, ry = {bry}, rz = {brz};
  joint theta = q1, d = 127.3, a = 0, alpha = pi/2;
  joint theta = q2, d = 0, a = -612, alpha = 0;
  joint theta = q3, d = 0, a = -572.3, alpha = 0;
  joint theta = q4, d = 163.941, a = 0, alpha = pi/2;
  joint theta = q5, d = 115.7, a = 0, alpha = -pi/2;
  joint theta = q6, d = 92.2, a = 0, alpha = 0;
  tool z = 93;
}}
var x, y, z;
ur10({q}) at (0, 0, 0) == (x, y, z);
"""


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_a_model_with_a_6dof_base_reproduces_numpy_on_100_poses(tmp_path, formulation):
    """End to end through the language: a robot in standard DH with a 6-DOF base and a tool
    frame; propagation encloses the numpy position of the tool (to 1e-9 relative)."""
    rng = np.random.default_rng(7)
    base = (1200.0, -3300.0, -150.0, 0.01, -0.02, 1.6)
    path = tmp_path / "ur10.cal"
    for k in range(100 if formulation == "matrix" else 25):
        q = rng.uniform(-math.pi, math.pi, 6)
        path.write_text(MODEL.format(bx=base[0], by=base[1], bz=base[2], brx=base[3],
                                     bry=base[4], brz=base[5],
                                     q=", ".join(repr(float(v)) for v in q)))
        prog = compile_model(elaborate(path, formulation=formulation))
        res = propagate(prog, tol=0.0)
        ref = six_dof(*base)
        for (d, a, alpha), qj in zip(UR10_SDH, q, strict=True):
            ref = ref @ sdh(qj, d, a, alpha)
        want = (ref @ np.array([0.0, 0.0, 93.0, 1.0]))[:3]
        for name, w in zip("xyz", want, strict=True):
            i = prog.slots.names.index(name)
            assert res.lo[i] <= w + 1e-9 * abs(w) and w - 1e-9 * abs(w) <= res.hi[i], (k, name)
            assert res.hi[i] - res.lo[i] < 1e-6, (k, name)  # a point, up to rounding


LIBRARY = """units mm, rad;
include "{robot}";
const base_x = 1200; const base_y = -3300; const base_z = -150;
const base_rx = 0.01; const base_ry = -0.02; const base_rz = 1.6;
{chain}
var x, y, z;
{name}({q}) at (0.4, -0.1, 93) == (x, y, z);
"""


@pytest.mark.parametrize("name", ["ur10", "ur5"])
def test_the_robot_library_gives_the_nominal_chain(tmp_path, name):
    """models/robots/NAME.cal with its own nominal values declared as the chain's consts:
    the tool point where numpy's modified DH (from the same nominal values) puts it."""
    root = __import__("pathlib").Path(__file__).resolve().parents[2]
    robot = root / "models" / "robots" / f"{name}.cal"
    chain = "\n".join(f"const {p}{j} = {name}_{p}{j};" for j in range(1, 7)
                      for p in ("alpha", "d", "theta", "r"))
    rng = np.random.default_rng(3)
    q = rng.uniform(-math.pi, math.pi, 6)
    path = tmp_path / "m.cal"
    path.write_text(LIBRARY.format(robot=robot, chain=chain, name=name,
                                   q=", ".join(repr(float(v)) for v in q)))
    model = elaborate(path)
    prog = compile_model(model)
    res = propagate(prog, tol=0.0)
    nominal = {"ur10": UR10_MDH, "ur5": [(0.0, 0.0, 89.159), (math.pi / 2, 0.0, 0.0),
                                         (0.0, -425.0, 0.0), (0.0, -392.25, 109.15),
                                         (math.pi / 2, 0.0, 94.65), (-math.pi / 2, 0.0, 82.3)]}
    ref = six_dof(1200, -3300, -150, 0.01, -0.02, 1.6)
    for (alpha, d, r), qj in zip(nominal[name], q, strict=True):
        ref = ref @ mdh(alpha, d, qj, r)
    want = (ref @ np.array([0.4, -0.1, 93.0, 1.0]))[:3]
    for axis, w in zip("xyz", want, strict=True):
        i = prog.slots.names.index(axis)
        assert res.lo[i] - 1e-9 * abs(w) <= w <= res.hi[i] + 1e-9 * abs(w)
        assert res.hi[i] - res.lo[i] < 1e-6
