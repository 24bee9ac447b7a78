"""The robot's accuracy over the data's own poses: measured minus predicted per measured column
and per configuration (a data row), at a few parameter points (floating point: statistics, not
proofs), and a guaranteed bound on the distance between the measurement and the prediction of
every parameter vector of the result box (residuals.py's ranges, rounded upward: a proof).

A configuration's distance is the Euclidean norm of its measured columns' residuals (a
tracker's x, y, z: the position error), columns read in an angle unit left out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.analysis.lsq import Linearized, linearized
from calib_dsl.analysis.residuals import Ranges
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents

# a float sum of n non-negative terms is within n ulps of the exact one, and a square root
# within one: the bound is scaled up by this many ulps per term, plus a few, then stepped up
_ULP = 2.0 ** -52


@dataclass(frozen=True)
class Layout:
    """The measured values of a program as a table: configurations (table, model row) by
    measured columns; `side[i, j]` the slot of configuration i's column j (-1: not measured)."""

    configurations: list[tuple[str, int]]
    columns: list[str]
    side: np.ndarray


def layout(prog: Program) -> Layout:
    s = prog.slots
    sides = s.measured_sides or {}
    assert not sides or (s.row_keys is not None and s.col_keys is not None)
    configs: dict[tuple[str, int], int] = {}
    columns: dict[str, int] = {}
    cells = []
    for k in sorted(sides):
        r, c = sides[k]
        key = (s.row_keys[r][0], s.row_keys[r][1])  # type: ignore[index]
        col = s.col_keys[c][1]  # type: ignore[index]
        cells.append((configs.setdefault(key, len(configs)),
                      columns.setdefault(col, len(columns)), k))
    side = np.full((len(configs), len(columns)), -1, dtype=np.int64)
    for i, j, k in cells:
        side[i, j] = k
    return Layout(list(configs), list(columns), side)


def point_residuals(prog: Program, at: Layout, p: np.ndarray,
                    lin: Linearized | None = None) -> np.ndarray:
    """Measured minus predicted at the parameter vector p (independents' order), readings at
    their middles: (configurations, columns), nan where a column is not measured or no row
    compares it (a merge of slots: `x == m.v[k]` makes x the cell) or the model is not
    defined at p. `lin`: the rows at p (linearized(prog, p, owners=False)) if made already."""
    lin = linearized(prog, p, owners=False, jacobian=False) if lin is None else lin
    pick = _first_rows(lin.slots, at.side)
    out = np.full(at.side.shape, np.nan)
    has = pick >= 0
    out[has] = -lin.d[pick[has]]
    return out


def _first_rows(targets: np.ndarray, side: np.ndarray) -> np.ndarray:
    """Per entry of `side` (a slot, or -1), the first row whose target it is (-1: none)."""
    slots, first = np.unique(targets, return_index=True)  # (each slot's first occurrence)
    if not len(slots):
        return np.full(side.shape, -1, dtype=np.int64)
    at = np.minimum(np.searchsorted(slots, side), len(slots) - 1)
    return np.where((slots[at] == side) & (side >= 0), first[at], -1).astype(np.int64)


def distances(residuals: np.ndarray, among: np.ndarray | None = None) -> np.ndarray:
    """Per configuration, the Euclidean norm of its measured columns' residuals (of the
    columns `among` marks, if given; nan where none has one)."""
    if among is not None:
        residuals = residuals[:, among]
    with np.errstate(invalid="ignore"):
        d = np.sqrt(np.nansum(residuals ** 2, axis=1))
    return np.where(np.all(np.isnan(residuals), axis=1), np.nan, d)


def bound_table(ranges: Ranges, at: Layout, consistent: bool = True) -> np.ndarray:
    """Per configuration and column, an upper bound on |measured - predicted| (readings at
    their values) for every parameter vector of the box; if `consistent`, for every
    consistent one only: the smaller of that and the error bound e plus how far the
    readings' errors move the prediction (a consistent vector predicts within e of the
    measurement at some readings within their errors). inf where no range was found."""
    index = {(t, r, c): i for i, (t, r, c) in enumerate(zip(ranges.tables, ranges.rows,
                                                              ranges.columns, strict=True))}
    worst = np.maximum(np.abs(ranges.lo), np.abs(ranges.hi))
    if consistent and ranges.slack is not None:
        with np.errstate(over="ignore"):
            allowed = np.nextafter(ranges.bound + ranges.slack, np.inf)
        worst = np.minimum(worst, allowed)
    k = np.array([[index.get((t, r, c), -1) for c in at.columns]
                  for t, r in at.configurations], dtype=np.int64).reshape(at.side.shape)
    found = np.where(k >= 0, worst[np.maximum(k, 0)] if len(worst) else np.inf, np.inf)
    return np.where(at.side >= 0, found, np.nan)


