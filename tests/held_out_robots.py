"""Robots nobody tuned to, written as .cal text for the held-out battery
(tests/test_held_out_battery.py): other DH tables and conventions, tool points, joint readings
exact or with errors, other units and dialects, a 6-DOF tracker. Each model states its true
values, so a test checks that every result holds them."""

from __future__ import annotations

# Standard DH, four joints, exact joint readings, a tool point along z, one tracker point.
ARM4_DH = """units mm, rad;
const e = 0.05;
param bx in 0 +- 3 true 0.8; param by in 0 +- 3 true -1.1; param bz in 0 +- 3 true 0.4;
param d1 in 300 +- 3 true 301.2;
param a2 in 450 +- 3 true 448.7; param a3 in 380 +- 3 true 381.5;
param off2 in 0 +- 0.01 true 0.0021; param off3 in 0 +- 0.01 true -0.0013;
param tz in 80 +- 3 true 79.4;
robot arm(q1, q2, q3, q4) dh {
  base x = bx, y = by, z = bz;
  joint theta = q1, d = d1, a = 0, alpha = pi / 2;
  joint theta = q2 + off2, a = a2;
  joint theta = q3 + off3, a = a3;
  joint theta = q4, alpha = pi / 2;
  tool z = tz;
}
table m = "arm4.csv" {
  q1, q2, q3, q4 : +- 0 simulate in [-2, 2];
  x, y, z : +- e;
}
for k in 1..rows(m) {
  arm(m.q1[k], m.q2[k], m.q3[k], m.q4[k]) at (0, 0, 0) == (m.x[k], m.y[k], m.z[k]);
}
"""

# Modified DH, five joints read with errors and written in degrees, positions in metres,
# ';'-separated with the file's own header names.
ARM5_MDH = """units mm, rad;
const e = 0.1;
const qe = 2e-5;
param r1 in 250 +- 4 true 251.3;
param d3 in 520 +- 4 true 517.9; param d4 in 410 +- 4 true 412.2;
param t2 in 0 +- 0.01 true -0.004; param t3 in 0 +- 0.01 true 0.003;
param t4 in 0 +- 0.01 true 0.0015;
param px in 0 +- 4 true 1.5; param py in 0 +- 4 true -2.0; param pz in 120 +- 4 true 118.6;
robot arm(q1, q2, q3, q4, q5) {
  joint theta = q1, r = r1;
  joint alpha = pi / 2, theta = q2 + t2;
  joint d = d3, theta = q3 + t3;
  joint d = d4, theta = q4 + t4;
  joint alpha = -pi / 2, theta = q5;
}
table m = "arm5.csv" (separator = ";") {
  q1 = "J1" in deg, q2 = "J2" in deg, q3 = "J3" in deg, q4 = "J4" in deg, q5 = "J5" in deg
    : +- qe simulate in [-2.5, 2.5];
  x = "X" in m, y = "Y" in m, z = "Z" in m : +- e;
}
for k in 1..rows(m) {
  arm(m.q1[k], m.q2[k], m.q3[k], m.q4[k], m.q5[k]) at (px, py, pz)
    == (m.x[k], m.y[k], m.z[k]);
}
"""

# A 6-DOF tracker on a three-joint arm (standard DH): position and X-Y-Z Euler angles in
# degrees. SIX_DOF solves with the rotation matrices (as models/ur10_tracker6d.cal);
# SIX_DOF_GEN states each angle as a cell == expression, the form `calibc simulate` draws.
_SIX_DOF_HEAD = """units mm, rad;
const e = 0.05;
const e_rot = 2e-4;
param d1 in 200 +- 3 true 199.2; param a2 in 400 +- 3 true 401.1;
const a3 = 299.4;
param o2 in 0 +- 0.01 true 0.0031; param o3 in 0 +- 0.01 true -0.0022;
param tool_rz in 0 +- 0.01 true 0.004;
param tx in 50 +- 3 true 51.2;
robot arm(q1, q2, q3) dh {
  joint theta = q1, d = d1, alpha = pi / 2;
  joint theta = q2 + o2, a = a2;
  joint theta = q3 + o3, a = a3;
}
table m = "arm3.csv" {
  q1, q2, q3 : +- 0 simulate in [-1.5, 1.5];
  x, y, z : +- e;
  rx in deg, ry in deg, rz in deg : +- e_rot;
}
"""
SIX_DOF = _SIX_DOF_HEAD + """for k in 1..rows(m) {
  arm(m.q1[k], m.q2[k], m.q3[k]) at (tx, 0, 0) == (m.x[k], m.y[k], m.z[k]);
  compose(arm(m.q1[k], m.q2[k], m.q3[k]) axes, euler_xyz(0, 0, tool_rz))
    == euler_xyz(m.rx[k], m.ry[k], m.rz[k]);
}
"""
SIX_DOF_GEN = _SIX_DOF_HEAD + """for k in 1..rows(m) {
  arm(m.q1[k], m.q2[k], m.q3[k]) at (tx, 0, 0) == (m.x[k], m.y[k], m.z[k]);
  let R = compose(arm(m.q1[k], m.q2[k], m.q3[k]) axes, euler_xyz(0, 0, tool_rz));
  m.rx[k] == atan2(-R[6], R[9]);
  m.ry[k] == atan2(R[3], sqrt(sqr(R[1]) + sqr(R[2])));
  m.rz[k] == atan2(-R[2], R[1]);
}
"""

