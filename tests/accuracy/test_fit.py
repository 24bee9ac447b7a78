"""The accuracy statement's least-squares polish (numpy only) reaches scipy's fit, stays in
the domains, and says when it stopped on its budget."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

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
