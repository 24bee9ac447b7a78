"""Orientation readings decided (issue #44): a 6-DOF tracker's Euler angles are measured sides
like a position's coordinates (elaborate/orientation.py), so a point check can prove a
campaign consistent. Simulated 6-DOF campaigns of a UR10 (`calibc simulate` on a 6-DOF model
with true values, small noise) are certified *consistent*, the truth inside; the rewriting
keeps what it must not touch (angles that wrap, a reading that enters another row)."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from click.testing import CliRunner

from calib_dsl import cli
from calib_dsl.compile.group import compile_model
from calib_dsl.elaborate.elaborator import Inputs, elaborate
from calib_dsl.pipeline import min_error
from tests.strategy.test_verdict import assert_said, verdict_of

MODELS = Path(__file__).resolve().parents[2] / "models"

# the chain parameters of models/ur10_simulated.cal, each drawn about its true value
CHAIN = {"alpha2": (1.5709, 0.01), "d2": (0.44, 5), "theta2": (0.0008, 0.01),
         "r2": (-0.26, 5), "alpha3": (0.0004, 0.01), "d3": (-613.29, 5),
         "theta3": (0.0003, 0.01), "alpha4": (-0.0007, 0.01), "d4": (-572.2, 5),
         "theta4": (-0.0025, 0.01), "alpha5": (1.5682, 0.01), "d5": (-0.12, 5),
         "theta5": (-0.0036, 0.01), "r5": (115.81, 5), "tx": (-0.77, 5), "ty": (-0.21, 5),
         "tz": (92.69, 5), "tool_rx": (0.0, 0.01), "tool_ry": (0.0, 0.01),
         "tool_rz": (-1.5708, 0.01)}
NOMINAL = {"alpha2": "ur10_alpha2", "d2": "ur10_d2", "theta2": "ur10_theta2",
           "r2": "ur10_r2", "alpha3": "ur10_alpha3", "d3": "ur10_d3", "theta3": "ur10_theta3",
           "alpha4": "ur10_alpha4", "d4": "ur10_d4", "theta4": "ur10_theta4",
           "alpha5": "ur10_alpha5", "d5": "ur10_d5", "theta5": "ur10_theta5", "r5": "ur10_r5",
           "tx": "0", "ty": "0", "tz": "93", "tool_rx": "0", "tool_ry": "0",
           "tool_rz": "-pi / 2"}


def six_dof_model(tmp: Path, draw: random.Random, e: float = 0.1, e_rot: float = 0.001,
                  extra: str = "", q_err: float = 1e-5) -> tuple[Path, dict[str, float]]:
    """A 6-DOF tracker model of a UR10 whose parameters are drawn within their priors (a
    fifth of the half-width about models/ur10_simulated.cal's true values), and its truth."""
    true = {n: t + draw.uniform(-0.2, 0.2) * w for n, (t, w) in CHAIN.items()}
    params = "\n".join(f"param {n} in {NOMINAL[n]} +- {CHAIN[n][1]} true {true[n]!r};"
                       for n in CHAIN)
    text = f"""units mm, rad;
include "{MODELS}/robots/ur10.cal";
const e = {e}; const e_rot = {e_rot}; const q_err = {q_err!r};
const base_x = 508.72; const base_y = -3567.26; const base_z = -1225.97;
const base_rx = 0.0011; const base_ry = -0.0036; const base_rz = 0.3496;
const alpha1 = ur10_alpha1; const d1 = ur10_d1; const theta1 = ur10_theta1; const r1 = ur10_r1;
const r3 = ur10_r3; const r4 = ur10_r4;
const alpha6 = ur10_alpha6; const d6 = ur10_d6; const theta6 = ur10_theta6; const r6 = ur10_r6;
{params}
table m = "sim.csv" {{
  q1, q2, q3, q4, q5, q6 : +- q_err simulate in [-pi, pi];
  x, y, z : +- e;
  rx, ry, rz : +- e_rot;
}}
for k in 1..rows(m) {{
  ur10(m.q1[k], m.q2[k], m.q3[k], m.q4[k], m.q5[k], m.q6[k]) at (tx, ty, tz)
    == (m.x[k], m.y[k], m.z[k]);
  compose(ur10(m.q1[k], m.q2[k], m.q3[k], m.q4[k], m.q5[k], m.q6[k]) axes,
          euler_xyz(tool_rx, tool_ry, tool_rz)) == euler_xyz(m.rx[k], m.ry[k], m.rz[k]);
}}
{extra}"""
    tmp.mkdir(parents=True, exist_ok=True)
    path = tmp / "six.cal"
    path.write_text(text, encoding="utf-8")
    return path, true


def simulated(tmp: Path, draw: random.Random, rows: int, q_err: float = 1e-5
              ) -> tuple[Path, dict[str, float]]:
    path, true = six_dof_model(tmp, draw, q_err=q_err)
    res = CliRunner().invoke(cli.main, ["simulate", str(path), "--configs", str(rows),
                                        "--seed", str(draw.randrange(10_000)), "-o",
                                        str(tmp / "sim.csv")], catch_exceptions=False)
    assert res.exit_code == 0, res.output
    return path, true


def certified_with_truth(tmp: Path, draw: random.Random, rows: int) -> str:
    path, true = simulated(tmp, draw, rows)
    code, data, text, err = verdict_of(path)
    assert_said(code, data, text, err)
    for name, t in true.items():
        lo, hi = data["parameters"][name]["result"]
        assert lo <= t <= hi, (name, lo, t, hi)
    return str(data["verdict"])


def moved_verdict(tmp: Path, draw: random.Random, rows: int = 16) -> str:
    """One coordinate of one row moved by 2-20 mm (either sign)."""
    path, _ = simulated(tmp, draw, rows)
    lines = (tmp / "sim.csv").read_text().splitlines()
    head = lines[0].split(",")
    k, column = 1 + draw.randrange(rows), draw.choice(["x", "y", "z"])
    cells = lines[k].split(",")
    cells[head.index(column)] = repr(float(cells[head.index(column)])
                                     + draw.uniform(2, 20) * draw.choice([-1, 1]))
    lines[k] = ",".join(cells)
    (tmp / "sim.csv").write_text("\n".join(lines) + "\n")
    code, data, text, err = verdict_of(path)
    assert_said(code, data, text, err)
    return str(data["verdict"])


def below_verdict(tmp: Path, draw: random.Random, rows: int = 16) -> str:
    """The position bound 3 % below the smallest consistent one (its bracket within 2 %),
    the joints exact."""
    path, _ = simulated(tmp, draw, rows, q_err=0.0)
    found = min_error(path, "e")
    assert found.lo is not None and found.hi / found.lo <= 1.02, (found.lo, found.hi)
    code, data, text, err = verdict_of(path, "-D", f"e={0.97 * found.hi!r}")
    assert_said(code, data, text, err)
    return str(data["verdict"])


def test_an_orientation_reading_is_three_measured_angles(tmp_path):
    """Three angle rows with measured sides, the nine matrix rows kept (they contract) but
    implied; every slot they merge is named so for every row of the loop compiled once."""
    path, _ = simulated(tmp_path, random.Random(1), 12)
    prog = compile_model(elaborate(path))
    assert prog.op_counts.get("atan2") == 3 * 12
    assert prog.rows is not None and len(prog.slots.implied) == 9 * 12
    unrolled = compile_model(elaborate(path, inputs=Inputs(unroll=True)))
    assert len(unrolled.slots.implied) == 9 * 12


def test_a_simulated_six_dof_campaign_is_certified_consistent(tmp_path):
    assert certified_with_truth(tmp_path, random.Random(4404), 16) == "consistent"


@pytest.mark.slow
def test_one_six_dof_draw_of_each_fault(tmp_path):
    draw = random.Random(4406)
    assert moved_verdict(tmp_path / "moved", draw) == "inconsistent"
    assert below_verdict(tmp_path / "below", draw) == "inconsistent"


def test_angles_that_wrap_are_compared_as_matrices(tmp_path):
    """A reading whose interval reaches past 180 degrees (rx here): no angle row, no implied
    row (the principal angle could not equal it)."""
    path, _ = simulated(tmp_path, random.Random(2), 6)
    lines = (tmp_path / "sim.csv").read_text().splitlines()
    head, first = lines[0].split(","), lines[1].split(",")
    first[head.index("rx")] = repr(3.1412)  # 1 mrad inside pi, and e_rot = 1 mrad
    lines[1] = ",".join(first)
    (tmp_path / "sim.csv").write_text("\n".join(lines) + "\n")
    prog = compile_model(elaborate(path))
    assert "atan2" not in prog.op_counts and not prog.slots.implied


def test_a_reading_used_elsewhere_is_not_implied(tmp_path):
    """An angle that also enters another constraint: the proof would move it under that
    row too, so the matrix rows stay rows to prove."""
    draw = random.Random(3)
    path, _ = six_dof_model(tmp_path, draw, extra="var w in [-10, 10];\nw == m.rx[1] * 2;\n")
    source = path.read_text()
    simulated(tmp_path, random.Random(3), 6)  # writes sim.csv (and the model, overwritten)
    path.write_text(source)
    prog = compile_model(elaborate(path))
    assert prog.op_counts.get("atan2") == 3 * 6
    assert not prog.slots.implied
