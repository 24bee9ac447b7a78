"""The accuracy statement's least-squares polish (numpy only) reaches scipy's fit, stays in
the domains, and says when it stopped on its budget."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from calib_dsl.accuracy.fit import polish
from calib_dsl.analysis.lsq import estimate, residuals
from calib_dsl.pipeline import load
from calib_dsl.relax.layout import independents
from calib_dsl.settings import DEFAULT

ROOT = Path(__file__).resolve().parents[2]


def test_the_polish_reaches_scipys_fit_from_the_domains_middle():
    prog = load(ROOT / "models" / "ur10_simulated.cal")
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    mine = polish(prog, 0.5 * (lo + hi), DEFAULT)
    theirs = estimate(prog, start=0.5 * (lo + hi))
    assert mine.converged and np.all((lo <= mine.values) & (mine.values <= hi))
    assert mine.rms <= theirs.rms * (1 + 1e-6)
    r, jac = residuals(prog, mine.values)
    # the gradient of the sum of squares vanishes at an interior optimum
    inside = (mine.values > lo) & (mine.values < hi)
    grad = (jac.T @ r)[inside]
    assert np.linalg.norm(grad) <= 1e-4 * np.linalg.norm(jac[:, inside]) * np.linalg.norm(r)


def test_a_polish_out_of_steps_is_not_converged():
    prog = load(ROOT / "models" / "ur10_simulated.cal")
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    fit = polish(prog, lo.copy(), replace(DEFAULT, fit_steps=1))
    assert not fit.converged
    assert np.all((lo <= fit.values) & (fit.values <= hi))


def test_a_polish_from_a_fit_with_its_rows_evaluates_them_once_without_jacobian(monkeypatch):
    """From scipy's fit with its rows (Estimate.rows), the polish evaluates every row once,
    without the Jacobian (the linearized rows expect no gain, and the trial confirms it),
    and ends at the fit's sum of squares within the tolerance; from the domains' middle it
    needs Jacobians, and reaches the same."""
    import calib_dsl.analysis.lsq as lsq_module

    prog = load(ROOT / "models" / "ur10_simulated.cal")
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    theirs = estimate(prog, start=0.5 * (lo + hi))
    assert theirs.converged and theirs.rows is not None
    calls: list[bool] = []
    real = lsq_module.linearized

    def counted(*args, **kwargs):
        calls.append(kwargs.get("jacobian", True))
        return real(*args, **kwargs)

    monkeypatch.setattr(lsq_module, "linearized", counted)
    seen: dict = {}
    mine = polish(prog, theirs.values, DEFAULT, seen, theirs.rows)
    assert calls == [False]
    assert mine.converged and mine.rms ** 2 <= theirs.rms ** 2 * (1 + DEFAULT.fit_tolerance)
    assert seen[theirs.values.tobytes()] is theirs.rows and mine.values.tobytes() in seen
    calls.clear()
    afresh = polish(prog, 0.5 * (lo + hi), DEFAULT)
    assert calls[0] and afresh.converged
    assert afresh.rms ** 2 == pytest.approx(mine.rms ** 2, rel=10 * DEFAULT.fit_tolerance)
