"""Rounds on a working set of the rows, grown by the rows the LPs' optima violate
(strategy/working.py): on random robots with simulated data (known truth) the box holds the
truth, every phase runs on the working set, the check sees every row and its violated rows
join; and a UR10 campaign of thousands of rows gets the second-order rounds."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.compile.chunks import start_rows
from calib_dsl.relax.layout import independents
from calib_dsl.settings import DEFAULT
from calib_dsl.strategy.tight import solve_tight
from tests.relax.test_linearize import random_robot, robot_draws

SMALL = DEFAULT.tuned(working_rows=6)  # a working set of 6 rows, grown by the checks


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(**robot_draws(st.integers(14, 30)))
def test_a_working_set_solve_holds_the_truth(tmp_path_factory, seed, joints, rows,
                                             formulation):
    sim = random_robot(tmp_path_factory.mktemp("working"), seed, joints, rows, formulation)
    prog = sim.prog
    if prog.rows is None:
        return
    # (in the original unknowns: a program rewritten along combinations has its rows
    # unrolled, and has no working set)
    sol = solve_tight(prog, settings=SMALL, combinations=False)
    assert sol.status != "infeasible"
    for k, truth in zip(independents(prog), sim.p_true, strict=True):
        assert sol.lo[k] <= truth <= sol.hi[k], prog.slots.names[k]
    labels = [step.label for step in sol.history.steps]
    assert any("6 working rows" in label for label in labels), labels


@settings(max_examples=6, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(**robot_draws(st.integers(20, 30)))
def test_the_working_set_reaches_the_all_rows_fixed_point(tmp_path_factory, seed, joints,
                                                          rows, formulation):
    """Grown by the rows its optima violate, a working set of 6 rows ends about where the
    rounds on all rows end (not looser by more than a few percent of any width), and the
    truth stays inside both."""
    sim = random_robot(tmp_path_factory.mktemp("fixed"), seed, joints, rows, formulation)
    prog = sim.prog
    if prog.rows is None:
        return
    grown = solve_tight(prog, settings=SMALL.tuned(working_passes=6), combinations=False,
                        split=False)
    whole = solve_tight(prog, combinations=False, split=False)
    if grown.status == "infeasible" or whole.status == "infeasible":
        return
    ind = independents(prog)
    for sol in (grown, whole):
        for k, truth in zip(ind, sim.p_true, strict=True):
            assert sol.lo[k] <= truth <= sol.hi[k], prog.slots.names[k]
    wide = whole.hi[ind] - whole.lo[ind]
    moved = wide > 0
    ratio = (grown.hi[ind] - grown.lo[ind])[moved] / wide[moved]
    assert np.median(ratio) <= 1.05, ratio


def test_the_working_set_starts_spread_over_the_rows(tmp_path):
    prog = random_robot(tmp_path, 3, 2, 25, "matrix").prog  # (seed 3: a spatial robot)
    every = start_rows(prog, 30)
    assert every is not None and np.array_equal(every, np.arange(25))  # fewer: all of them
    start = start_rows(prog, 10)
    assert start is not None and len(start) == 10
    assert start[0] == 0 and start[-1] == 24 and np.all(np.diff(start) > 0)


def test_a_resumed_pass_skips_only_the_ends_no_joined_row_cuts_off():
    """A pass that resumes the fine rounds after a check solves no LP again for an end whose
    optimum no row found cuts off (working._settled), and solves again every end that one
    did; bench/checks/test_working_ur10.py runs it through a UR10 campaign whose third pass
    skips some ends (the box that of re-solving every end)."""
    from calib_dsl.strategy import working

    ends = {(0, 1.0), (0, -1.0), (3, 1.0), (5, -1.0)}
    cut = {(0, -1.0), (5, -1.0), (7, 1.0)}  # (an end of another pass's cut: not this one's)
    assert working._settled(ends, cut) == frozenset({(0, 1.0), (3, 1.0)})
    assert working._settled(ends, set()) == frozenset(ends)
    assert working._settled(ends, ends) == frozenset()


@pytest.mark.slow
def test_a_pass_cut_short_goes_on_where_the_check_joins_no_row(tmp_path, monkeypatch):
    """A pass that a check follows ends after one fine round (fine_rounds_per_check); where
    the check then joins no row, the rounds go on on the same rows until their phases end
    (working.py). With the check made to join none, the solve runs more than that one fine
    round, and its box is as narrow as the rounds' run to their end without the cut
    (widths to 1e-4), the truth inside. Without the guard it stops after one fine round."""
    from calib_dsl.elaborate.elaborator import Inputs
    from calib_dsl.pipeline import load
    from calib_dsl.strategy import working
    from calib_dsl.studies.campaign import Campaign
    from calib_dsl.studies.simulate import simulate
    from tests.test_ur10 import TRACKER, _noisy_simulation_model, truth

    table = tmp_path / "sim.csv"
    simulate(_noisy_simulation_model(tmp_path, 0.05), 30, 5, out_csv=table,
             campaign=Campaign("random", 4, systematic=0.6))
    prog = load(TRACKER, inputs=Inputs(data={"m": table}, consts={"e": "0.65"}))
    ind = independents(prog)
    none = (np.zeros(0, dtype=np.int64), set())
    monkeypatch.setattr(working.WorkingRows, "violated", lambda self, *a: none)
    monkeypatch.setattr(working.WorkingRows, "relaxed_violated", lambda self, *a: none)

    def solved(per_check: int):
        sol = solve_tight(prog, settings=DEFAULT.tuned(working_rows=10,
                                                       fine_rounds_per_check=per_check),
                          split=False, combinations=False)
        assert sol.status == "contracted"
        for name, t in truth().items():
            i = prog.slots.names.index(name)
            assert sol.lo[i] <= t <= sol.hi[i], name
        return sol

    cut, whole = solved(1), solved(40)
    assert whole.work.fine_rounds > 1  # (the case's rounds have more than one to run)
    assert cut.work.fine_rounds > 1
    ratio = (cut.hi[ind] - cut.lo[ind]) / (whole.hi[ind] - whole.lo[ind])
    assert np.all(ratio <= 1.0 + 1e-4), ratio
