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

from calib_dsl.analysis.residuals import residual_ranges, row_enclosures
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents
from calib_dsl.relax.ownership import NONE


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
    ranges = row_enclosures(prog, lo, hi, ind, owners=True)
    ev = ranges.ev
    if not len(ranges.lo):
        none = np.zeros(0, dtype=bool)
        return none, np.zeros(0, dtype=np.int64), none
    with np.errstate(invalid="ignore"):
        violated = (ranges.lo > 0) | (ranges.hi < 0)
    owners = ev.data_rows()
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
