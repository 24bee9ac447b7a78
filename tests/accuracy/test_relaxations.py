"""The relaxation the predictions run over (accuracy/relaxations.py): on a planar arm
measured with errors small beside its joint readings' effect, the first-order relaxation's
rows are the thinner and it is taken: its predictions hold the held-out truths, are narrower
than the second order's and their inner ends are certified; with a joint offset measured
with wide errors (curved over a wide box) the second order is kept."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.accuracy.predict import Calibrated, Source, held_at, predict
from calib_dsl.accuracy.relaxations import prediction_relaxation, thickness
from calib_dsl.analysis.certify_point import check_point
from calib_dsl.analysis.existence import prove_point
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.pipeline import predict_at, solve
from calib_dsl.problem import Problem
from calib_dsl.relax.layout import independents
from calib_dsl.relax.linearize import relax
from calib_dsl.relax.quadratic import FAMILY
from calib_dsl.settings import DEFAULT
from tests.accuracy.test_certified_predictions import READING, assert_inner_ends, table, tip

EXAMPLES = Path(__file__).resolve().parents[2] / "models" / "examples"
NARROW = 2e-6  # beside the readings' +- 1e-6 rad over arms of about 1.5


# the arm with an offset on its first joint: curved in its parameters (the lengths alone
# enter linearly, and a first-order relaxation pays no curvature)
OFFSET = """param l1 in [0.8, 1.2]; param l2 in [0.3, 0.7]; param o1 in [-0.2, 0.2];
include "planar_arm_robot.cal";
const e = 1e-4;
table m = "planar_arm.csv" { q1, q2 : +- 1e-6; x, y : +- e; }
for k in 1..rows(m) {
  let p = tip(m.q1[k] + o1, m.q2[k]);
  (p[1], p[2]) == (m.x[k], m.y[k]);
  p[3] == 0;
}
"""


def _campaign(tmp: Path, lengths: tuple[float, float], e: float, seed: int, rows: int = 30,
              offset: float = 0.0) -> tuple[Inputs, Path, np.ndarray]:
    """Measurements of the planar arm (with a first joint's `offset`: planar_arm.cal's
    copy in OFFSET) at `rows` random poses (noise uniform within e), and 6 held-out poses
    with their true positions."""
    rng = np.random.default_rng(seed)
    for name in ("planar_arm.cal", "planar_arm_robot.cal"):
        shutil.copy(EXAMPLES / name, tmp)
    if offset:
        (tmp / "planar_arm.cal").write_text(OFFSET)
    q = rng.uniform(-np.pi, np.pi, (rows, 2))
    x, y = tip(*lengths, q[:, 0] + offset, q[:, 1])
    noisy = (x + rng.uniform(-e, e, rows), y + rng.uniform(-e, e, rows))
    train = table(tmp / "train.csv", q, noisy)
    qh = rng.uniform(-np.pi, np.pi, (6, 2))
    truth = np.array(tip(*lengths, qh[:, 0] + offset, qh[:, 1])).T
    return (Inputs(data={"m": train}, consts={"e": repr(e)}),
            table(tmp / "held.csv", qh, (truth[:, 0], truth[:, 1])), truth)


def _chosen(tmp: Path, inputs: Inputs, settings=DEFAULT):
    problem = Problem.load(tmp / "planar_arm.cal", "matrix", inputs, settings.fits,
                           settings.sampling)
    sol = solve(problem.program, settings=settings)
    return problem, sol, prediction_relaxation(problem.program, sol.lo, sol.hi, settings)


@settings(max_examples=10, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.floats(0.85, 1.15), st.floats(0.35, 0.65), st.integers(0, 2 ** 31))
def test_narrow_errors_predict_over_the_first_order_soundly(tmp_path, l1, l2, seed):
    inputs, held, truth = _campaign(tmp_path, (l1, l2), NARROW, seed)
    problem, sol, chosen = _chosen(tmp_path, inputs)
    assert chosen is not None and chosen[0].family == "first order" and chosen[1] is None
    _, p = predict_at(problem, held)
    assert p is not None
    assert np.all(p.lo <= truth) and np.all(truth <= p.hi)
    some = ~np.isnan(p.inner_lo)
    assert some.any() and p.inner_from is not None and p.inner_points is not None
    assert_inner_ends(p, np.stack(held_q(held), axis=1), READING)
    prog = problem.program
    order = [p.names.index(prog.slots.names[k]) for k in independents(prog)]
    assert p.inner_readings is not None
    for w, r in zip(p.inner_points, p.inner_readings, strict=True):
        check = check_point(prog, w[order], r)
        assert check.holds or prove_point(prog, w[order], r, check)


def held_q(held: Path) -> tuple[np.ndarray, np.ndarray]:
    q = np.loadtxt(held, delimiter=",", skiprows=1)
    return q[:, 0], q[:, 1]


@pytest.mark.parametrize("seed", [3, 17])
def test_the_first_order_predicts_narrower_where_it_is_taken(tmp_path, seed):
    inputs, held, truth = _campaign(tmp_path, (1.02, 0.48), NARROW, seed)
    problem, sol, chosen = _chosen(tmp_path, inputs)
    assert chosen is not None and chosen[0].family == "first order"
    ind = independents(problem.program)
    box = {problem.program.slots.names[k]: (float(sol.lo[k]), float(sol.hi[k])) for k in ind}
    source = Source(problem.path, problem.formulation, problem.inputs, problem.model,
                    problem.with_table)
    widths = {}
    for name, rel in (("first", chosen), ("second", _second(problem, sol))):
        p = predict(held_at(source, held), Calibrated(box, DEFAULT, rel[0], rel[1]))
        assert np.all(p.lo <= truth) and np.all(truth <= p.hi)
        widths[name] = np.median(p.hi - p.lo)
    assert widths["first"] < widths["second"]


def _second(problem: Problem, sol):
    from calib_dsl.relax.quadratic import relax_quadratic

    fine = relax_quadratic(problem.program, sol.lo, sol.hi, prune=0.0)
    assert fine is not None
    return fine[0], fine[1].center


def test_wide_errors_on_a_curved_model_keep_the_second_order(tmp_path):
    inputs, _, _ = _campaign(tmp_path, (1.02, 0.48), 0.02, 5, rows=10, offset=0.05)
    problem, sol, chosen = _chosen(tmp_path, inputs)
    assert chosen is not None and chosen[0].family == FAMILY
    first = relax(problem.program, sol.lo, sol.hi, cell_variables=False)
    assert first is not None and thickness(first) > thickness(chosen[0])