def distance_bounds(worst: np.ndarray, among: np.ndarray | None = None) -> np.ndarray:
    """Per configuration, an upper bound on sqrt(sum over its columns (those `among` marks)
    of worst^2): the float computation scaled up by its rounding errors' bound, then
    stepped up one ulp."""
    if among is not None:
        worst = worst[:, among]
    n = worst.shape[1] if worst.ndim == 2 else 0
    with np.errstate(over="ignore", invalid="ignore"):
        d = np.sqrt(np.nansum(worst ** 2, axis=1)) * (1.0 + (2 * n + 4) * _ULP)
    return np.nextafter(d, np.inf)


def nominal_point(prog: Program) -> np.ndarray:
    """The parameters before calibration: the centre of each `c +- w` (or `lsq +- w`) domain,
    else the middle of a finite domain, else the point of the domain nearest 0. A value
    stated with `true` is the truth a simulation used, not a nominal one: not used here."""
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    with np.errstate(invalid="ignore"):
        out = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), np.clip(0.0, lo, hi))
    for j, k in enumerate(ind):
        name = prog.slots.names[k]
        v = prog.true_values.get(name)
        if v is not None and name not in prog.true_stated:
            out[j] = v
    return out


def independent_point(prog: Program, true: dict[str, float | None]) -> np.ndarray | None:
    """The vector of `true` values (independents' order), or None if one is missing."""
    vals = [true.get(prog.slots.names[k]) for k in independents(prog)]
    return None if any(v is None for v in vals) else np.array(vals, dtype=float)


@dataclass(frozen=True)
class Accuracy:
    """The residuals at named parameter points (`points`: label -> (configurations, columns)
    measured minus predicted), and the guaranteed bounds over the result box: `worst` per
    configuration and column (largest |measured - predicted|), `bound` per configuration (on
    the distance), both for the consistent vectors; `box_worst` and `box_bound` the same for
    every vector of the box (consistent or not: looser where the box is)."""

    at: Layout
    points: dict[str, np.ndarray]
    worst: np.ndarray
    bound: np.ndarray
    box_worst: np.ndarray
    box_bound: np.ndarray
    among: np.ndarray  # per column, whether the distance counts it (not an angle)


def accuracy(prog: Program, ranges: Ranges, points: dict[str, np.ndarray],
             angles: frozenset[str] = frozenset(),
             seen: dict[bytes, Linearized] | None = None) -> Accuracy:
    """The accuracy at `points` (label -> parameter vector, independents' order) with the
    bounds of `ranges` (residuals.residual_ranges over the result box); the columns named
    in `angles` (measured in an angle unit) have their own statistics but no part in the
    distance, unless every column is one. `seen`: the rows at some points, made already
    (by their bytes)."""
    seen = seen or {}
    at = layout(prog)
    among = np.array([c not in angles for c in at.columns], dtype=bool)
    if not among.any():
        among[:] = True
    worst, box = bound_table(ranges, at), bound_table(ranges, at, consistent=False)
    return Accuracy(at, {k: point_residuals(prog, at, p, seen.get(p.tobytes()))
                         for k, p in points.items()},
                    worst, distance_bounds(worst, among), box, distance_bounds(box, among),
                    among)


def statistics(values: np.ndarray, signed: bool = False) -> dict[str, float | None]:
    """`mean` (of the signed values where `signed`, else of their sizes), `rms`, `p95` (the 95th
    percentile of the sizes) and `max` (the largest size) of the finite values; None where
    there are none."""
    v = values[np.isfinite(values)]
    if not len(v):
        return {"mean": None, "rms": None, "p95": None, "max": None}
    a = np.abs(v)
    return {"mean": float(np.mean(v if signed else a)), "rms": float(np.sqrt(np.mean(v ** 2))),
            "p95": float(np.percentile(a, 95)), "max": float(np.max(a))}
