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
"""

from __future__ import annotations

import numpy as np

from calib_dsl.ir.program import Program
from calib_dsl.lp.certify import Certificates, mapped
from calib_dsl.relax.quadratic import FAMILY as SECOND_ORDER
from calib_dsl.relax.quadratic import relax_quadratic
from calib_dsl.relax.quadratic_readings import FAMILY as READINGS_FAMILY
from calib_dsl.relax.quadratic_readings import relax_quadratic_readings
from calib_dsl.relax.relaxation import LinearRelaxation


def violated_rows(prog: Program, certs: Certificates, rows: np.ndarray
                  ) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """For each optimum kept in the LP columns of `certs` (a second-order family, with its
    box): the loop rows of `rows` whose relaxed inequalities cut it off, and by how much
    (in the rows' own units). None where the check cannot be made this way."""
    lay = prog.rows
    if lay is None or certs.box is None or not certs.columns or len(rows) == 0:
        return None
    lo, hi = certs.box
    if certs.family == READINGS_FAMILY:
        built = relax_quadratic_readings(prog, lo, hi, rows=rows)
    elif certs.family == SECOND_ORDER:
        built = relax_quadratic(prog, lo, hi, prune=0.0, rows=rows)
    else:
        return None
    if built is None:
        return None
    rel, ex = built
    if rel.keys is None or rel.col_keys is None:
        return None
    slots = ex.rows.slots[rel.keys]
    data_row = (slots - lay.shared) // max(lay.width, 1)
    out = []
    for keys, values in certs.columns.values():
        excess = _excess(rel, mapped(keys, values, rel.col_keys, np.nan))
        bad = (excess > 0) & (slots >= lay.shared)
        out.append((data_row[bad], excess[bad]))
    return out


def _excess(rel: LinearRelaxation, x: np.ndarray) -> np.ndarray:
    """How far each row of rel is from holding at x, where the columns x leaves unknown
    (NaN) take whatever value in their bounds suits that row best: > 0 where none does."""
    A = rel.A
    m = A.shape[0]
    row = np.repeat(np.arange(m), np.diff(A.indptr))
    col, a = A.indices, A.data
    known = ~np.isnan(x[col])
    fixed = np.bincount(row[known], a[known] * x[col[known]], minlength=m)
    free = ~known
    lo_part = np.minimum(a[free] * rel.lo[col[free]], a[free] * rel.hi[col[free]])
    hi_part = np.maximum(a[free] * rel.lo[col[free]], a[free] * rel.hi[col[free]])
    least = fixed + np.bincount(row[free], lo_part, minlength=m)
    most = fixed + np.bincount(row[free], hi_part, minlength=m)
    with np.errstate(invalid="ignore"):
        over = np.where(np.isfinite(rel.b), least - rel.b, -np.inf)
        under = (np.where(np.isfinite(rel.b_lo), rel.b_lo - most, -np.inf)
                 if rel.b_lo is not None else np.full(m, -np.inf))
    return np.nan_to_num(np.maximum(over, under), nan=-np.inf)
