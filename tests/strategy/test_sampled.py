"""Rounds on a sample of the rows, checked on all of them (strategy/sampled.py): on random
robots with simulated data (known truth) the box holds the truth, the round on all rows
runs, and its binding rows join the sample."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.compile.chunks import spread_rows
from calib_dsl.relax.layout import independents
from calib_dsl.settings import DEFAULT
from calib_dsl.strategy.tight import solve_tight
from tests.relax.test_linearize import random_robot, robot_draws

SMALL = replace(DEFAULT, sample_rows=6, sample_gain=0.0)  # a sample of 6 rows, grown always


@pytest.mark.slow
@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(**robot_draws(st.integers(14, 30)))
def test_a_sampled_solve_holds_the_truth(tmp_path_factory, seed, joints, rows, formulation):
    sim = random_robot(tmp_path_factory.mktemp("sampled"), seed, joints, rows, formulation)
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
    prog = random_robot(tmp_path, 3, 2, 25, "matrix").prog  # (seed 3: a spatial robot)
    assert spread_rows(prog, 13) is None  # 25 rows: not over twice the sample
    sample = spread_rows(prog, 10)
    assert sample is not None and len(sample) == 10
    assert sample[0] == 0 and sample[-1] == 24 and np.all(np.diff(sample) > 0)
