"""The working set's check on the relaxation's own rows: the rows left out, relaxed as the
last LPs' were (on their box, in the same columns), evaluated at those LPs' optima.

A working-set LP's optimum (t, y, dq) can satisfy the model at its parameters while the
second-order rows of rows left out, at that same (t, y), exclude it: the products y are
free of t_i t_j within McCormick's inequalities, and the readings' errors dq are columns.
A row left out is violated where no value of its own columns (its readings' errors, and
any product the working set's LPs had no column for) within their bounds satisfies it with
the optimum's other columns: then adding it changes that LP's optimum. The test is on each
inequality alone (a row's readings free per inequality): it finds only rows that surely cut
the optimum off. Which rows join the set is a cost choice: every relaxation of some rows
holds every solution.

The rows are checked a chunk at a time (each chunk's relaxation made, evaluated and
dropped): the memory follows the chunk, not the campaign, and a row's relaxed inequalities
are its own, so the rows found are those of one relaxation of them all. The chunks are
shared among `workers` threads (numpy's array work runs outside the GIL), their results
joined in the chunks' order: the same on every run.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.ir.program import Program
from calib_dsl.lp.certify import Certificates, mapped
from calib_dsl.relax.chunked import in_threads
from calib_dsl.relax.quadratic import FAMILY as SECOND_ORDER
from calib_dsl.relax.quadratic import relax_quadratic
from calib_dsl.relax.quadratic_readings import FAMILY as READINGS_FAMILY
from calib_dsl.relax.quadratic_readings import relax_quadratic_readings
from calib_dsl.relax.relaxation import LinearRelaxation
from calib_dsl.relax.taylor import CHUNK_SLOTS


def violated_rows(prog: Program, certs: Certificates, rows: np.ndarray, workers: int = 1
                  ) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """For each optimum kept in the LP columns of `certs` (a second-order family, with its
    box): the loop rows of `rows` whose relaxed inequalities cut it off, and by how much
    (in the rows' own units), the chunks shared among `workers` threads. None where the
    check cannot be made this way."""
    if prog.rows is None or certs.box is None or not certs.columns or len(rows) == 0:
        return None
    # (chunk-sized groups of the rows, as compile/chunks.py sizes them; each relaxed on its
    # own from the whole program, so no chunk program is built)
    lay = prog.rows
    size = max(1, (CHUNK_SLOTS - lay.shared) // max(lay.width, 1))
    parts = [rows[a:a + size] for a in range(0, len(rows), size)]
    found = in_threads(lambda part: _violated(prog, certs, part), parts, workers)
    if any(f is None for f in found):
        return None
    return [(np.concatenate([f[k][0] for f in found if f is not None]),
             np.concatenate([f[k][1] for f in found if f is not None]))
            for k in range(len(certs.columns))]


def _violated(prog: Program, certs: Certificates, rows: np.ndarray
              ) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """violated_rows on one relaxation of `rows`."""
    lay = prog.rows
    assert lay is not None and certs.box is not None
    lo, hi = certs.box
    if certs.family == READINGS_FAMILY:
        built = relax_quadratic_readings(prog, lo, hi, rows=rows)
    elif certs.family == SECOND_ORDER:
        built = relax_quadratic(prog, lo, hi, prune=0.0, rows=rows)
    else:
        return None
    if built is None:
        return None
    rel, _ = built
    if rel.targets is None or rel.col_keys is None:
        return None
    slots = rel.targets
    data_row = (slots - lay.shared) // max(lay.width, 1)
    points = np.array([mapped(keys, values, rel.col_keys, np.nan)
                       for keys, values in certs.columns.values()])
    out = []
    for excess in _excesses(rel, points):
        bad = (excess > 0) & (slots >= lay.shared)
        out.append((data_row[bad], excess[bad]))
    return out


def _excess(rel: LinearRelaxation, x: np.ndarray) -> np.ndarray:
    """How far each row of rel is from holding at x, where the columns x leaves unknown
    (NaN) take whatever value in their bounds suits that row best: > 0 where none does."""
    return _excesses(rel, x[None])[0]


def _excesses(rel: LinearRelaxation, X: np.ndarray) -> np.ndarray:
    """_excess at each row of X (points x columns). Points that leave the same columns
    unknown (the optima of one LP) share the free columns' part, and their known part is
    one sparse product for all of them."""
    from scipy.sparse import csr_matrix  # (a large campaign's check only: a slow import)

    A = rel.A
    m = A.shape[0]
    row = np.repeat(np.arange(m), np.diff(A.indptr))
    col, a = A.indices, A.data
    out = np.empty((len(X), m))
    groups: dict[bytes, list[int]] = {}
    for k, x in enumerate(X):
        groups.setdefault(np.isnan(x).tobytes(), []).append(k)
    for members in groups.values():
        known = ~np.isnan(X[members[0]])[col]
        fixed = csr_matrix((np.where(known, a, 0.0), col, A.indptr), shape=A.shape) \
            @ np.nan_to_num(X[members], nan=0.0).T  # (m, points)
        free = ~known
        af, lo, hi = a[free], rel.lo[col[free]], rel.hi[col[free]]
        least = np.bincount(row[free], np.minimum(af * lo, af * hi), minlength=m)
        most = np.bincount(row[free], np.maximum(af * lo, af * hi), minlength=m)
        out[members] = _outside(rel, fixed + least[:, None], fixed + most[:, None]).T
    return out


def _outside(rel: LinearRelaxation, least: np.ndarray, most: np.ndarray) -> np.ndarray:
    """How far rows whose value ranges over [least, most] (rows x points) are from their
    sides: > 0 where no value in the range holds."""
    b = rel.b[:, None]
    with np.errstate(invalid="ignore"):
        over = np.where(np.isfinite(b), least - b, -np.inf)
        if rel.b_lo is None:
            under = np.full(least.shape, -np.inf)
        else:
            b_lo = rel.b_lo[:, None]
            under = np.where(np.isfinite(b_lo), b_lo - most, -np.inf)
    return np.nan_to_num(np.maximum(over, under), nan=-np.inf)
