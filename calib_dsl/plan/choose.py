"""Choosing N of the candidates: the classical designs, the LP exchange, and predictions.

The stages, each from the last: D-optimal (greedy, exchanges), the unknowns' log variances
(exchanges), the widths of the linearized feasible set (the LP exchange, refine.py). Each
stage's design is a finalist; final.py picks among them by simulated solves.

A predicted width is what a solve of the design would give to first order: the hull of the
feasible set of noisy rows (noise uniform within each row's bound, as the simulator draws
it), the median over a few draws, in the model's units.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from calib_dsl.lp.hull import Hull
from calib_dsl.plan.classical import d_optimal, marginal_exchange
from calib_dsl.plan.linear import Linear
from calib_dsl.plan.refine import hull_of, refine, rows_of, score
from calib_dsl.settings import Settings


@dataclass(frozen=True)
class Stage:
    """One stage's design: its name, its rows (candidate indices), its LP score (mean log
    width over domain, noise-free: lower is better) and the seconds it took."""

    name: str
    rows: np.ndarray
    score: float
    seconds: float


def stages(lin: Linear, count: int, settings: Settings,
           given: np.ndarray | None = None) -> list[Stage]:
    """The finalists for `count` configurations (`given`: rows already measured, in the
    same units, which every design keeps)."""
    box = lin.box
    out = []
    start = time.perf_counter()
    d = d_optimal(lin.blocks, count, settings.plan_ridge, settings.plan_passes,
                  settings.plan_shortlist, given)
    out.append(Stage("d-optimal", d, _score(lin, d, given), time.perf_counter() - start))
    start = time.perf_counter()
    m = marginal_exchange(lin.blocks, d, settings.plan_ridge, settings.plan_passes,
                          settings.plan_shortlist, given)
    out.append(Stage("variances", m, _score(lin, m, given), time.perf_counter() - start))
    start = time.perf_counter()
    ref = refine(lin.blocks, m, box, settings.plan_tries, settings.plan_lp_hulls, given,
                 settings.plan_improvement)
    out.append(Stage("lp-widths", ref.chosen, ref.score, time.perf_counter() - start))
    return out


def _score(lin: Linear, rows: np.ndarray, given: np.ndarray | None) -> float:
    return score(hull_of(rows_of(lin.blocks, rows, given), lin.box), lin.box)


def predicted(lin: Linear, rows: np.ndarray, draws: int, seed: int,
              given: np.ndarray | None = None) -> np.ndarray:
    """Each unknown's predicted width (model units): the median over `draws` noisy hulls."""
    a = rows_of(lin.blocks, rows, given)
    rng = np.random.default_rng([seed, 43])
    widths = [_widths(lin, hull_of(a, lin.box, rng.uniform(-1.0, 1.0, len(a))))
              for _ in range(draws)]
    return np.median(np.array(widths), axis=0)


def _widths(lin: Linear, hull: Hull) -> np.ndarray:
    return (hull.hi - hull.lo) * lin.half
