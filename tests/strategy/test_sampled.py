"""Rounds on a sample of the rows, checked on all of them (strategy/sampled.py): on random
robots with simulated data (known truth) the box holds the truth, the round on all rows
runs, and its binding rows join the sample."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.compile.chunks import spread_rows
from calib_dsl.relax.layout import independents
from calib_dsl.settings import DEFAULT
from calib_dsl.strategy.tight import solve_tight
from tests.relax.test_linearize import clean_version, robot_source, simulate_cal

SMALL = replace(DEFAULT, sample_rows=6, sample_gain=0.0)  # a sample of 6 rows, grown always


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), joints=st.integers(1, 3), rows=st.integers(14, 30),
       formulation=st.sampled_from(["matrix", "rotation"]))
def test_a_sampled_solve_holds_the_truth(tmp_path_factory, seed, joints, rows, formulation):
    rng = np.random.default_rng(seed)
    source = robot_source(rng, joints, 1e-6, 1e-4, spatial=bool(seed % 2))
    sim = simulate_cal(tmp_path_factory.mktemp("sampled"), source, clean_version(source),
                       rows, seed, formulation)
    prog = sim.prog
    if prog.rows is None:
        return
    assert spread_rows(prog, SMALL.sample_rows) is not None
    # (in the original unknowns: a program rewritten along combinations has its rows
    # unrolled, and is never sampled)
    sol = solve_tight(prog, settings=SMALL, combinations=False)
    assert sol.status != "infeasible"
    for k, truth in zip(independents(prog), sim.p_true, strict=True):
        assert sol.lo[k] <= truth <= sol.hi[k], prog.slots.names[k]
    labels = [step.label for step in sol.history.steps]
    assert any("6 sampled rows" in label for label in labels), labels
    assert any("all rows" in label for label in labels), labels


def test_the_sample_is_spread_over_the_rows(tmp_path):
    rng = np.random.default_rng(3)
    source = robot_source(rng, 2, 1e-6, 1e-4, spatial=True)
    prog = simulate_cal(tmp_path, source, clean_version(source), 25, 3, "matrix").prog
    assert spread_rows(prog, 13) is None  # 25 rows: not over twice the sample
    sample = spread_rows(prog, 10)
    assert sample is not None and len(sample) == 10
    assert sample[0] == 0 and sample[-1] == 24 and np.all(np.diff(sample) > 0)
