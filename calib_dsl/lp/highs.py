"""HiGHS: loading a relaxation into a model, its options and bases, rows added as they
are violated, and its banner kept off standard output.
"""

from __future__ import annotations

import ctypes
import functools
import os
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from calib_dsl.relax.relaxation import LinearRelaxation, Rows
from calib_dsl.settings import Settings

LOWER, BASIC = 0, 1  # HiGHS's basis statuses kLower, kBasic
MANY_PIVOTS = 2**31 - 1  # HiGHS's own default: no limit
DUAL_SIMPLEX = 1  # HiGHS's simplex_strategy kSimplexStrategyDual
# (module attribute, the settings' declared value: tests make blocks small)
CHECK_ROWS = Settings.blocks.check_rows


def optimal(h: Any) -> bool:
    import highspy

    return bool(h.getModelStatus() == highspy.HighsModelStatus.kOptimal)


def infeasible(h: Any) -> bool:
    import highspy

    return bool(h.getModelStatus() == highspy.HighsModelStatus.kInfeasible)


def current_basis(h: Any) -> tuple[np.ndarray, np.ndarray] | None:
    b = h.getBasis()
    if not b.valid:
        return None
    return (np.array([v.value for v in b.row_status], np.int8),
            np.array([v.value for v in b.col_status], np.int8))


@functools.cache
def _statuses() -> list:
    """HiGHS's basis statuses by value (making each anew from an int cost a millisecond per
    basis set)."""
    import highspy

    return [highspy.HighsBasisStatus(k) for k in range(5)]


def set_basis(h: Any, rows: np.ndarray, cols: np.ndarray) -> None:
    """Start the next solve from these statuses. HiGHS takes an "alien" basis (one with too
    many or too few basic variables, as a mapped one may have) and completes it."""
    import highspy

    status = _statuses()
    b = highspy.HighsBasis()
    b.row_status = [status[v] for v in rows.tolist()]
    b.col_status = [status[v] for v in cols.tolist()]
    b.alien = True
    b.valid = True
    h.setBasis(b)


def starting_rows(rel: LinearRelaxation) -> np.ndarray:
    """Evenly spread rows, a few per unknown (main column; all columns where none is
    marked): enough to bound the LP well at the start. An optimum of an unknown binds on
    about as many rows as the columns it leaves off their bounds, and the nuisance columns
    (products, a reading's error) mostly sit at theirs; the row generation adds the rest."""
    m, n = rel.A.shape
    return np.unique(np.linspace(0, m - 1, min(m, 8 * (rel.main or n))).astype(np.int64))


