"""Rigorous bounds from a linear program (Neumaier-Shcherbina).

The LP solver (HiGHS, through its official Python binding highspy) works in floating point,
so its optimum is never trusted. Only its dual multipliers are used, as a *certificate*: for
any y >= 0 and any p in the box with A p <= b,

    c.p = y.(A p) + (c - A'y).p  <=  y.b + max over the box of (c - A'y).p,

whatever y is. Every sum is bounded with an explicit rounding-error term, so the bound holds
in exact arithmetic. A poor y gives a poor bound, never a wrong one.
"""

from __future__ import annotations

import ctypes
import functools
import os
import sys
import threading
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from scipy import sparse

# Relative rounding-error budget of a float dot product of length <= 10^6 in round-to-nearest
# (gamma_n = n u / (1 - n u) with u = 2^-53, n <= 10^6, is below 1.2e-10): 1e-9 covers it.
_REL = 1e-9
_ABS = 1e-300
# Per objective: a degenerate LP near the fixed point can crawl. The iteration limit stops it
# the same way on every machine (results do not depend on load); the time limit is a backstop.
LP_ITERATIONS = 1000
LP_SECONDS = 1.0
WORKERS = min(2, os.cpu_count() or 1)  # HiGHS models solved in parallel threads
# Above this many rows the LP starts from a subset and adds the rows its optimum violates
# (row generation); a tall LP (1000 configurations: 9000 rows, 33 columns) is far faster so.
ROWS_AT_ONCE = 2000
ROWS_ADDED = 500  # at most this many violated rows per pass
SCALING = 0  # HiGHS's simplex_scale_strategy: 0, none (see _load)


@dataclass
class Rows:
    """A sparse matrix stored by rows (CSR: the same three arrays as scipy's csr_matrix). The
    tight strategy builds its relaxations as these, so that it never imports scipy.sparse
    (a fifth of a second of a Test A solve); a scipy CSR matrix is accepted wherever a Rows is.
    """

    data: np.ndarray
    indices: np.ndarray
    indptr: np.ndarray
    shape: tuple[int, int]

    @staticmethod
    def join(dense: np.ndarray, rows: np.ndarray, cols: np.ndarray, vals: np.ndarray,
             width: int) -> Rows:
        """[dense | S] where S (m x width) has the entries vals at (rows, cols)."""
        m, k = dense.shape
        r, c = np.nonzero(dense)
        r = np.concatenate([r, rows])
        c = np.concatenate([c, k + cols])
        v = np.concatenate([dense[dense != 0], vals])
        order = np.lexsort((c, r))
        indptr = np.zeros(m + 1, dtype=np.int64)
        np.cumsum(np.bincount(r, minlength=m), out=indptr[1:])
        return Rows(v[order].astype(float), c[order].astype(np.int64), indptr, (m, k + width))

    def take(self, rows: np.ndarray) -> Rows:
        start, stop = self.indptr[rows], self.indptr[rows + 1]
        lengths = stop - start
        at = np.repeat(start - np.cumsum(lengths) + lengths, lengths) + np.arange(lengths.sum())
        indptr = np.zeros(len(rows) + 1, dtype=np.int64)
        np.cumsum(lengths, out=indptr[1:])
        return Rows(self.data[at], self.indices[at], indptr, (len(rows), self.shape[1]))

    def row_nonzeros(self) -> np.ndarray:
        return np.diff(self.indptr)


def transpose_times(A: Any, y: np.ndarray, absolute: bool = False) -> np.ndarray:
    """A^T y for a CSR matrix (Rows or scipy's), or |A|^T y."""
    data = np.abs(A.data) if absolute else A.data
    rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
    return np.bincount(A.indices, weights=data * y[rows], minlength=A.shape[1])


