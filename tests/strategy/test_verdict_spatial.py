"""The verdicts' properties (issue #44's Must show) on spatial robots that are not in the
repository: UR5-like arms whose 23 parameters are drawn within their priors, measured by
a simulated tracker (exact joints, `: +- 0`; positions within +- e). A file with one
coordinate moved by 2-20 mm, and a bound 3 % below the smallest consistent one, end as
*inconsistent* in >= 95 % of draws and never as *consistent*; an undecided one says so
(exit 4, stderr, the report's top, the JSON); the truth within its bounds is never called
inconsistent. The 20-draw versions run in bench/checks/test_verdict_draws.py; one draw of
each stays here."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from calib_dsl.pipeline import min_error
from tests.simulated_ur5 import JOINTS, PARAMS, header, simulate_rows, write_table
from tests.strategy.test_verdict import assert_said, verdict_of

E = 0.1  # mm, per axis
ROWS = 24
COLUMNS = ["q1", "q2", "q3", "q4", "q5", "q6", "x", "y", "z"]


def robot(tmp: Path, draw: random.Random) -> tuple[Path, list[dict[str, float]]]:
    """A UR5-like robot drawn about tests/simulated_ur5.py's true values (each within a
    fifth of its prior's half-width of them, so inside the prior), its model and its
    simulated table."""
    tmp.mkdir(parents=True, exist_ok=True)
    seed = draw.randrange(10_000)
    shares = {name: draw.uniform(-0.9, 0.9) for name in PARAMS}
    true = {name: t + shares[name] * w * 0.2 for name, (_, w, t) in PARAMS.items()}
    rows = simulate_rows(tmp, ROWS, seed, E, true)
    write_table(tmp / "data.csv", rows, COLUMNS, lambda r, c: r[c])
    model = tmp / "robot.cal"
    model.write_text(header(E, true) + 'table m = "data.csv" {\n  q1, q2, q3, q4, q5, q6 : +- 0;'
                     "\n  x, y, z : +- e;\n}\nfor k in 1..rows(m) {\n"
                     f"  ur5({JOINTS}) at (tx, ty, tz) == (m.x[k], m.y[k], m.z[k]);\n}}\n",
                     encoding="utf-8")
    return model, rows


def moved_verdict(tmp: Path, draw: random.Random) -> str:
    model, rows = robot(tmp, draw)
    k, column = draw.randrange(ROWS), draw.choice(["x", "y", "z"])
    mm = draw.uniform(2, 20) * draw.choice([-1, 1])
    rows[k] = {**rows[k], column: rows[k][column] + mm}
    write_table(tmp / "moved.csv", rows, COLUMNS, lambda r, c: r[c])
    code, data, text, err = verdict_of(model, "--data", str(tmp / "moved.csv"))
    assert_said(code, data, text, err)
    return str(data["verdict"])


def below_verdict(tmp: Path, draw: random.Random) -> str:
    model, _ = robot(tmp, draw)
    found = min_error(model, "e")
    below = 0.97 * found.hi
    assert found.lo is not None and found.hi / found.lo <= 1.02, (found.lo, found.hi)
    code, data, text, err = verdict_of(model, "-D", f"e={below!r}")
    assert_said(code, data, text, err)
    return str(data["verdict"])


def truth_verdict(tmp: Path, draw: random.Random) -> str:
    model, _ = robot(tmp, draw)
    code, data, text, err = verdict_of(model)
    assert_said(code, data, text, err)
    return str(data["verdict"])


@pytest.mark.slow
def test_one_draw_of_each(tmp_path):
    draw = random.Random(4401)
    assert moved_verdict(tmp_path / "moved", draw) == "inconsistent"
    assert truth_verdict(tmp_path / "truth", draw) == "consistent"