# PUMA 560, standard DH from its published table (a2 = 431.8, a3 = 20.3, d3 = 150.05,
# d4 = 431.8 mm), measured at a tool point 0.5 mm from joint 6's axis: th5 and al5 are barely
# seen by the data (the point hardly moves when joint 5's axis tilts), so they keep wide
# domains. 24 parameters: the base's pose (absorbing joint 1's offsets), joints 2-5, the tool.
PUMA560 = """units mm, rad;
const e = 0.1;
const qe = 1e-5;
param bx in 0 +- 5 true 1.3; param by in 0 +- 5 true -0.9; param bz in 0 +- 5 true 2.1;
param brx in 0 +- 0.005 true 0.0012; param bry in 0 +- 0.005 true -0.0021;
param brz in 0 +- 0.005 true 0.0017;
param th2 in 0 +- 0.01 true 0.0031; param a2 in 431.8 +- 3 true 432.6;
param al2 in 0 +- 0.01 true -0.0017;
param th3 in 0 +- 0.01 true -0.0024; param d3 in 150.05 +- 3 true 149.3;
param a3 in 20.3 +- 3 true 21.1; param al3 in -pi / 2 +- 0.01 true -pi / 2 + 0.0026;
param th4 in 0 +- 0.01 true 0.0043; param d4 in 431.8 +- 3 true 430.9;
param a4 in 0 +- 3 true 0.6; param al4 in pi / 2 +- 0.01 true pi / 2 - 0.0019;
param th5 in 0 +- 0.01 true -0.0036; param d5 in 0 +- 3 true -0.7;
param a5 in 0 +- 3 true 0.5; param al5 in -pi / 2 +- 0.01 true -pi / 2 + 0.0022;
param tx in 0 +- 3 true 0.4; param ty in 0 +- 3 true -0.3; param tz in 100 +- 3 true 100.5;
robot puma(q1, q2, q3, q4, q5, q6) dh {
  base x = bx, y = by, z = bz, rx = brx, ry = bry, rz = brz;
  joint theta = q1, alpha = pi / 2;
  joint theta = q2 + th2, a = a2, alpha = al2;
  joint theta = q3 + th3, d = d3, a = a3, alpha = al3;
  joint theta = q4 + th4, d = d4, a = a4, alpha = al4;
  joint theta = q5 + th5, d = d5, a = a5, alpha = al5;
  joint theta = q6;
}
table m = "puma.csv" {
  q1, q2, q3, q4, q5, q6 : +- qe simulate in [-2, 2];
  x, y, z : +- e;
}
for k in 1..rows(m) {
  puma(m.q1[k], m.q2[k], m.q3[k], m.q4[k], m.q5[k], m.q6[k]) at (tx, ty, tz)
    == (m.x[k], m.y[k], m.z[k]);
}
"""

# name: (model source, its table's file, the model that simulates the table)
ROBOTS = {
    "arm4_dh.cal": (ARM4_DH, "arm4.csv", "arm4_dh.cal"),
    "arm5_mdh.cal": (ARM5_MDH, "arm5.csv", "arm5_mdh.cal"),
    "arm3_6dof.cal": (SIX_DOF, "arm3.csv", "arm3_6dof_gen.cal"),
    "puma560.cal": (PUMA560, "puma.csv", "puma560.cal"),
}
GENERATORS = {"arm3_6dof_gen.cal": SIX_DOF_GEN}
