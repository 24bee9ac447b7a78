"""The verdicts' statistical claims (issue #44's Must show) over 20 drawn spatial robots each:
too heavy for `make test` (a whole solve, and for a bound below the smallest a bracket, per
draw), where one draw of each case runs (tests/strategy/test_verdict_spatial.py and
test_verdict_orientation.py) and the planar arm's 20 draws (tests/strategy/test_verdict.py)."""

from __future__ import annotations

import random

import pytest

from tests.strategy import test_verdict_orientation as six_dof
from tests.strategy import test_verdict_spatial as spatial

DRAWS = 20  # the ">= 95 % of draws": one undecided draw in 20 at most


# each robot's fault cases with the seeds of their draws (moved coordinate, bound below)
FAULTS = [(spatial, "ur5", (44, 45)), (six_dof, "six_dof", (4407, 4408))]


@pytest.mark.parametrize("robot, seeds", [(r, s) for r, _, s in FAULTS],
                         ids=[name for _, name, _ in FAULTS])
@pytest.mark.parametrize("case", ["moved", "below"])
def test_faults_are_proven_inconsistent_in_most_draws(tmp_path, robot, seeds, case):
    draw = random.Random(seeds[0] if case == "moved" else seeds[1])
    run = robot.moved_verdict if case == "moved" else robot.below_verdict
    verdicts = [run(tmp_path / f"{case}{i}", draw) for i in range(DRAWS)]
    assert "consistent" not in verdicts
    assert verdicts.count("inconsistent") >= 0.95 * len(verdicts), verdicts


def test_the_ur5_truth_is_never_called_inconsistent(tmp_path):
    draw = random.Random(46)
    verdicts = [spatial.truth_verdict(tmp_path / f"t{i}", draw) for i in range(DRAWS)]
    assert "inconsistent" not in verdicts
    assert verdicts.count("consistent") >= 0.95 * len(verdicts), verdicts
