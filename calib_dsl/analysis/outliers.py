"""Which data rows are outliers of a box (`calibc solve --outliers K`).

A data row (a configuration: all its measured values) is a *certain* outlier of the box B
when one of its constraint rows is proven violated at every point of B: the enclosure of the
row's difference over B (the mean-value form of relax/evaluation.py, readings over their
error bounds, every rounding covered) excludes 0. It is a *possible* one when it is not
certain and not proven satisfied at every point of B (each of its measured values' residual
range, analysis/residuals.py, inside its error bound; a row with other constraints than
measured values is never proven so). A constraint of no data row proven violated on B
proves that B holds no solution at all (`hard_violated`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.analysis.residuals import residual_ranges
from calib_dsl.ir.program import Program
from calib_dsl.relax.evaluation import Evaluation
from calib_dsl.relax.layout import independents
from calib_dsl.relax.ownership import NONE, row_owners
from calib_dsl.relax.relaxation import RHS_REL


@dataclass(frozen=True)
class Classified:
    certain: list[int]  # data row ids (Slots.row_keys), increasing
    possible: list[int]
    hard_violated: bool


def classify(prog: Program, lo: np.ndarray, hi: np.ndarray) -> Classified:
    """The certain and possible outliers of the box (over the program's slots)."""
    ind = independents(prog)
    violated, owners, measured = _violated_rows(prog, lo, hi, ind)
    certain = sorted({int(r) for r in owners[violated & (owners >= 0)]})
    owned = {int(r) for r in owners[owners >= 0]}
    unproven = {int(r) for r in owners[(owners >= 0) & ~measured]}  # not measured values
    unproven |= _unproven_measurements(prog, lo, hi, ind)
    possible = sorted((owned & unproven) - set(certain))
    return Classified(certain, possible, bool(np.any(violated & (owners == NONE))))


def _violated_rows(prog: Program, lo: np.ndarray, hi: np.ndarray, ind: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per constraint row: whether its enclosure over the box excludes 0, its data row, and
    whether it compares with a measured value (one that residual_ranges encloses)."""
    center = 0.5 * (lo[ind] + hi[ind])
    ev = Evaluation(prog, lo, hi, ind, center)
    rows = ev.run()
    if not rows:
        none = np.zeros(0, dtype=bool)
        return none, np.zeros(0, dtype=np.int64), none
    dlo, dhi = (np.concatenate([r[0][i] for r in rows]) for i in (0, 1))
    gmax = np.concatenate([np.maximum(np.abs(r[1][0]), np.abs(r[1][1])) for r in rows])
    qmax = np.concatenate([np.maximum(np.abs(r[2][0]), np.abs(r[2][1])) for r in rows])
    w = np.maximum(center - lo[ind], hi[ind] - center) * (1 + 4 * RHS_REL)
    with np.errstate(invalid="ignore"):  # 0 * inf: an unbounded unknown a row ignores
        spread = gmax @ w + (qmax @ ev.e if qmax.shape[1] else 0.0)
    spread = np.where(np.isnan(spread), np.inf, spread)
    err = RHS_REL * (spread + np.abs(dlo) + np.abs(dhi)) + 1e-300
    with np.errstate(invalid="ignore"):
        violated = (dlo - spread - err > 0) | (dhi + spread + err < 0)
    owners = row_owners(prog, ind, ev.sources, [r[5] for r in ev.rows])
    targets = ev.targets()
    measured = np.isin(targets, np.array(sorted(prog.slots.measured_sides or {}), dtype=int))
    return violated, owners, measured


def _unproven_measurements(prog: Program, lo: np.ndarray, hi: np.ndarray,
                           ind: np.ndarray) -> set[int]:
    """The data rows with a measured value whose residual range over the box is not inside
    its error bound."""
    s = prog.slots
    box = {s.names[k]: (float(lo[k]), float(hi[k])) for k in ind}
    ranges = residual_ranges(prog, box)
    ids = {key: i for i, key in enumerate(s.row_keys or [])}
    inside = (ranges.lo >= -ranges.bound) & (ranges.hi <= ranges.bound)
    return {ids[(t, r)] for t, r, ok in zip(ranges.tables, ranges.rows, inside.tolist(),
                                            strict=True) if not ok and (t, r) in ids}
