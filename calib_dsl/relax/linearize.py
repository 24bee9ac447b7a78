"""A linear relaxation of the whole program on the current box (centered / mean-value form).

Every constraint of the program is, after decomposition, "a primitive's output equals a slot
that is already known some other way": a measurement constant, a declared unknown, or a
temporary computed earlier. Writing each side as a function of the declared unknowns p, the
mean-value theorem on the box [p] gives

    f(p) in f(p^) + G (p - p^),   G an interval enclosure of the gradient over the box,

so every solution satisfies two linear inequalities in p. G is the *mixed* (Hansen) form:
its column j encloses the derivative in p_j over the box in which the unknowns before j keep
their ranges and those after j sit at the center (f(p) - f(p^) telescopes one unknown at a
time, so the form holds as well); each column sees about half the box, and so the
relaxation's slack is about half the plain form's (docs/decisions/02). The coefficients are
the midpoints of G; the radii of G, the width of f(p^) (it holds the data's uncertainty,
folded in instead of one LP variable per measured joint angle) and every rounding error go
into the right-hand sides.
Gradients are propagated forward through the flat program with the same grouping as the
propagator, in interval arithmetic over the *whole* box (not the contracted temporaries: the
mean-value theorem needs the derivative along segments that leave the solution set).
"""

from __future__ import annotations

import numpy as np

from calib_dsl.ir.program import Program
from calib_dsl.relax.chunked import Evaluated, evaluation
from calib_dsl.relax.layout import independents
from calib_dsl.relax.relaxation import RHS_REL, LinearRelaxation, Rows


def relax(prog: Program, lo: np.ndarray, hi: np.ndarray, cell_variables: bool = True,
          max_cell_columns: int | None = None, rows: np.ndarray | None = None
          ) -> LinearRelaxation | None:
    """Valid inequalities A x <= b over the box [lo, hi]; x = (p, dq).

    p are the declared unknowns (the first `main` columns). With `cell_variables`, each
    measured value's error dq of one configuration is an LP variable too (bounded by its
    tolerance), so the rows of a configuration share it, as they should; without, each row
    bounds it alone (folded into the right-hand side: fewer columns, a little looser). Over
    `max_cell_columns` such columns, they are folded anyway (the LP would grow too large).
    `rows`: the constraints of these rows of the loop compiled once only (and the shared
    part's): fewer valid inequalities, a valid relaxation still.
    """
    done = relax_evaluated(prog, lo, hi, cell_variables, max_cell_columns, rows=rows)
    return None if done is None else done[0]


def relax_evaluated(prog: Program, lo: np.ndarray, hi: np.ndarray, cell_variables: bool = True,
                    max_cell_columns: int | None = None, owners: bool = False,
                    rows: np.ndarray | None = None
                    ) -> tuple[LinearRelaxation, Evaluated] | None:
    """`relax`, and the evaluation it was made from (its rows' sources and targets; with
    `owners`, their data rows)."""
    ind = independents(prog)
    plo, phi = lo[ind], hi[ind]
    if len(ind) == 0 or not (np.all(np.isfinite(plo)) and np.all(np.isfinite(phi))):
        return None
    center = 0.5 * (plo + phi)
    ev = evaluation(prog, lo, hi, center, mixed=True, owners=owners, rows=rows)
    done = ev.run()
    if not done:
        return None
    rel = inequalities(done, center, plo, phi, ev.e, cell_variables, max_cell_columns)
    assert rel.keys is not None
    rel.targets = ev.targets()[rel.keys]
    return rel, ev


