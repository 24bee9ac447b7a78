"""--min-error asks every trial about the same priors: `lsq +- w` domains are the first
load's, not centred anew on each trial (problem.py's `Problem.keeping_priors`). Along a
direction the data do not see, a domain centred anew moves, and the point certified in one
trial's domains fell outside the next's (an internal error before, then a bracket 30 times
too wide)."""

from __future__ import annotations

from pathlib import Path

import pytest

from calib_dsl.pipeline import min_error
from tests.simulated_ur5 import JOINTS, header, simulate_rows, write_table

COLUMNS = ["q1", "q2", "q3", "q4", "q5", "q6", "x", "y", "z"]


@pytest.mark.slow
def test_min_error_with_lsq_priors_and_an_unseen_direction(tmp_path: Path) -> None:
    rows = simulate_rows(tmp_path, 40, seed=4, e=0.05)
    write_table(tmp_path / "data.csv", rows, COLUMNS, lambda r, c: r[c])
    text = header(0.05, with_true=False)
    for axis in "xyz":  # the base about the data's least-squares estimate
        text = text.replace(f"param base_{axis} in 0 +- 5;", f"param base_{axis} in lsq +- 5;")
    # r3 and r2 move the same way (the axes 2-3-4 are parallel): the data see their sum only
    text = text.replace("const r3 = ur5_r3;", "param r3 in ur5_r3 +- 5;")
    path = tmp_path / "robot.cal"
    path.write_text(text + 'table m = "data.csv" {\n  q1, q2, q3, q4, q5, q6 : +- 0;\n'
                    "  x, y, z : +- e;\n}\nfor k in 1..rows(m) {\n"
                    f"  ur5({JOINTS}) at (tx, ty, tz) == (m.x[k], m.y[k], m.z[k]);\n}}\n",
                    encoding="utf-8")
    found = min_error(path, "e")
    assert found.hi <= 0.05 * 1.01  # the data were drawn within 0.05 of the truth
    assert found.lo is not None and found.lo < found.hi


def test_every_trial_has_the_first_loads_lsq_domains(tmp_path: Path) -> None:
    from dataclasses import replace

    from calib_dsl.elaborate.elaborator import Inputs
    from calib_dsl.problem import Problem

    rows = simulate_rows(tmp_path, 12, seed=5, e=0.05)
    write_table(tmp_path / "data.csv", rows, COLUMNS, lambda r, c: r[c])
    path = tmp_path / "robot.cal"
    path.write_text(header(0.05, with_true=False).replace("param base_x in 0 +- 5;",
                                                          "param base_x in lsq +- 5;")
                    + 'table m = "data.csv" {\n  q1, q2, q3, q4, q5, q6 : +- 0;\n'
                    "  x, y, z : +- e;\n}\nfor k in 1..rows(m) {\n"
                    f"  ur5({JOINTS}) at (tx, ty, tz) == (m.x[k], m.y[k], m.z[k]);\n}}\n",
                    encoding="utf-8")
    first = Problem.load(path).keeping_priors()
    at = first.program.slots.names.index("base_x")
    want = (first.program.slots.lo[at], first.program.slots.hi[at])
    assert first.derive(Inputs()) is first
    # other rows, another bound: their own least squares would centre base_x elsewhere
    from calib_dsl.elaborate.rows import Selection, parse_ranges
    for inputs in (Inputs(rows={"": Selection(parse_ranges("1..6"))}),
                   replace(Inputs(), consts={"e": "0.07"})):
        other = first.derive(inputs).program
        j = other.slots.names.index("base_x")
        assert (other.slots.lo[j], other.slots.hi[j]) == want
        assert other.centred == first.program.centred
