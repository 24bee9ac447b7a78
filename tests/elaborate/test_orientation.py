"""Orientation measurements: `robot(q...) axes` (the last frame's rotation, a 9-vector row by
row), `euler_xyz(rx, ry, rz)` and `compose(A, B)`, in both formulations, against an independent
numpy computation; a 6-DOF tracker model on simulated data (known truth) holds the truth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from elaborate.test_frames import mdh, six_dof
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.compile.group import compile_model
from calib_dsl.elaborate.chains import FORMULATIONS
from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.propagate.fixpoint import propagate

MODEL = """units mm, rad;
robot r(q1, q2, q3) {{
  base x = 1200, y = -3300, z = -150, rx = {b[0]!r}, ry = {b[1]!r}, rz = {b[2]!r};
  joint alpha = 0.3, d = 10, theta = q1, r = 5;
  joint alpha = pi / 2, d = -612, theta = q2, r = 0;
  joint alpha = -0.7, d = 3, theta = q3, r = 2;
  tool x = 1, y = 2, z = 93, rx = {t[0]!r}, ry = {t[1]!r}, rz = {t[2]!r};
}}
var a[1..9];
for i in 1..9 {{
  a[i] == compose(r({q}) axes, euler_xyz({e[0]!r}, {e[1]!r}, {e[2]!r}))[i];
}}
"""

angles = st.tuples(*[st.floats(-math.pi, math.pi)] * 3)


@pytest.mark.parametrize("formulation", FORMULATIONS)
@settings(max_examples=40, deadline=None)
@given(base=angles, tool=angles, q=angles, extra=angles)
def test_axes_compose_and_euler_match_numpy(tmp_path_factory, formulation, base, tool, q,
                                            extra):
    path = tmp_path_factory.mktemp("axes") / "m.cal"
    path.write_text(MODEL.format(b=base, t=tool, e=extra, q=", ".join(map(repr, q))))
    prog = compile_model(elaborate(path, formulation=formulation))
    res = propagate(prog, tol=0.0)
    ref = six_dof(1200, -3300, -150, *base)
    for (alpha, d, r), qj in zip([(0.3, 10, 5), (math.pi / 2, -612, 0), (-0.7, 3, 2)], q,
                                 strict=True):
        ref = ref @ mdh(alpha, d, qj, r)
    ref = ref @ six_dof(1, 2, 93, *tool) @ six_dof(0, 0, 0, *extra)
    want = ref[:3, :3].ravel()
    declared = dict(zip(prog.slots.declared_names, prog.slots.declared, strict=True))
    for k, w in enumerate(want, start=1):
        i = declared[f"a[{k}]"]
        assert res.lo[i] - 1e-12 <= w <= res.hi[i] + 1e-12, (k, res.lo[i], w, res.hi[i])
        assert res.hi[i] - res.lo[i] < 1e-9  # a point, up to rounding


def test_rotations_are_nine_vectors(write_model):
    bad = write_model("var a in [0, 1];\ncompose(euler_xyz(0, 0, 0), (1, 2, 3)) == "
                      "(a, a, a, a, a, a, a, a, a);\n")
    with pytest.raises(CalError, match="9-vectors"):
        elaborate(bad)
    wrong = write_model("var a in [0, 1];\neuler_xyz(a, a) == (a, a, a);\n")
    with pytest.raises(CalError, match="takes 3 arguments"):
        elaborate(wrong)
    not_robot = write_model("const k = 1;\nvar a in [0, 1];\nk(1) axes == (a, a);\n")
    with pytest.raises(CalError, match="not a robot"):
        elaborate(not_robot)


# -- a 6-DOF tracker on a simulated UR10 (the public data's dialect; truth known) ----------
SIX_DOF = """units mm, rad;
include "{robots}/ur10.cal";
const e = 0.2; const e_rot = 0.001; const q_err = 1e-5;
const alpha1 = ur10_alpha1; const d1 = ur10_d1; const theta1 = ur10_theta1; const r1 = ur10_r1;
const alpha2 = ur10_alpha2; const d2 = ur10_d2; const theta2 = ur10_theta2; const r2 = ur10_r2;
const alpha3 = ur10_alpha3; const theta3 = ur10_theta3; const r3 = ur10_r3;
const alpha4 = ur10_alpha4; const d4 = ur10_d4; const theta4 = ur10_theta4; const r4 = ur10_r4;
const alpha5 = ur10_alpha5; const d5 = ur10_d5; const theta5 = ur10_theta5; const r5 = ur10_r5;
const alpha6 = ur10_alpha6; const d6 = ur10_d6; const theta6 = ur10_theta6; const r6 = ur10_r6;
const base_x = 500; const base_y = -3500; const base_z = -1200;
param base_rx in 0 +- 0.01; param base_ry in 0 +- 0.01; param base_rz in 0.35 +- 0.01;
param d3 in -612 +- 5;
param tx in 0 +- 5; param ty in 0 +- 5; param tz in 93 +- 5;
param tool_rx in 0 +- 0.01; param tool_ry in 0 +- 0.01; param tool_rz in -pi / 2 +- 0.01;
table m = "sim.csv" (separator = ";", decimal = ",") {{
  q1 = "shoulder_pan_joint" in rad, q2 = "shoulder_lift_joint" in rad,
  q3 = "elbow_joint" in rad, q4 = "wrist_1_joint" in rad, q5 = "wrist_2_joint" in rad,
  q6 = "wrist_3_joint" in rad : +- q_err;
  x = "measurement_x" in mm, y = "measurement_y" in mm, z = "measurement_z" in mm : +- e;
  rx = "measurement_rx" in deg, ry = "measurement_ry" in deg, rz = "measurement_rz" in deg
    : +- e_rot;
}}
for k in 1..rows(m) {{
  ur10(m.q1[k], m.q2[k], m.q3[k], m.q4[k], m.q5[k], m.q6[k]) at (tx, ty, tz)
    == (m.x[k], m.y[k], m.z[k]);
  compose(ur10(m.q1[k], m.q2[k], m.q3[k], m.q4[k], m.q5[k], m.q6[k]) axes,
          euler_xyz(tool_rx, tool_ry, tool_rz)) == euler_xyz(m.rx[k], m.ry[k], m.rz[k]);
}}
"""

UR10 = [(0.0, 0.0, 127.3), (math.pi / 2, 0.0, 0.0), (0.0, -612.0, 0.0),
        (0.0, -572.3, 163.941), (math.pi / 2, 0.0, 115.7), (-math.pi / 2, 0.0, 92.2)]


def xyz_angles(m: np.ndarray) -> tuple[float, float, float]:
    """Intrinsic X-Y-Z Euler angles of a rotation (independently of the library)."""
    return (math.atan2(-m[1, 2], m[2, 2]), math.asin(max(-1.0, min(1.0, m[0, 2]))),
            math.atan2(-m[0, 1], m[0, 0]))


def simulated_table(rng, truth, rows: int, e: float, e_rot: float) -> str:
    lines = ["shoulder_pan_joint;shoulder_lift_joint;elbow_joint;wrist_1_joint;wrist_2_joint;"
             "wrist_3_joint;measurement_x;measurement_y;measurement_z;measurement_rx;"
             "measurement_ry;measurement_rz"]
    for _ in range(rows):
        q = rng.uniform(-math.pi, math.pi, 6)
        m = six_dof(500, -3500, -1200, truth["base_rx"], truth["base_ry"], truth["base_rz"])
        for j, ((alpha, d, r), qj) in enumerate(zip(UR10, q, strict=True)):
            m = m @ mdh(alpha, truth["d3"] if j == 2 else d, qj, r)
        p = m @ np.array([truth["tx"], truth["ty"], truth["tz"], 1.0])
        rot = m @ six_dof(0, 0, 0, truth["tool_rx"], truth["tool_ry"], truth["tool_rz"])
        ang = np.degrees(np.array(xyz_angles(rot[:3, :3])) + rng.uniform(-e_rot, e_rot, 3))
        xyz = p[:3] + rng.uniform(-e, e, 3)
        cells = [*q, *xyz, *ang]
        lines.append(";".join(repr(float(c)).replace(".", ",") for c in cells))
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("seed", [0, 1, *(pytest.param(k, marks=pytest.mark.slow)
                                         for k in range(2, 6))])
def test_a_six_dof_tracker_holds_the_truth(tmp_path, seed):
    rng = np.random.default_rng(seed)
    truth = {"base_rx": rng.uniform(-0.008, 0.008), "base_ry": rng.uniform(-0.008, 0.008),
             "base_rz": 0.35 + rng.uniform(-0.008, 0.008), "d3": -612 + rng.uniform(-4, 4),
             "tx": rng.uniform(-4, 4), "ty": rng.uniform(-4, 4), "tz": 93 + rng.uniform(-4, 4),
             "tool_rx": rng.uniform(-0.008, 0.008), "tool_ry": rng.uniform(-0.008, 0.008),
             "tool_rz": -math.pi / 2 + rng.uniform(-0.008, 0.008)}
    (tmp_path / "sim.csv").write_text(simulated_table(rng, truth, 30, 0.2, 0.001))
    robots = __import__("pathlib").Path(__file__).resolve().parents[2] / "models" / "robots"
    path = tmp_path / "six.cal"
    path.write_text(SIX_DOF.format(robots=robots))
    from calib_dsl.pipeline import solve

    prog = compile_model(elaborate(path))
    sol = solve(prog)
    assert sol.status == "contracted"
    narrowed = 0
    for name, t in truth.items():
        i = prog.slots.names.index(name)
        assert sol.lo[i] <= t <= sol.hi[i], (seed, name, sol.lo[i], t, sol.hi[i])
        narrowed += sol.hi[i] - sol.lo[i] < 0.5 * (prog.slots.hi[i] - prog.slots.lo[i])
    # the orientation rows pin the tool's rotation and the base's (1 mrad against 10)
    assert narrowed >= 6
