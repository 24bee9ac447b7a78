"""A HiGHS model of the rows of a relaxation that a path of nearby LPs needs (row generation).

HiGHS's cost per run grows with the loaded matrix, and along a path of nearby objectives
only a few dozen of a relaxation's rows are active at each optimum, much the same ones from
one LP to the next. So the model holds the rows active at the last `keep` optima (a row that
came back violated after it was deleted: `keep` more each time it did): an LP over
those is a relaxation of the whole one (its multipliers, zero on the rows left out, certify
a bound over all rows), and its optimum, checked against every row, is the whole LP's when
it violates none; the violated rows are added and the LP run again from its basis. A row
inactive at the last optima it may stay for is deleted (only rows whose slack is basic: the basis
stays a basis). The check multiplies a dense copy of the matrix where it is small (the
prediction LPs' are: a sparse product's overhead would cost about as much as a run).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from calib_dsl.lp.highs import RowCheck, load
from calib_dsl.relax.relaxation import LinearRelaxation
from calib_dsl.settings import LPSettings


class WorkingRows:
    """The model (`h`, all rows at first) and which of the relaxation's rows it holds."""

    def __init__(self, rel: LinearRelaxation, lp: LPSettings, keep: int, most: int) -> None:
        self.rel, self.keep = rel, keep
        self.h: Any = load(rel, None, lp.iterations, lp.scaling)
        m = rel.A.shape[0]
        self.rows = np.arange(m, dtype=np.int64)  # the model's rows, in its order
        self.seen = np.zeros(m, dtype=np.int64)  # per row: the last optimum it was active at
        self.optima = 0
        # per row: the optima it may stay inactive at before it is deleted, `keep` more
        # each time it came back violated (a row the path keeps needing stays)
        self.kept_for = np.full(m, keep, dtype=np.int64)
        self.most = most
        self.dense = _dense(rel.A) if m * rel.A.shape[1] <= lp.dense_entries else None
        self.check = RowCheck(rel, most) if self.dense is None else None
        self.b_lo = rel.b_lo if rel.b_lo is not None else np.full(m, -np.inf)
        self.rows_of = _RowsOf(rel)

    def missing(self, x: np.ndarray) -> np.ndarray:
        """The rows outside the model that x violates (the `most` most violated, the most
        first), to a tolerance relative to the rows' terms at x."""
        if self.check is not None:
            return self.check.violated(x, self.rows)
        assert self.dense is not None
        A, absA = self.dense
        ax = A @ x
        tol = 1e-9 * (absA @ np.abs(x)) + 1e-12
        with np.errstate(invalid="ignore"):
            excess = np.maximum(ax - self.rel.b, self.b_lo - ax) - tol
        excess[self.rows] = 0.0
        bad = np.flatnonzero(excess > 0)
        return bad[np.argsort(-excess[bad])[:self.most]]

    def add(self, more: np.ndarray) -> None:
        self.rows_of.add(self.h, more)
        self.rows = np.concatenate([self.rows, more])
        self.seen[more] = self.optima
        self.kept_for[more] += self.keep

    def multipliers(self) -> np.ndarray:
        """The last run's multipliers over all the relaxation's rows (0 on those left out;
        y > 0 on an upper side, as certify.certified_maxes takes them)."""
        y = np.zeros(self.rel.A.shape[0])
        y[self.rows] = -np.asarray(self.h.getSolution().row_dual)
        return y

    def settle(self) -> None:
        """After an LP: its active rows marked, rows inactive at the last optima they may
        stay for (`keep`, more for a row that came back) deleted. A row strictly inside its
        sides is inactive and its slack basic (a nonbasic slack sits at a side); one at a
        side is taken as active (a basic slack at its side, degenerate, is kept too: the
        basis stays a basis)."""
        self.optima += 1
        sol = self.h.getSolution()
        if not sol.value_valid:
            return
        value = np.asarray(sol.row_value)
        margin = 1e-9 * (1.0 + np.abs(value))
        inside = (value < self.rel.b[self.rows] - margin) & \
            (value > self.b_lo[self.rows] + margin)
        self.seen[self.rows[~inside]] = self.optima
        since = self.optima - self.kept_for[self.rows]
        stale = np.flatnonzero(inside & (self.seen[self.rows] < since))
        if len(stale):
            self.h.deleteRows(len(stale), stale.astype(np.int32))
            self.rows = np.delete(self.rows, stale)


def _dense(A: Any) -> tuple[np.ndarray, np.ndarray]:
    """A CSR matrix (Rows or scipy's) as a dense array, and its absolute values."""
    m, n = A.shape
    out = np.zeros((m, n))
    at = np.repeat(np.arange(m), np.diff(np.asarray(A.indptr)))
    np.add.at(out, (at, np.asarray(A.indices)), np.asarray(A.data))
    return out, np.abs(out)


class _RowsOf:
    """The relaxation's rows as HiGHS adds them (lp/highs.py add_rows' arrays), each row's
    entries and sides converted once: a path's LPs add a few rows hundreds of times."""

    def __init__(self, rel: LinearRelaxation) -> None:
        import highspy

        inf = highspy.kHighsInf
        A = rel.A
        ptr = np.asarray(A.indptr)
        index = np.asarray(A.indices).astype(np.int32)
        value = np.asarray(A.data).astype(float)
        self.index = [index[ptr[r]:ptr[r + 1]] for r in range(A.shape[0])]
        self.value = [value[ptr[r]:ptr[r + 1]] for r in range(A.shape[0])]
        self.lower = (np.full(A.shape[0], -inf) if rel.b_lo is None
                      else np.where(np.isfinite(rel.b_lo), rel.b_lo, -inf).astype(float))
        self.upper = np.where(np.isfinite(rel.b), rel.b, inf).astype(float)

    def add(self, h: Any, rows: np.ndarray) -> None:
        if not len(rows):
            return
        index = [self.index[r] for r in rows]
        starts = np.zeros(len(rows), dtype=np.int32)
        np.cumsum([len(i) for i in index[:-1]], out=starts[1:])
        value = np.concatenate([self.value[r] for r in rows])
        h.addRows(len(rows), self.lower[rows], self.upper[rows], len(value), starts,
                  np.concatenate(index), value)
