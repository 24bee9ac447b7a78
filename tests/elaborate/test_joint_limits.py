"""Joint limits: `robot r(q1 in [lo, hi], ...)`, reaching the table columns they bound."""

from __future__ import annotations

import math

import pytest

from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.frontend.diagnostics import CalError
from tests.cli_run import run

ARM = """
param l1 in [0.9, 1.1] true 1; param l2 in [0.4, 0.6] true 0.5;
table m = "d.csv" {{ a, b : +- 1e-6 simulate in [-3, 3]; x, y, z : +- 1e-3; }}
robot arm({q1}, {q2}) {{
  joint theta = q1, r = 0;
  joint d = l1, theta = q2;
}}
for k in 1..rows(m) {{ arm(m.a[k], m.b[k]) at (l2, 0, 0) == (m.x[k], m.y[k], m.z[k]); }}
"""
DATA = "a,b,x,y,z\n0.1,0.2,1.4,0.1,0\n0.3,0.4,1.3,0.4,0\n"


def model(write_model, q1: str = "q1", q2: str = "q2"):
    return write_model(ARM.format(q1=q1, q2=q2), files={"d.csv": DATA})


def test_limits_reach_the_columns_of_the_joints_they_bound(write_model):
    m = elaborate(str(model(write_model, "q1 in [-2 * pi, 2 * pi]", "q2 in 0.5 +- 1")))
    assert m.joint_limits[("m", "a")][0] == pytest.approx(-2 * math.pi)
    assert m.joint_limits[("m", "b")] == (-0.5, 1.5)
    sim = elaborate(str(model(write_model, "q1", "q2 in [-1, 1]")), simulate_rows=2)
    assert sim.joint_limits == {("m", "b"): (-1.0, 1.0)}


def test_a_robot_without_limits_has_none(write_model):
    assert elaborate(str(model(write_model))).joint_limits == {}


@pytest.mark.parametrize("limit, says", [
    ("q1 in [-oo, 1]", "a joint limit is a finite range"),
    ("q1 in 2", "a joint limit is a finite range"),
    ("q1 in [2, 1]", "empty interval"),
    ("q1 in [1, x]", "unknown name 'x'"),
    ("q1 in", "expected an expression"),
])
def test_malformed_limits_are_located_errors(write_model, limit, says):
    path = model(write_model, limit)
    with pytest.raises(CalError, match=says.replace("(", r"\(")):
        elaborate(str(path))
    result = run("compile", path)
    assert result.exit_code == 2
    first = result.output.splitlines()[0]
    assert first.startswith(f"{path}:4:") and "error:" in first
