"""Certified bounds from LP multipliers: whatever the LP solver returns, a bound is computed
again from its multipliers in floating point with every rounding error covered (weak
duality), so a wrong or inexact optimum can only make a bound looser, never wrong.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calib_dsl.lp.highs import BASIC, LOWER
from calib_dsl.relax.relaxation import RHS_ABS, RHS_REL, LinearRelaxation, Rows, transpose_times
from calib_dsl.settings import LPSettings

DENSE = LPSettings.dense_entries  # (the declared default: callers pass their settings')


def dot_up(x: np.ndarray, y: np.ndarray) -> float:
    """An upper bound on the exact dot product x.y of float vectors."""
    return float(_dots_up(x[None, :], y[None, :])[0])


def box_max_up(r_lo: np.ndarray, r_hi: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """An upper bound on max r.p over r in [r_lo, r_hi], p in [lo, hi]."""
    return float(box_maxes_up(r_lo[None, :], r_hi[None, :], lo, hi)[0])


def certified_max(rel: LinearRelaxation, c: np.ndarray, y: np.ndarray,
                  dense_entries: int = DENSE) -> float:
    """A rigorous upper bound on max c.p over the relaxation, from a dual guess y.

    y_i > 0 multiplies the row's upper side A_i p <= b_i, y_i < 0 its lower side
    A_i p >= b_lo_i (both give y_i A_i p <= y_i rhs_i); any such y is a certificate.
    """
    return float(certified_maxes(rel, c[None, :], y[None, :], dense_entries)[0])



def certified_maxes(rel: LinearRelaxation, C: np.ndarray, Y: np.ndarray,
                    dense_entries: int = DENSE) -> np.ndarray:
    """certified_max for each row of C (objectives) and Y (their multipliers) at once: a few
    matrix products instead of two sparse passes per objective. Each float dot product has
    length at most 10^6, so RHS_REL covers its rounding in any order of summation.
    `dense_entries`: the largest matrix multiplied as a dense copy (LPSettings)."""
    b = rel.b[None, :]
    b_lo = (rel.b_lo if rel.b_lo is not None else np.full(len(rel.b), -np.inf))[None, :]
    ok = np.isfinite(Y) & (((Y > 0) & np.isfinite(b)) | ((Y < 0) & np.isfinite(b_lo)))
    Y = np.where(ok, Y, 0.0)  # an unusable multiplier is dropped (0: the row is not used)
    rhs = np.where(Y > 0, b, np.where(Y < 0, b_lo, 0.0))
    AY, absAY = _times(rel.A, Y, dense_entries)
    r = C - AY
    err = RHS_REL * (np.abs(C) + absAY) + RHS_ABS  # rounding error of r, componentwise
    return _dots_up(Y, rhs) + box_maxes_up(r - err, r + err, rel.lo, rel.hi)


def _times(A: Any, Y: np.ndarray, dense_entries: int) -> tuple[np.ndarray, np.ndarray]:
    """(Y A, |Y| |A|) for a CSR matrix A (Rows or scipy's) and rows of multipliers Y."""
    m, n = A.shape
    kept = A.__dict__.get("_dense") if isinstance(A, Rows) else None
    if kept is not None:
        return Y @ kept[0], np.abs(Y) @ kept[1]
    # a dense copy pays when it is not much larger than the entries times the objectives, or
    # when it is kept for the next objectives (a Rows: the LP's objectives are certified one
    # by one against the same matrix)
    reused = isinstance(A, Rows)
    small = m * n <= dense_entries
    if small and (reused or m * n * (1 + len(Y)) <= 4 * len(Y) * len(A.data)):
        at = np.repeat(np.arange(m), np.diff(A.indptr)) * n + np.asarray(A.indices)
        # a matrix with a repeated entry is left to the exact path (summing it would round)
        if len(at) == 0 or np.bincount(at, minlength=m * n).max() <= 1:
            dense = np.zeros(m * n)
            dense[at] = A.data
            dense = dense.reshape(m, n)
            if reused:  # (Rows are not changed once made; two threads may both store it)
                A.__dict__["_dense"] = (dense, np.abs(dense))
            return Y @ dense, np.abs(Y) @ np.abs(dense)
    return (np.array([transpose_times(A, y) for y in Y]).reshape(len(Y), n),
            np.array([transpose_times(A, np.abs(y), absolute=True)
                      for y in Y]).reshape(len(Y), n))


def _dots_up(X: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """dot_up of each row pair: the float sum plus a bound on its rounding error (infinite
    where either overflows: no finite bound to give)."""
    s = np.sum(X * Z, axis=1)
    err = np.sum(np.abs(X) * np.abs(Z), axis=1)
    ok = np.isfinite(s) & np.isfinite(err)
    return np.where(ok, s + RHS_REL * np.where(ok, err, 0.0) + RHS_ABS, np.inf)


def box_maxes_up(r_lo: np.ndarray, r_hi: np.ndarray, lo: np.ndarray,
                 hi: np.ndarray) -> np.ndarray:
    """box_max_up of each row of r_lo, r_hi over the same box: per entry the largest of the
    four corner products, summed, plus a bound on the sum's rounding error; +inf for a row
    with a coefficient that is no number (nothing bounds it)."""
    unknown = np.isnan(r_lo).any(axis=1) | np.isnan(r_hi).any(axis=1)
    with np.errstate(invalid="ignore"):
        cand = np.stack([r_lo * lo, r_lo * hi, r_hi * lo, r_hi * hi])
    cand = np.where(np.isnan(cand), 0.0, cand)  # 0 * inf: a zero coefficient contributes 0
    terms = cand.max(axis=0)
    s = terms.sum(axis=1)
    with np.errstate(invalid="ignore"):
        out = s + RHS_REL * np.abs(terms).sum(axis=1) + RHS_ABS
    return np.where(np.isfinite(s) & ~unknown, out, np.inf)  # +inf: unbounded; -inf: overflow


@dataclass
class Certificates:
    """The multipliers of the last LP solved for each objective (index, sign), by row key,
    for the objective's unknown in its own units (a column of unit `scale` takes the
    multipliers times 1 / scale). The rows of a relaxation are the same constraints
    on every box, so the same combination of them still bounds the unknown on a smaller box,
    and its bound is checked there as any multipliers are (certified_max): a matrix product
    instead of an LP. It stays near the new LP's optimum as long as the active rows do not
    change (docs/decisions/04)."""

    family: str = ""
    key_space: str = ""  # the kept LPs' relaxation's (LinearRelaxation.key_space)
    y: dict[tuple[int, float], tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    # the simplex's final basis for each objective (row keys, row statuses, column keys,
    # column statuses): the next LP of the same objective starts from it; and what that
    # LP's rows and columns meant (its rows' compared slots, its cells, its count of unknowns:
    # inner/starts.py), where the relaxation said
    basis: dict[tuple[int, float], tuple] = field(default_factory=dict)
    meaning: dict[tuple[int, float], tuple] = field(default_factory=dict)
    # each objective's LP optimum, in the unknowns (unknowns_at), where the LP found one:
    # where the optima stand, not a bound (a row generation checks them on rows left out)
    points: dict[tuple[int, float], np.ndarray] = field(default_factory=dict)
    # the same optima in the LP's own columns, by column key (sorted keys, values): a row
    # generation evaluates the relaxation's rows left out there (strategy/relaxed_check.py)
    columns: dict[tuple[int, float], tuple[np.ndarray, np.ndarray]] = field(
        default_factory=dict)
    # the box (every slot's lo, hi) the last fresh LPs relaxed, where their caller said
    box: tuple[np.ndarray, np.ndarray] | None = None

    def copy(self) -> Certificates:
        return Certificates(self.family, self.key_space, dict(self.y), dict(self.basis),
                            dict(self.meaning), dict(self.points), dict(self.columns),
                            self.box)

    def usable(self, rel: LinearRelaxation) -> bool:
        return bool(self.y) and rel.keys is not None and rel.family == self.family

    def record(self, rel: LinearRelaxation, i: int, sign: float, y: np.ndarray | None,
               basis: tuple | None = None, point: np.ndarray | None = None) -> None:
        if rel.keys is None:
            return
        if rel.family != self.family:
            self.family, self.y, self.basis, self.meaning = rel.family, {}, {}, {}
            self.key_space, self.points, self.columns = rel.key_space, {}, {}
        if point is not None:
            at = unknowns_at(rel, point)
            if at is not None:
                self.points[(i, sign)] = at
            if rel.col_keys is not None and len(point) == len(rel.col_keys):
                order = np.argsort(rel.col_keys, kind="stable")
                self.columns[(i, sign)] = (rel.col_keys[order], np.asarray(point)[order])
        if y is not None:  # (None: no LP solved, the box bound stood; its old y stays valid)
            self.y[(i, sign)] = (rel.keys, y * _unit(rel, i))
        if basis is not None and rel.col_keys is not None:
            self.basis[(i, sign)] = (rel.keys, basis[0], rel.col_keys, basis[1])
            if rel.targets is not None and rel.cells is not None:
                self.meaning[(i, sign)] = (rel.targets, rel.cells, rel.main)
            else:
                self.meaning.pop((i, sign), None)
        else:
            self.basis.pop((i, sign), None)
            self.meaning.pop((i, sign), None)

    def bound_keys(self, objectives: list[tuple[int, float]] | None = None) -> np.ndarray:
        """The keys of the rows with a nonzero multiplier in the kept LPs (of these
        objectives, or of all), sorted."""
        ys = [self.y[o] for o in (self.y if objectives is None else objectives)
              if o in self.y]
        if not ys:
            return np.zeros(0, dtype=np.int64)
        return np.unique(np.concatenate([keys[y != 0] for keys, y in ys]))

    def binding(self, rel: LinearRelaxation, objectives: list[tuple[int, float]]
                ) -> np.ndarray | None:
        """rel's rows (positions) that had a nonzero multiplier in the kept LPs of these
        objectives (of rel's family, or of another whose keys mean the same constraints), or
        None where there are none."""
        same_keys = rel.family == self.family or (rel.key_space != ""
                                                  and rel.key_space == self.key_space)
        if not (self.y and same_keys) or rel.keys is None:
            return None
        rows = np.flatnonzero(np.isin(rel.keys, self.bound_keys(objectives)))
        return rows if len(rows) else None

    def remainder_cost(self, rel: LinearRelaxation, n: int) -> np.ndarray:
        """For each of the n unknowns, what the rows' remainders (rel.slack) add to the width
        of its bounds from the kept LPs over rel, in its own units: each multiplier's
        magnitude times its row's slack, over both ends (0 where none is known). Without
        the remainders, those LPs' certificates would give bounds narrower by that much."""
        cost = np.zeros(n)
        if not self.usable(rel) or rel.slack is None or rel.keys is None:
            return cost
        for (i, _), (keys, y) in self.y.items():
            if i < n:
                cost[i] += float(np.abs(mapped(keys, y, rel.keys, 0.0)) @ rel.slack)
        return cost

    def start(self, rel: LinearRelaxation, i: int, sign: float) -> tuple | None:
        """The statuses (rows, columns) of the last basis of this objective mapped onto rel's
        rows and columns (a new row's slack basic, a new column at its lower bound), or None."""
        if (i, sign) not in self.basis or rel.family != self.family or rel.keys is None \
                or rel.col_keys is None:
            return None
        row_keys, rows, col_keys, cols = self.basis[(i, sign)]
        return (mapped(row_keys, rows, rel.keys, BASIC),
                mapped(col_keys, cols, rel.col_keys, LOWER))


def unknowns_at(rel: LinearRelaxation, x: np.ndarray) -> np.ndarray | None:
    """The unknowns at an LP point x of rel (its main columns, mapped back by p = center +
    scale t where they are scaled), or None where the mapping is not known. Floating point:
    a point to look at, never a bound."""
    t = np.asarray(x[: rel.main], dtype=float)
    if rel.scale is None:
        return t
    if rel.center is None:
        return None
    return rel.center + rel.scale * np.clip(t, -1.0, 1.0)


def mapped(old_keys: np.ndarray, values: np.ndarray, keys: np.ndarray,
           missing: float) -> np.ndarray:
    """The value of each key of `keys` in old_keys, `missing` for a key not there (a key
    twice in old_keys: the first one's). A relaxation's keys need not increase (a
    second-order one's follow its expansion's rows): they are sorted here where they do not."""
    if len(old_keys) == 0:
        return np.full(len(keys), missing, dtype=values.dtype)
    if np.any(old_keys[1:] < old_keys[:-1]):
        order = np.argsort(old_keys, kind="stable")
        old_keys, values = old_keys[order], values[order]
    at = np.minimum(np.searchsorted(old_keys, keys), len(old_keys) - 1)
    return np.where(old_keys[at] == keys, values[at], missing)


def _unit(rel: LinearRelaxation, j: int) -> float:
    return 1.0 if rel.scale is None else float(rel.scale[j])


def reused_bounds(rel: LinearRelaxation, objectives: np.ndarray, certs: Certificates,
                  dense_entries: int = DENSE) -> tuple[np.ndarray, np.ndarray]:
    """Rigorous [min, max] of each unit objective (a row of the identity) over `rel` from the
    multipliers kept in `certs` (the box's own bound where there are none)."""
    lower, upper, signed = box_bounds(rel, objectives)
    if not certs.usable(rel):
        return lower, upper
    keys = rel.keys if rel.keys is not None else np.zeros(0, np.int64)
    kept = [(i, sign, c) for i, sign, c in signed if (i, sign) in certs.y]
    if not kept:
        return lower, upper
    Y = np.array([mapped(*certs.y[(i, sign)], keys, 0.0) * (1.0 / _unit(rel, i))
                  for i, sign, _ in kept]).reshape(len(kept), len(keys))
    bounds = certified_maxes(rel, np.array([c for _, _, c in kept]), Y, dense_entries)
    for (i, sign, _), bound in zip(kept, bounds, strict=True):
        tighten(lower, upper, i, sign, float(bound))
    return lower, upper


def box_bounds(rel: LinearRelaxation, objectives: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, list[tuple[int, float, np.ndarray]]]:
    """The box's own [min, max] of each objective, and the signed objectives (i, sign, c)
    over all the relaxation's columns (nuisance columns cost nothing): maximize sign * c.p."""
    k = objectives.shape[0]
    lower, upper = np.full(k, -np.inf), np.full(k, np.inf)
    pad = np.zeros(rel.A.shape[1] - objectives.shape[1])
    signed = []
    for i, c in enumerate(objectives):
        for sign in (1.0, -1.0):
            c_full = sign * np.concatenate([c, pad])
            tighten(lower, upper, i, sign, box_max_up(c_full, c_full, rel.lo, rel.hi))
            signed.append((i, sign, c_full))
    return lower, upper, signed


def tighten(lower: np.ndarray, upper: np.ndarray, i: int, sign: float, bound: float) -> None:
    """Take a certified max of sign * c_i.p into c_i's bounds."""
    if sign > 0:
        upper[i] = min(upper[i], bound)
    else:
        lower[i] = max(lower[i], -bound)