@dataclass
class LinearRelaxation:
    """Valid inequalities b_lo <= A p <= b over the box lo <= p <= hi (in exact arithmetic).

    b_lo is optional (no lower sides); an infinite entry of b or b_lo is no constraint. A row
    bounded on both sides is one LP row, not two: the simplex then works on half the rows.
    """

    A: Rows | sparse.csr_matrix  # (m, n)
    b: np.ndarray  # (m,)
    lo: np.ndarray  # (n,)
    hi: np.ndarray  # (n,)
    main: int = 0  # the first `main` columns are the unknowns; the others nuisance variables
    # for each nuisance column: (configuration id, table column id) of the measured cell whose
    # error it is (ids as in decompose.Slots.cell_row / cell_col)
    cells: np.ndarray | None = None
    b_lo: np.ndarray | None = None
    # How much of the rows' width is the linearization's remainder rather than the data's
    # errors (90th percentile over rows of remainder / (remainder + data)); near 0, the model
    # is linear over the box to within a small part of the errors: relaxing again on a
    # smaller box would give (nearly) the same LP. 1 when unknown.
    remainder_share: float = 1.0
    # How curved the model is over the box: the median over rows of the remainder over the
    # first-order range (linearize); LP rounds stall above about 1/7. 0 when unknown.
    curvature: float = 0.0
    # Which constraint each row relaxes (increasing ids, the same in every relaxation of the
    # same kind, `family`), and how much of its unknown one unit of each main column is (p =
    # center + scale t): with them, multipliers found on one box certify bounds on another
    # (Certificates). None: no reuse.
    keys: np.ndarray | None = None
    scale: np.ndarray | None = None
    family: str = ""
    col_keys: np.ndarray | None = None  # which quantity each column is (increasing), likewise

    def one_sided(self) -> tuple[sparse.csr_matrix, np.ndarray]:
        """The same inequalities as A' p <= b' only (finite right-hand sides)."""
        from scipy import sparse

        A0 = sparse.csr_matrix((self.A.data, self.A.indices, self.A.indptr), shape=self.A.shape)
        if self.b_lo is None:
            keep = np.flatnonzero(np.isfinite(self.b))
            return A0[keep], self.b[keep]
        up, dn = np.flatnonzero(np.isfinite(self.b)), np.flatnonzero(np.isfinite(self.b_lo))
        A = sparse.vstack([A0[up], -A0[dn]]).tocsr()
        return A, np.concatenate([self.b[up], -self.b_lo[dn]])


def dot_up(x: np.ndarray, y: np.ndarray) -> float:
    """An upper bound on the exact dot product x.y of float vectors."""
    return float(_dots_up(x[None, :], y[None, :])[0])