class RowCheck:
    """Which rows outside the LP a point violates (the `most` most violated). A x and |A| |x|
    are sparse products, `block` rows at a time (|A| of a block only is made: a copy of a
    tall LP's whole matrix per check would add to the peak memory; each row's sum is the
    same for any block). An LP of one block keeps its two matrices: the row generation
    checks many points, and they hold no more than one check's temporaries."""

    def __init__(self, rel: LinearRelaxation, most: int, block: int = CHECK_ROWS) -> None:
        self.rel, self.most, self.block = rel, most, max(1, block)
        self.rows = _rows_of(rel.A)
        self.b_lo = rel.b_lo if rel.b_lo is not None else np.full(rel.A.shape[0], -np.inf)
        m = self.rows.shape[0]
        self.whole = self._block(0, m) if m <= self.block else None

    def _block(self, a: int, b: int) -> tuple[Any, Any]:
        """Rows a..b-1 as (A, |A|), sparse."""
        from scipy.sparse import csr_matrix  # (a tall LP's row generation only: a slow import)

        r = self.rows
        s, e = r.indptr[a], r.indptr[b]
        ptr, cols, vals = r.indptr[a:b + 1] - s, r.indices[s:e], r.data[s:e]
        shape = (b - a, r.shape[1])
        return csr_matrix((vals, cols, ptr), shape=shape), \
            csr_matrix((np.abs(vals), cols, ptr), shape=shape)

    def products(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(A x, |A| |x|)."""
        m = self.rows.shape[0]
        ax, scale, size = np.empty(m), np.empty(m), np.abs(x)
        for a in range(0, m, self.block):
            b = min(m, a + self.block)
            A, absA = self.whole if self.whole is not None else self._block(a, b)
            ax[a:b], scale[a:b] = A @ x, absA @ size
        return ax, scale

    def violated(self, x: np.ndarray, rows: np.ndarray) -> np.ndarray:
        ax, scale = self.products(x)
        tol = 1e-9 * scale + 1e-12
        with np.errstate(invalid="ignore"):
            excess = np.maximum(ax - self.rel.b, self.b_lo - ax) - tol
        excess[rows] = 0.0
        bad = np.flatnonzero(excess > 0)
        return bad[np.argsort(-excess[bad])[:self.most]]


def add_rows(h: Any, rel: LinearRelaxation, rows: np.ndarray) -> None:
    import highspy

    inf = highspy.kHighsInf
    part = _rows_of(rel.A).take(rows)
    lower = (np.full(len(rows), -inf) if rel.b_lo is None
             else np.where(np.isfinite(rel.b_lo[rows]), rel.b_lo[rows], -inf))
    upper = np.where(np.isfinite(rel.b[rows]), rel.b[rows], inf)
    h.addRows(len(rows), lower.astype(float), upper.astype(float), len(part.data),
              part.indptr[:-1].astype(np.int32), part.indices.astype(np.int32),
              part.data.astype(float))


def _rows_of(A: Any) -> Rows:
    """A itself, or a scipy CSR matrix's arrays as Rows."""
    if isinstance(A, Rows):
        return A
    return Rows(np.asarray(A.data), np.asarray(A.indices), np.asarray(A.indptr), A.shape)


def load(rel: LinearRelaxation, rows: np.ndarray | None = None,
         iterations: int = MANY_PIVOTS, scaling: int | None = None) -> Any:
    """A HiGHS model of the relaxation, with only `rows` of its rows if given (`iterations`:
    simplex pivots per run; `scaling`: HiGHS's simplex_scale_strategy, None for its
    default)."""
    import highspy

    h = _new_highs()
    h.setOptionValue("output_flag", False)
    # one thread a model: our LPs already run one per thread of our own, and HiGHS's workers
    # would only compete with them for the cores
    h.setOptionValue("threads", 1)
    # no callbacks: highspy sets a Python one, and HiGHS copies it at every run's start, which
    # takes the interpreter's lock (a run on one thread waits for Python work on another)
    disable = getattr(h, "disableCallbacks", None)
    if disable is not None:  # (an older highspy has neither the method nor the callback)
        disable()
    h.setOptionValue("simplex_iteration_limit", iterations)  # counted per run
    # HiGHS equilibrates rows and columns by default. Our relaxations are built scaled (the
    # second-order ones in t-units, each column in [-1, 1]), and without HiGHS's own scaling
    # the simplex takes far fewer pivots from the same bases to the same bounds
    # (docs/decisions/06).
    if scaling is not None:
        h.setOptionValue("simplex_scale_strategy", scaling)
    if rows is not None and len(rows) < rel.A.shape[0]:
        A = _rows_of(rel.A).take(rows)
        rel = LinearRelaxation(A, rel.b[rows], rel.lo, rel.hi, rel.main, rel.cells,
                               None if rel.b_lo is None else rel.b_lo[rows])
    m, n = rel.A.shape
    lp = highspy.HighsLp()
    lp.num_col_, lp.num_row_ = n, m
    lp.col_cost_ = np.zeros(n)
    lp.col_lower_ = np.where(np.isfinite(rel.lo), rel.lo, -highspy.kHighsInf)
    lp.col_upper_ = np.where(np.isfinite(rel.hi), rel.hi, highspy.kHighsInf)
    inf = highspy.kHighsInf
    lp.row_lower_ = (np.full(m, -inf) if rel.b_lo is None
                     else np.where(np.isfinite(rel.b_lo), rel.b_lo, -inf).astype(float))
    lp.row_upper_ = np.where(np.isfinite(rel.b), rel.b, inf).astype(float)
    lp.a_matrix_.format_ = highspy.MatrixFormat.kRowwise
    lp.a_matrix_.start_ = np.asarray(rel.A.indptr, dtype=np.int32)
    lp.a_matrix_.index_ = np.asarray(rel.A.indices, dtype=np.int32)
    lp.a_matrix_.value_ = np.asarray(rel.A.data, dtype=float)
    h.passModel(lp)
    return h


def minimize(rel: LinearRelaxation, cost: np.ndarray) -> np.ndarray | None:
    """x minimizing cost.x over all of the relaxation's rows and column bounds (None when HiGHS
    does not find the optimum): a plain LP, with HiGHS's own scaling (its rows are not built
    scaled) and no pivot limit. scipy's linprog would do the same, but importing
    scipy.optimize is slow, a large share of a short command (docs/decisions/14)."""
    h = load(rel, iterations=MANY_PIVOTS, scaling=None)
    n = rel.A.shape[1]
    h.changeColsCost(n, np.arange(n, dtype=np.int32), np.asarray(cost, dtype=float))
    h.run()
    return np.array(h.getSolution().col_value) if optimal(h) else None


_GREETED = threading.Lock()  # held while the process's first HiGHS object is made
_greeted = False  # whether it was made


def _new_highs() -> Any:
    """A new HiGHS object. From highspy 1.16 on, the first one made in a process prints HiGHS's
    banner on the C-level stdout, before any option can turn output off; it would corrupt
    `calibc solve --json -` (and the pickled results of a child process, workers.py). So the
    first one is made with file descriptor 1 pointed at /dev/null (and C's buffers flushed
    before it is put back); later ones print nothing."""
    import highspy

    global _greeted
    with _GREETED:
        if not _greeted:
            _greeted = True
            with _stdout_silenced():
                return highspy.Highs()
    return highspy.Highs()


@contextmanager
def _stdout_silenced() -> Iterator[None]:
    if sys.stdout is not None:
        sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no stdout at all: nothing to protect
        yield
        return
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        yield
    finally:
        try:
            ctypes.CDLL(None).fflush(None)  # what C wrote is still buffered: to /dev/null too
        except (OSError, AttributeError, TypeError):  # no C library to flush here
            pass
        os.dup2(saved, 1)
        os.close(null)
        os.close(saved)


def _finite_or_none(x: np.ndarray) -> list[float | None]:
    return [float(v) if np.isfinite(v) else None for v in x]
