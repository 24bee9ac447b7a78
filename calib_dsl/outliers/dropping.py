"""A linear relaxation of "every constraint holds, but those of at most K data rows" over a
box (`calibc solve --outliers K`).

Each data row k (a configuration: all its measured values) gets an LP column z_k in [0, 1],
with sum z_k <= K; each relaxation row of configuration k, `b_lo <= a.x <= b`, becomes two
one-sided rows

    a.x - M_up z_k <= b        a.x + M_dn z_k >= b_lo

with M_up >= max over the box of a.x - b (M_dn likewise), rounded up. With z_k = 1 both rows
hold on the whole box, whatever x is; with z_k = 0 they are the row itself. So every
parameter vector of the box that satisfies all rows but those of a set J of at most K data
rows satisfies the new rows with z the indicator of J (integer, sum <= K), and a fortiori the
LP with z continuous: its certified bounds (lp/, the z columns are nuisance columns like the
cells') hold for every such vector. A row that depends on several data rows (MIXED) is left
out (fewer rows: a relaxation still). Rows of data rows known to hold on the set (the sets of
rows of outliers/solve.py show which may fail) stay as they are.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.ir.program import Program
from calib_dsl.relax.linearize import relax_evaluated
from calib_dsl.relax.ownership import NONE
from calib_dsl.relax.relaxation import RHS_ABS, RHS_REL, LinearRelaxation, Rows


def relax_owned(prog: Program, lo: np.ndarray, hi: np.ndarray
                ) -> tuple[LinearRelaxation, np.ndarray] | None:
    """The first-order relaxation of the program over the box (linearize.relax, with a column
    per measured cell) and the data row each of its rows depends on."""
    done = relax_evaluated(prog, lo, hi, cell_variables=True, owners=True)
    if done is None:
        return None
    rel, ev = done
    owners = ev.data_rows()
    assert rel.keys is not None
    return rel, owners[rel.keys]


def dropping(rel: LinearRelaxation, owners: np.ndarray, k: int,
             may_fail: set[int] | None = None) -> LinearRelaxation:
    """The relaxation of `rel` in which the rows of at most k data rows may fail (above): of
    the data rows `may_fail` only, if given (the others hold on the set relaxed)."""
    m, n = rel.A.shape
    b_lo = rel.b_lo if rel.b_lo is not None else np.full(m, -np.inf)
    held = np.zeros(m, dtype=bool)  # rows of data rows that hold on the set
    if may_fail is not None:
        held = (owners >= 0) & ~np.isin(owners, np.array(sorted(may_fail), dtype=owners.dtype))
    hard = np.flatnonzero((owners == NONE) | held)
    soft = np.flatnonzero((owners >= 0) & ~held)
    data, z_of = np.unique(owners[soft], return_inverse=True)
    top, bottom = _row_ranges(rel, soft)
    up = soft[np.isfinite(rel.b[soft]) & np.isfinite(top)]
    dn = soft[np.isfinite(b_lo[soft]) & np.isfinite(bottom)]
    z_up, z_dn = (z_of[np.searchsorted(soft, r)] for r in (up, dn))
    m_up = _excess(top[np.searchsorted(soft, up)], rel.b[up])
    m_dn = _excess(-bottom[np.searchsorted(soft, dn)], -b_lo[dn])
    parts = [(hard, None, None, rel.b[hard], b_lo[hard]),
             (up, z_up, -m_up, rel.b[up], np.full(len(up), -np.inf)),
             (dn, z_dn, m_dn, np.full(len(dn), np.inf), b_lo[dn])]
    A, b, lo_side = _stack(rel.A, parts, n, len(data))
    # the budget: sum z <= k
    A = _append_row(A, n, len(data))
    b, lo_side = np.append(b, float(k)), np.append(lo_side, -np.inf)
    cells = rel.cells if rel.cells is not None else np.zeros((0, 2), np.int64)
    return LinearRelaxation(A, b, np.concatenate([rel.lo, np.zeros(len(data))]),
                            np.concatenate([rel.hi, np.ones(len(data))]), main=rel.main,
                            cells=cells, b_lo=lo_side, family="outliers")


def _row_ranges(rel: LinearRelaxation, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Upper bounds of max and lower bounds of min of a.x over the box, per row, rounded
    outward (the largest corner product of each entry, summed, plus the sum's error)."""
    A = rel.A.take(rows) if isinstance(rel.A, Rows) else Rows(rel.A.data, rel.A.indices,
                                                                 rel.A.indptr,
                                                                 rel.A.shape).take(rows)
    at = np.repeat(np.arange(len(rows)), np.diff(A.indptr))
    a, lo, hi = A.data, rel.lo[A.indices], rel.hi[A.indices]
    big = np.maximum(a * lo, a * hi)
    small = np.minimum(a * lo, a * hi)
    mag = np.bincount(at, weights=np.maximum(np.abs(big), np.abs(small)), minlength=len(rows))
    err = RHS_REL * mag + RHS_ABS
    top = np.bincount(at, weights=big, minlength=len(rows)) + err
    bottom = np.bincount(at, weights=small, minlength=len(rows)) - err
    return top, bottom


def _excess(top: np.ndarray, b: np.ndarray) -> np.ndarray:
    """M >= top - b (exactly), and >= 0: a bound on how far a.x exceeds b on the box."""
    d = top - b
    return np.maximum(d + RHS_REL * (np.abs(top) + np.abs(b)) + RHS_ABS, 0.0)


def _stack(A0: Rows, parts: list, n: int, nz: int) -> tuple[Rows, np.ndarray, np.ndarray]:
    """The rows of A0 picked by each part, each with its z entry (column n + z, value coef),
    as one CSR matrix over n + nz columns, and the parts' sides."""
    A0 = A0 if isinstance(A0, Rows) else Rows(A0.data, A0.indices, A0.indptr, A0.shape)
    data, indices, lengths, b, b_lo = [], [], [], [], []
    for rows, z, coef, up, dn in parts:
        sub = A0.take(rows)
        lens = np.diff(sub.indptr)
        if z is None:
            data.append(sub.data)
            indices.append(sub.indices)
            lengths.append(lens)
        else:  # one more entry at the end of each row: the z column (after every x column)
            starts = sub.indptr[:-1] + np.arange(len(rows))
            d = np.empty(len(sub.data) + len(rows))
            i = np.empty(len(d), dtype=np.int64)
            mask = np.ones(len(d), dtype=bool)
            mask[starts + lens] = False
            d[mask], i[mask] = sub.data, sub.indices
            d[~mask], i[~mask] = coef, n + z
            data.append(d)
            indices.append(i)
            lengths.append(lens + 1)
        b.append(up)
        b_lo.append(dn)
    lens = np.concatenate(lengths)
    indptr = np.zeros(len(lens) + 1, dtype=np.int64)
    np.cumsum(lens, out=indptr[1:])
    A = Rows(np.concatenate(data), np.concatenate(indices), indptr, (len(lens), n + nz))
    return A, np.concatenate(b), np.concatenate(b_lo)


def _append_row(A: Rows, n: int, nz: int) -> Rows:
    """A with one more row: the sum of the z columns."""
    return Rows(np.concatenate([A.data, np.ones(nz)]),
                np.concatenate([A.indices, n + np.arange(nz)]),
                np.append(A.indptr, A.indptr[-1] + nz), (A.shape[0] + 1, n + nz))
