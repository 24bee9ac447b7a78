"""Leverage: data rows that carry most of what the data say about a parameter. A fault in
such a row does not show as an inconsistency (nothing else checks it): it moves the result.
So a "contracted" that rests on one row says so.

At the middle of the result, with the rows in units of their bounds (J, rows by columns), the
least-squares estimate of parameter k is a weighted sum of the rows' residuals, with weights
w = row k of pinv(J); the share of a data row in it is the sum of its rows' w^2 over all of
them (its share of the estimate's variance). A floating-point diagnosis, not a proof.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.analysis.lsq import linearized
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents
from calib_dsl.settings_analysis import FitSettings


@dataclass(frozen=True)
class Leverage:
    parameter: str
    data_row: int  # the table row id (Slots.row_keys)
    share: float


def heavy_rows(prog: Program, lo: np.ndarray, hi: np.ndarray,
               fits: FitSettings) -> list[Leverage]:
    """Per parameter the data estimate, the data row with more than `fits.leverage_share`
    of its estimate (none when the rows share it); largest share first. Directions the data
    see less than `fits.leverage_rcond` (relative) are not estimated."""
    ind = independents(prog)
    free = np.flatnonzero(hi[ind] > lo[ind])
    if not len(free) or prog.slots.row_keys is None:
        return []
    if set(ind.tolist()) & set(prog.slots.measured_sides or {}):
        return []  # a row merged into an unknown's domain: not among the rows weighed here
    p = np.where(np.isfinite(lo[ind]) & np.isfinite(hi[ind]), 0.5 * (lo[ind] + hi[ind]),
                 np.clip(0.0, lo[ind], hi[ind]))
    with np.errstate(all="ignore"):
        lin = linearized(prog, p)
        keep = (np.isfinite(lin.half) & (lin.half > 0) & (lin.data_row >= 0)
                & np.all(np.isfinite(lin.jac[:, free]), axis=1))
        J = lin.jac[keep][:, free] / lin.half[keep, None]
    rows = lin.data_row[keep]
    if J.shape[0] <= J.shape[1]:
        return []
    u, sv, vt = np.linalg.svd(J, full_matrices=False)
    seen = (sv > fits.leverage_rcond * sv[0] if len(sv) and sv[0] > 0
            else np.zeros(len(sv), dtype=bool))
    weights = (vt[seen].T / sv[seen]) @ u[:, seen].T  # pinv(J): parameters by rows
    out = []
    for j, k in enumerate(free):
        if np.linalg.norm(vt[~seen][:, j]) > 1e-6:
            continue  # not estimated alone: its share means nothing
        w2 = weights[j] ** 2
        by_row = np.bincount(rows, weights=w2)
        total = float(by_row.sum())
        top = int(np.argmax(by_row)) if total > 0 else -1
        if top >= 0 and by_row[top] > (fits.leverage_share + 1e-6) * total:  # not an even split
            out.append(Leverage(prog.slots.names[ind[k]], top, float(by_row[top] / total)))
    return sorted(out, key=lambda x: -x.share)
