"""A caller's fit and sampling settings reach every least-squares estimate a feature starts
from (the conflict's ranking, advice, the reference hull, the report's least squares, the
lsq priors, a Chebyshev fit's start): each is called with the caller's budget and sample."""

from __future__ import annotations

from pathlib import Path

import pytest

from calib_dsl.analysis import chebyshev, lsq, priors
from calib_dsl.outliers import conflict
from calib_dsl.problem import load_model
from calib_dsl.settings import Settings
from calib_dsl.studies import advice, reference

ARM = Path(__file__).resolve().parent.parent / "models" / "examples" / "planar_arm.cal"
MINE = Settings().tuned(lsq_evaluations=7, prior_evaluations=9, lsq_rows=13, lsq_min_rows=3)


@pytest.fixture
def calls(monkeypatch):
    seen: list[tuple[int, object]] = []
    real = lsq.estimate

    def spy(prog, start=None, max_evaluations=30, sampling=None):
        seen.append((max_evaluations, sampling))
        return real(prog, start, max_evaluations, sampling)

    for module in (chebyshev, conflict, advice, priors, lsq):
        monkeypatch.setattr(module, "estimate", spy)
    return seen


def test_the_callers_settings_reach_each_estimate(calls):
    _, prog = load_model(ARM)
    conflict.ranked_ids(prog, MINE.fits, MINE.sampling)
    advice.advise(prog, MINE)
    reference.yardstick(load_model(ARM)[1], MINE)  # (imports estimate when called)
    chebyshev.proven_consistent(prog, MINE.fits, MINE.sampling)
    assert len(calls) == 4
    assert all(n == 7 and s is MINE.sampling for n, s in calls), calls


def test_the_priors_centre_with_the_callers_sample(calls):
    _, prog = load_model(ARM, centre=False)
    prog.priors = {prog.slots.names[i]: (1.0, 0.5) for i in prog.slots.declared[:1]}
    priors.centre_on_least_squares(prog, MINE.fits, MINE.sampling)
    assert calls and all(n == 9 and s is MINE.sampling for n, s in calls), calls