def box_max_up(r_lo: np.ndarray, r_hi: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """An upper bound on max r.p over r in [r_lo, r_hi], p in [lo, hi]."""
    return float(_box_maxes_up(r_lo[None, :], r_hi[None, :], lo, hi)[0])


def certified_max(rel: LinearRelaxation, c: np.ndarray, y: np.ndarray) -> float:
    """A rigorous upper bound on max c.p over the relaxation, from a dual guess y.

    y_i > 0 multiplies the row's upper side A_i p <= b_i, y_i < 0 its lower side
    A_i p >= b_lo_i (both give y_i A_i p <= y_i rhs_i); any such y is a certificate.
    """
    return float(certified_maxes(rel, c[None, :], y[None, :])[0])


# Above this many matrix entries (or for a sparse matrix and few objectives), certified_maxes
# works row by row of Y on the sparse matrix instead of on a dense copy of A.
DENSE_ENTRIES = 4_000_000


def certified_maxes(rel: LinearRelaxation, C: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """certified_max for each row of C (objectives) and Y (their multipliers) at once: a few
    matrix products instead of two sparse passes per objective. Each float dot product has
    length at most 10^6, so _REL covers its rounding in any order of summation."""
    b = rel.b[None, :]
    b_lo = (rel.b_lo if rel.b_lo is not None else np.full(len(rel.b), -np.inf))[None, :]
    ok = np.isfinite(Y) & (((Y > 0) & np.isfinite(b)) | ((Y < 0) & np.isfinite(b_lo)))
    Y = np.where(ok, Y, 0.0)  # an unusable multiplier is dropped (0: the row is not used)
    rhs = np.where(Y > 0, b, np.where(Y < 0, b_lo, 0.0))
    AY, absAY = _times(rel.A, Y)
    r = C - AY
    err = _REL * (np.abs(C) + absAY) + _ABS  # rounding error of r, componentwise
    return _dots_up(Y, rhs) + _box_maxes_up(r - err, r + err, rel.lo, rel.hi)


def _times(A: Any, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Y A, |Y| |A|) for a CSR matrix A (Rows or scipy's) and rows of multipliers Y."""
    m, n = A.shape
    kept = A.__dict__.get("_dense") if isinstance(A, Rows) else None
    if kept is not None:
        return Y @ kept[0], np.abs(Y) @ kept[1]
    # a dense copy pays when it is not much larger than the entries times the objectives, or
    # when it is kept for the next objectives (a Rows: the LP's objectives are certified one
    # by one against the same matrix)
    reused = isinstance(A, Rows)
    if m * n <= DENSE_ENTRIES and (reused or m * n * (1 + len(Y)) <= 4 * len(Y) * len(A.data)):
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
    return np.where(ok, s + _REL * np.where(ok, err, 0.0) + _ABS, np.inf)


def _box_maxes_up(r_lo: np.ndarray, r_hi: np.ndarray, lo: np.ndarray,
                  hi: np.ndarray) -> np.ndarray:
    """box_max_up of each row of r_lo, r_hi over the same box: per entry the largest of the
    four corner products, summed, plus a bound on the sum's rounding error."""
    with np.errstate(invalid="ignore"):
        cand = np.stack([r_lo * lo, r_lo * hi, r_hi * lo, r_hi * hi])
    cand = np.where(np.isnan(cand), 0.0, cand)  # 0 * inf: a zero coefficient contributes 0
    terms = cand.max(axis=0)
    s = terms.sum(axis=1)
    with np.errstate(invalid="ignore"):
        out = s + _REL * np.abs(terms).sum(axis=1) + _ABS
    return np.where(np.isfinite(s), out, np.inf)  # +inf: unbounded; -inf only by overflow


@dataclass
class Certificates:
    """The multipliers of the last LP solved for each objective (index, sign), by row key,
    for the objective's unknown in its own units (a column of unit `scale` takes the
    multipliers times 1 / scale). The rows of a relaxation are the same constraints
    on every box, so the same combination of them still bounds the unknown on a smaller box,
    and its bound is checked there as any multipliers are (certified_max): a matrix product
    instead of an LP. It stays near the new LP's optimum as long as the active rows do not
    change (on the RX90 from section 4, within 1% of the fresh bound a round later)."""

    family: str = ""
    y: dict[tuple[int, float], tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    # the simplex's final basis for each objective (row keys, row statuses, column keys,
    # column statuses): the next LP of the same objective starts from it
    basis: dict[tuple[int, float], tuple] = field(default_factory=dict)

    def copy(self) -> Certificates:
        return Certificates(self.family, dict(self.y), dict(self.basis))

    def usable(self, rel: LinearRelaxation) -> bool:
        return bool(self.y) and rel.keys is not None and rel.family == self.family

    def record(self, rel: LinearRelaxation, i: int, sign: float, y: np.ndarray | None,
               basis: tuple | None = None) -> None:
        if rel.keys is None:
            return
        if rel.family != self.family:
            self.family, self.y, self.basis = rel.family, {}, {}
        if y is not None:  # (None: no LP solved, the box bound stood; its old y stays valid)
            self.y[(i, sign)] = (rel.keys, y * _unit(rel, i))
        if basis is not None and rel.col_keys is not None:
            self.basis[(i, sign)] = (rel.keys, basis[0], rel.col_keys, basis[1])
        else:
            self.basis.pop((i, sign), None)

    def start(self, rel: LinearRelaxation, i: int, sign: float) -> tuple | None:
        """The statuses (rows, columns) of the last basis of this objective mapped onto rel's
        rows and columns (a new row's slack basic, a new column at its lower bound), or None."""
        if (i, sign) not in self.basis or rel.family != self.family or rel.keys is None \
                or rel.col_keys is None:
            return None
        row_keys, rows, col_keys, cols = self.basis[(i, sign)]
        return (_mapped(row_keys, rows, rel.keys, _BASIC),
                _mapped(col_keys, cols, rel.col_keys, _LOWER))


_LOWER, _BASIC = 0, 1  # HiGHS's basis statuses kLower, kBasic


def _mapped(old_keys: np.ndarray, values: np.ndarray, keys: np.ndarray,
            missing: float) -> np.ndarray:
    """The values of the keys in `keys` (sorted ids), `missing` for a key not in old_keys."""
    if len(old_keys) == 0:
        return np.full(len(keys), missing, dtype=values.dtype)
    at = np.minimum(np.searchsorted(old_keys, keys), len(old_keys) - 1)
    return np.where(old_keys[at] == keys, values[at], missing)


def _unit(rel: LinearRelaxation, j: int) -> float:
    return 1.0 if rel.scale is None else float(rel.scale[j])


def reused_bounds(rel: LinearRelaxation, objectives: np.ndarray,
                  certs: Certificates) -> tuple[np.ndarray, np.ndarray]:
    """Rigorous [min, max] of each unit objective (a row of the identity) over `rel` from the
    multipliers kept in `certs` (the box's own bound where there are none)."""
    lower, upper, signed = _box_bounds(rel, objectives)
    if not certs.usable(rel):
        return lower, upper
    keys = rel.keys if rel.keys is not None else np.zeros(0, np.int64)
    kept = [(i, sign, c) for i, sign, c in signed if (i, sign) in certs.y]
    if not kept:
        return lower, upper
    Y = np.array([_mapped(*certs.y[(i, sign)], keys, 0.0) * (1.0 / _unit(rel, i))
                  for i, sign, _ in kept]).reshape(len(kept), len(keys))
    bounds = certified_maxes(rel, np.array([c for _, _, c in kept]), Y)
    for (i, sign, _), bound in zip(kept, bounds, strict=True):
        _tighten(lower, upper, i, sign, float(bound))
    return lower, upper


def _box_bounds(rel: LinearRelaxation, objectives: np.ndarray
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
            _tighten(lower, upper, i, sign, box_max_up(c_full, c_full, rel.lo, rel.hi))
            signed.append((i, sign, c_full))
    return lower, upper, signed


def _tighten(lower: np.ndarray, upper: np.ndarray, i: int, sign: float, bound: float) -> None:
    """Take a certified max of sign * c_i.p into c_i's bounds."""
    if sign > 0:
        upper[i] = min(upper[i], bound)
    else:
        lower[i] = max(lower[i], -bound)


def lp_bounds(rel: LinearRelaxation, objectives: np.ndarray,
              skip: np.ndarray | None = None, iterations: int = LP_ITERATIONS,
              seconds: float = LP_SECONDS, solver: str = "simplex",
              certificates: Certificates | None = None,
              probes: bool = False, own_bases: bool = True,
              threads: int = WORKERS) -> tuple[np.ndarray, np.ndarray]:
    """Rigorous [min, max] of each objective row c.p over the relaxation.

    Each worker thread loads one HiGHS model and re-solves it for its share of the objectives
    from the previous basis (a few pivots each); HiGHS releases the GIL, so the workers run on
    separate cores. Where the LP fails (or finds the relaxation infeasible, which we do not
    certify), the bound falls back to the box's own bound on c.p: never wrong, just not
    tighter. Objectives flagged in `skip` get the box bound without an LP. `iterations` and
    `seconds` limit each solve (a run stopped by them still certifies a bound). `solver` is
    HiGHS's: "simplex" re-solves from the last basis; "ipm" (interior point, no crossover)
    starts afresh each time but costs the same few dozen iterations on any objective, which
    pays on a large LP whose objectives are far apart (their multipliers certify all the same).
    The multipliers of each LP solved are kept in `certificates` if given (for
    reused_bounds on a later box). With `probes`, a few probe LPs first find points on many
    box bounds at once (_probe_points): worth it far from the solution only. With `own_bases`
    (and `certificates`), the simplex starts each objective from that objective's last basis
    kept there; without, from the optimum of the objective its worker solved before.
    `threads`: how many workers (each with its own HiGHS model) share the objectives.
    """
    lower, upper, signed = _box_bounds(rel, objectives)
    tasks = [t for t in signed if not (skip is not None and skip[t[0]])]
    workers = max(1, min(threads, len(tasks)))
    points = _probe_points(rel, tasks, iterations, seconds) if probes and workers > 1 else []
    # both signs of an objective in the same share: the second starts from the first's optimum
    share_of = {i: k % workers for k, i in enumerate(dict.fromkeys(t[0] for t in tasks))}
    shares = [[t for t in tasks if share_of[t[0]] == w] for w in range(workers)]
    if workers == 1:
        results = [_solve_share(rel, shares[0], iterations, seconds, solver, certificates,
                                own_bases=own_bases)]
    else:
        with ThreadPoolExecutor(workers) as pool:
            results = list(pool.map(lambda share: _solve_share(rel, share, iterations, seconds,
                                                                    solver, certificates,
                                                                    points, own_bases),
                                    shares))
    for share in results:
        for i, sign, bound, y, basis in share:
            if certificates is not None:
                certificates.record(rel, i, sign, y, basis)
            if y is not None:  # (None: the box bound stands, and only a basis is kept)
                _tighten(lower, upper, i, sign, bound)
    return lower, upper


def _solve_share(rel: LinearRelaxation, share: list, iterations: int = LP_ITERATIONS,
                 seconds: float = LP_SECONDS,
                 solver: str = "simplex",
                 certificates: Certificates | None = None,
                 probes: list[tuple[np.ndarray, tuple | None]] | None = None,
                 own_bases: bool = True) -> list[tuple]:
    """Certified maxima of sign * c.p for one worker's objectives, on one warm HiGHS model.

    A tall relaxation is solved by row generation: the LP holds a subset of the rows, and the
    rows its optimum violates are added until none is (the optimum is then the full LP's).
    The certificate is exact either way: rows outside the LP get multiplier 0.
    """
    if not share:
        return []
    m, n = rel.A.shape
    rows = np.arange(m) if m <= ROWS_AT_ONCE else _starting_rows(rel)
    h = _load(rel, rows, iterations)
    # row generation re-solves after adding rows: the simplex goes on from its basis, an
    # interior point method would start over each time
    h.setOptionValue("solver", solver if len(rows) == m else "simplex")
    h.setOptionValue("run_crossover", "off")  # (ipm) a point inside is as good a certificate
    cols = np.arange(n, dtype=np.int32)
    check = _RowCheck(rel) if len(rows) < m else None
    out: list[tuple] = []
    # LP solutions found so far (feasible up to HiGHS's tolerance) and their bases, from the
    # probes on
    points: list[tuple[np.ndarray, tuple | None]] = list(probes or [])
    # the simplex on the whole LP can start from this objective's basis on an earlier box
    keep_basis = (own_bases and certificates is not None and len(rows) == m
                  and solver == "simplex")
    for i, sign, c in share:
        at = _reaching(c, points, rel)
        if at is not None:  # an LP point already lies on the box's bound: the box bound stays
            if keep_basis:  # next time, this objective starts from that point's basis
                out.append((i, sign, np.inf, None, points[at][1]))
            continue
        h.changeColsCost(n, cols, (-c).astype(float))  # maximize c.p as: minimize -c.p
        start = certificates.start(rel, i, sign) if keep_basis and certificates else None
        if start is not None:
            _set_basis(h, *start)
        # HiGHS's time limit counts all runs of the object: extend it per solve.
        h.setOptionValue("time_limit", h.getRunTime() + seconds)
        h.run()
        if solver == "ipm" and check is None and not _optimal(h):
            # without crossover the interior point method can stop short on a degenerate LP
            # (status unknown) with multipliers far from optimal: the simplex finishes it
            h.setOptionValue("solver", "simplex")
            h.run()
            h.setOptionValue("solver", solver)
        while check is not None:
            sol = h.getSolution()
            if sol.value_valid:
                more = check.violated(np.asarray(sol.col_value), rows)
            else:  # unbounded without the rows left out (an infinite box): take them all
                more, check = np.setdiff1d(np.arange(m), rows), None
            if len(more) == 0:
                break
            _add_rows(h, rel, more)
            rows = np.concatenate([rows, more])
            h.run()
        # Any multipliers certify a bound, so even a solve stopped by its iteration or time
        # limit gives a valid (if weaker) one: only a missing solution is skipped.
        sol = h.getSolution()
        basis = _basis(h) if keep_basis else None
        if sol.value_valid and h.getInfo().primal_solution_status == 2:  # feasible
            points.append((np.asarray(sol.col_value), basis))
        if sol.dual_valid:
            y = np.zeros(m)
            y[rows] = -np.asarray(sol.row_dual)
            out.append((i, sign, certified_max(rel, c, y), y, basis))
    return out


def _optimal(h: Any) -> bool:
    import highspy

    return bool(h.getModelStatus() == highspy.HighsModelStatus.kOptimal)


def _basis(h: Any) -> tuple[np.ndarray, np.ndarray] | None:
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


def _set_basis(h: Any, rows: np.ndarray, cols: np.ndarray) -> None:
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


PROBES = 4  # at most this many probe LPs before the objectives are shared out


def _probe_points(rel: LinearRelaxation, tasks: list, iterations: int,
                  seconds: float) -> list[tuple[np.ndarray, tuple | None]]:
    """LP points that attain many of the box's own bounds at once, for every worker's
    `_reaching`: the optima of the sum of the objectives, of its opposite, then of sums with
    random signs (seeded: the same points on every run), while each probe adds an objective
    that no LP needs to solve. One worker's own optima would serve only its share; far from
    the solution (where many unknowns do not move) these serve all, for two to four LPs.
    Only points (and their bases, where an objective they reach starts next time): no bound
    depends on them (see `_reaching`)."""
    if len(tasks) < 4 * PROBES or rel.A.shape[0] > ROWS_AT_ONCE:
        return []
    h = _load(rel, None, iterations)
    h.setOptionValue("time_limit", seconds)
    n = rel.A.shape[1]
    cols = np.arange(n, dtype=np.int32)
    unsigned = np.array(list({i: sign * c for i, sign, c in tasks}.values()))
    rng = np.random.default_rng(0)
    points: list[tuple[np.ndarray, tuple | None]] = []
    reached = 0
    for k in range(PROBES):
        signs = (rng.choice([-1.0, 1.0], len(unsigned)) if k >= 2
                 else np.full(len(unsigned), 1.0 if k == 0 else -1.0))
        c = signs @ unsigned
        h.changeColsCost(n, cols, (-c).astype(float))
        h.run()
        sol = h.getSolution()
        if not (sol.value_valid and h.getInfo().primal_solution_status == 2):
            break
        points.append((np.asarray(sol.col_value), _basis(h)))
        now = sum(_reaching(c_t, points, rel) is not None for _, _, c_t in tasks)
        if now <= reached:
            break
        reached = now
    return points


def _reaching(c: np.ndarray, points: list[tuple[np.ndarray, Any]],
              rel: LinearRelaxation) -> int | None:
    """The first LP point (of (point, basis) pairs) that already attains the box's own bound
    on c.p, or None: then the LP cannot tighten it, and solving it is skipped. (Skipping never
    narrows anything, so it is sound whatever the points are; it saves most LPs of a round
    far from the solution, where many unknowns do not move.)"""
    if not points:
        return None
    box = box_max_up(c, c, rel.lo, rel.hi)
    if not np.isfinite(box):
        return None
    values = np.stack([p for p, _ in points]) @ c
    hits = np.flatnonzero(values >= box - 1e-9 * (1.0 + abs(box)))
    return int(hits[0]) if len(hits) else None


def _starting_rows(rel: LinearRelaxation) -> np.ndarray:
    """Evenly spread rows, a few per column: enough to bound the LP well at the start."""
    m, n = rel.A.shape
    return np.unique(np.linspace(0, m - 1, min(m, 8 * n)).astype(np.int64))


class _RowCheck:
    """Which rows outside the LP a point violates."""

    def __init__(self, rel: LinearRelaxation) -> None:
        A = rel.A
        self.rel = rel
        self.row_of = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
        self.b_lo = rel.b_lo if rel.b_lo is not None else np.full(A.shape[0], -np.inf)

    def violated(self, x: np.ndarray, rows: np.ndarray) -> np.ndarray:
        A, m = self.rel.A, self.rel.A.shape[0]
        prods = A.data * x[A.indices]
        ax = np.bincount(self.row_of, weights=prods, minlength=m)
        scale = np.bincount(self.row_of, weights=np.abs(prods), minlength=m)
        tol = 1e-9 * scale + 1e-12
        with np.errstate(invalid="ignore"):
            excess = np.maximum(ax - self.rel.b, self.b_lo - ax) - tol
        excess[rows] = 0.0
        bad = np.flatnonzero(excess > 0)
        return bad[np.argsort(-excess[bad])[:ROWS_ADDED]]


def _add_rows(h: Any, rel: LinearRelaxation, rows: np.ndarray) -> None:
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


def _load(rel: LinearRelaxation, rows: np.ndarray | None = None,
          iterations: int = LP_ITERATIONS) -> Any:
    """A HiGHS model of the relaxation, with only `rows` of its rows if given."""
    import highspy

    h = _new_highs()
    h.setOptionValue("output_flag", False)
    h.setOptionValue("simplex_iteration_limit", iterations)  # counted per run
    # HiGHS equilibrates rows and columns by default. Our relaxations are built scaled (the
    # second-order ones in t-units, each column in [-1, 1]), and without HiGHS's own scaling
    # the simplex takes half the pivots from the same bases to the same bounds: on the RX90
    # from section 4, 57 000 second-order pivots instead of 123 000 and 21 000 first-order
    # ones instead of 39 000, widths equal to 0.1 % (docs/compiler.md).
    h.setOptionValue("simplex_scale_strategy", SCALING)
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


_GREETED = threading.Lock()  # held while the process's first HiGHS object is made
_greeted = False


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
