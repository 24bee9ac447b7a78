"""Certified points near the predictions' extremes, closer than a linearized LP's optimum
pulled back along a segment.

A linearized LP's optimum lies beyond the solution set where the rows curve; pulled back
towards a certified point along the segment, it stops where the segment leaves the set,
short of the extreme. Instead, as the inner bounds do (inner/bounds.py `_end`), each
candidate's LP is solved again with the rows its check found violated moved inside by what
they stuck out (further where they fail again): its optimum slides along the set's boundary
instead of back towards the start. Every open candidate is checked in one pass per
correction, and only those still failing after the last are pulled back. Each point is
proven by certify_point (or existence.py's proof): the LPs only propose.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from calib_dsl.analysis.certify_point import PointCheck, check_points
from calib_dsl.analysis.existence import prove_point
from calib_dsl.inner.lp import LinearModel
from calib_dsl.ir.program import Program
from calib_dsl.lp.highs import load, optimal
from calib_dsl.settings import InnerSettings, LPSettings, Settings

Found = tuple[np.ndarray, np.ndarray]  # a certified point and its readings
Basis = Any  # HiGHS's own basis object (kept_basis)
# (starts, their readings, candidates, their readings) -> per candidate a certified point
# on the segment from its start, or None
PullBack = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], list[Found | None]]


@dataclass
class Candidates:
    """LP optima over one linearized model `lm`: per candidate its objective (over the
    model's columns), its step (the optimum) and the basis it ended on (None: none kept)."""

    lm: LinearModel
    objectives: np.ndarray
    steps: np.ndarray
    bases: list[Basis | None]


def corrected(prog: Program, found: Candidates, start: Found, settings: Settings,
              pull_back: PullBack) -> list[Found | None]:
    """Per candidate, a certified point near its LP's optimum: the optimum where it is
    proven, else its LP's optimum with the violated rows tightened
    (`settings.prediction_corrections` times at most), and one still failing (or whose
    tightened LP had no optimum: from its last) pulled back towards `start` (a certified
    point) by `pull_back`; None where none was proven."""
    lm, k = found.lm, len(found.steps)
    out: list[Found | None] = [None] * k
    tighten = np.zeros((k, lm.rows))
    steps, bases = found.steps.copy(), list(found.bases)
    open_ = np.arange(k)
    stuck: list[int] = []
    for round_ in range(settings.prediction_corrections + 1):
        if not len(open_):
            break
        failed = _checked(prog, lm, steps, open_, out)
        if round_ == settings.prediction_corrections:
            open_ = np.array(sorted(failed), dtype=np.int64)
            break
        for i, check in failed.items():
            _tightened(lm, tighten[i], check, settings.inner)
        order = sorted(failed)
        solved = _resolved(lm, found.objectives[order], tighten[order],
                           [bases[i] for i in order], settings.lp)
        for i, (y, basis) in zip(order, solved, strict=True):
            if y is not None:
                steps[i], bases[i] = y, basis
        # (an LP its tightened rows left infeasible is pulled back from its last optimum)
        stuck.extend(i for i, (y, _) in zip(order, solved, strict=True) if y is None)
        open_ = np.array([i for i, (y, _) in zip(order, solved, strict=True)
                          if y is not None], dtype=np.int64)
    open_ = np.array(sorted([*open_.tolist(), *stuck]), dtype=np.int64)
    if len(open_):
        ends = [lm.point(steps[i]) for i in open_]
        back = pull_back(np.repeat(start[0][None], len(open_), axis=0),
                         np.repeat(start[1][None], len(open_), axis=0),
                         np.array([p for p, _ in ends]), np.array([r for _, r in ends]))
        for j, w in zip(open_.tolist(), back, strict=True):
            out[j] = w
    return out


def _checked(prog: Program, lm: LinearModel, steps: np.ndarray, open_: np.ndarray,
             out: list[Found | None]) -> dict[int, PointCheck]:
    """The open candidates' points checked in one pass: those proven into `out`, the
    others' checks returned (by candidate)."""
    at = [lm.point(steps[i]) for i in open_]
    points, readings = np.array([p for p, _ in at]), np.array([r for _, r in at])
    failed = {}
    for i, p, r, c in zip(open_, points, readings, check_points(prog, points, readings),
                          strict=True):
        if c.holds or prove_point(prog, p, r, c):
            out[int(i)] = (p, r)
        else:
            failed[int(i)] = c
    return failed


def _tightened(lm: LinearModel, tighten: np.ndarray, check: PointCheck,
               inner: InnerSettings) -> None:
    """inner/bounds.py `_end`'s rule, in place: each violated row moved inside by
    `overshoot` times its excess, a row failing again (its remainder exceeds what it was
    moved by: it was not binding) at least `escalate` times further, a row between two
    computed values (failing by its remainder, not its difference) doubled."""
    excess, computed = lm.excess(check)
    again = (excess > 0) & (tighten > 0)
    before = tighten[again]
    tighten += inner.overshoot * excess
    tighten[again] = np.maximum(tighten[again], inner.escalate * before)
    tighten[computed] = np.maximum(2.0 * tighten[computed], inner.computed_aim)


def _resolved(lm: LinearModel, objectives: np.ndarray, tighten: np.ndarray,
              bases: list[Basis | None], lp: LPSettings
              ) -> list[tuple[np.ndarray | None, Basis | None]]:
    """Each LP of max c.y over `lm` with its rows tightened, from its own last basis (the
    same cost, narrower rows: a few dual pivots), the LPs shared between lp.workers HiGHS
    models; per LP its optimum and basis (None, None where it did not end optimal)."""
    workers = max(1, min(lp.workers, len(objectives)))

    def run(part: np.ndarray) -> list[tuple[np.ndarray | None, Basis | None]]:
        h = load(lm.rel, None, lp.iterations, lp.scaling)
        n = objectives.shape[1]
        cols, rows = np.arange(n, dtype=np.int32), np.arange(lm.rows, dtype=np.int32)
        got: list[tuple[np.ndarray | None, Basis | None]] = []
        for i in part:
            b_lo, b = lm.bounds(tighten[i])
            inf = 1e300  # HiGHS's infinity: anything beyond 1e20
            h.changeRowsBounds(lm.rows, rows, np.maximum(b_lo, -inf), np.minimum(b, inf))
            h.changeColsCost(n, cols, -objectives[i].astype(float))
            basis = bases[i]
            if basis is not None:
                restart(h, basis)
            h.setOptionValue("time_limit", h.getRunTime() + lp.seconds)
            h.run()
            got.append((np.asarray(h.getSolution().col_value), kept_basis(h))
                       if optimal(h) else (None, None))
        return got

    with ThreadPoolExecutor(workers) as pool:
        parts = np.array_split(np.arange(len(objectives)), workers)
        return [x for part in pool.map(run, parts) for x in part]


def kept_basis(h: Any) -> Basis | None:
    """The model's basis as HiGHS's own object, a copy (reading its statuses into arrays
    makes a Python object a status: more than a small LP's re-solve); None where none."""
    b = h.getBasis()
    return b if b.valid else None


def restart(h: Any, basis: Basis) -> None:
    """The next solve from `basis` (kept_basis's, from a model of the same rows and columns):
    set as it is. HiGHS completes an "alien" basis first (a factorization that finds which
    columns to swap in, as lp/highs.py's set_basis needs for a mapped one), more than many
    of these re-solves' pivots; only a basis it refuses as it is is set again as alien."""
    import highspy

    basis.alien = False
    if h.setBasis(basis) != highspy.HighsStatus.kOk:
        basis.alien = True
        h.setBasis(basis)