def inequalities(rows: list, center: np.ndarray, plo: np.ndarray, phi: np.ndarray,
                  e: np.ndarray, cell_variables: bool,
                  max_cell_columns: int | None = None) -> LinearRelaxation:
    """0 in D + H (p - p^) + Q dq  with  |p - p^| <= w, |dq| <= e  gives a two-sided row:
    -D_hi - slack + h.p^ <= h.p + q.dq <= -D_lo + slack + h.p^, where h, q are midpoints and
    the slack bounds the radii times w and e (and every rounding)."""
    dlo, dhi = (np.concatenate([r[0][i] for r in rows]) for i in (0, 1))
    hlo, hhi = (np.concatenate([r[1][i] for r in rows]) for i in (0, 1))
    qlo, qhi = (np.concatenate([r[2][i] for r in rows]) for i in (0, 1))
    owner = np.concatenate([r[3] for r in rows])
    with np.errstate(invalid="ignore"):
        h, hrad = mid_rad(hlo, hhi)
        q, qrad = mid_rad(qlo, qhi)
    # a row with an unbounded coefficient says nothing: make it drop out (b = +inf)
    bad = ~(np.all(np.isfinite(h), axis=1) & np.all(np.isfinite(q), axis=1))
    h[bad], q[bad], hrad[bad] = 0.0, 0.0, np.inf
    w = np.maximum(center - plo, phi - center) * (1 + 4 * RHS_REL)
    slack = hrad @ w + qrad @ e
    folded = np.abs(q) @ e
    share = _remainder_share(slack, folded + 0.5 * (dhi - dlo))
    curvature = _curvature(hrad @ w, np.abs(h) @ w)
    if cell_variables and max_cell_columns is not None and q.shape[1]:
        used = np.unique((owner[:, None] * q.shape[1] + np.arange(q.shape[1]))[
            (q != 0) & (owner[:, None] >= 0)])
        cell_variables = len(used) <= max_cell_columns
    if not cell_variables:
        slack = slack + folded  # each row bounds the cell errors alone
        q = q[:, :0]
    hc = h @ center
    err = RHS_REL * (hrad @ w + qrad @ e + folded + np.abs(h) @ np.abs(center)
                  + np.abs(dlo) + np.abs(dhi) + np.abs(hc)) + 1e-300
    b_up = -dlo + slack + hc + err
    b_dn = dhi + slack - hc + err
    (rows_, cols_, vals), xlo, xhi, cells = cell_columns(q, owner, e)
    A = Rows.join(h, rows_, cols_, vals, len(xlo))
    # one two-sided row per constraint: -b_dn <= h.p + q.dq <= b_up
    b_lo = -b_dn
    keep = np.flatnonzero((np.isfinite(b_up) | np.isfinite(b_lo)) & (A.row_nonzeros() > 0))
    return LinearRelaxation(A.take(keep), b_up[keep], np.concatenate([plo, xlo]),
                            np.concatenate([phi, xhi]), main=len(plo), cells=cells,
                            b_lo=b_lo[keep], remainder_share=share, curvature=curvature,
                            keys=keep, family="first order",
                            col_keys=np.concatenate([np.arange(len(plo)),
                                                     len(plo) + cells[:, 0] * q.shape[1]
                                                     + cells[:, 1]]))


def _remainder_share(remainder: np.ndarray, data: np.ndarray) -> float:
    with np.errstate(invalid="ignore", divide="ignore"):
        r = remainder / (remainder + data)
    r = r[np.isfinite(r)]
    return float(np.percentile(r, 90)) if len(r) else 1.0


def _curvature(remainder: np.ndarray, first_order: np.ndarray) -> float:
    with np.errstate(invalid="ignore", divide="ignore"):
        r = remainder / first_order
    r = r[np.isfinite(r)]
    return float(np.median(r)) if len(r) else 0.0


def mid_rad(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Midpoint and a radius covering [lo, hi] around it (rounding included)."""
    mid = 0.5 * (lo + hi)
    rad = np.maximum(mid - lo, hi - mid) * (1 + 4 * RHS_REL) + 1e-300
    return mid, rad


def cell_columns(q: np.ndarray, owner: np.ndarray, e: np.ndarray):
    """One LP column per (configuration, table column) that some row uses: q's midpoints
    scattered into those columns (as row, column, value triples); bounds +- e; and which cell
    each column is (ids as in `Slots.cell_row` / `Slots.cell_col`)."""
    m, k = q.shape
    rows, cols = np.nonzero((q != 0) & (owner[:, None] >= 0))
    if k == 0 or len(rows) == 0:
        none = np.zeros(0, dtype=np.int64)
        return (none, none, np.zeros(0)), np.zeros(0), np.zeros(0), np.zeros((0, 2), np.int64)
    key = owner[rows] * k + cols
    uniq, col = np.unique(key, return_inverse=True)
    bound = e[uniq % k]
    return (rows, col, q[rows, cols]), -bound, bound, np.stack([uniq // k, uniq % k], axis=1)


def constraint_jacobian(prog: Program, point: np.ndarray, lo: np.ndarray | None = None,
                        hi: np.ndarray | None = None) -> np.ndarray:
    """The Jacobian (midpoints) of every constraint row w.r.t. the declared unknowns at a point.

    Rows are the program's constraints in the order `relax` builds them; columns follow
    `independents(prog)`. For identifiability: no guarantee is claimed from it.
    """
    ind = independents(prog)
    blo = prog.slots.lo.copy() if lo is None else lo.copy()
    bhi = prog.slots.hi.copy() if hi is None else hi.copy()
    blo[ind], bhi[ind] = point, point
    rows = evaluation(prog, blo, bhi, np.asarray(point, dtype=float), point=True).run()
    if not rows:
        return np.zeros((0, len(ind)))
    return np.concatenate([0.5 * (r[1][0] + r[1][1]) for r in rows])
