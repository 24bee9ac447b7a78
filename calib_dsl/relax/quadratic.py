"""A linear relaxation of the whole program over a wide box, from second-order Taylor models.

Each constraint row is, over the box (taylor.py, p = c + w t, t in [-1, 1]^n),

    c0 + c1.t + sum_k c2_k t_i t_j + [-r, r]  meets  the row's target [lo, hi].

Give each product t_i t_j an LP column y_k of its own, bounded by [-1, 1] ([0, 1] for a
square): the rows become linear in (t, y), and every solution p gives a point (t, y) that
satisfies them. The columns y are *shared* by all rows: hundreds of rows see the same
few hundred products, so the LP pins the curvature down as it pins t, where a first-order
relaxation pays each row's curvature alone in its right-hand side. Products whose
coefficients are small in every row go back into the rows' remainders (fewer columns).
Optionally, McCormick's inequalities tie each y_k to its t_i and t_j; they add little to
the shared columns and quadruple the rows, so they are off by default.

The LP's bounds on t are certified by lpbound like any other relaxation; `to_box` maps them
back to p with outward rounding.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from calib_dsl.arith import interval as iv
from calib_dsl.arith.interval import dn1, up1
from calib_dsl.ir.program import Program
from calib_dsl.relax.models import Models
from calib_dsl.relax.relaxation import RHS_REL, LinearRelaxation, Rows
from calib_dsl.relax.taylor import Expansion, expand, ids_end
from calib_dsl.settings import RoundsSettings

FAMILY = "second order"  # LinearRelaxation.family of these relaxations
# LinearRelaxation.key_space of every second-order relaxation: a constraint row is known by
# its constraint's id in the whole program (row_keys), a McCormick row by its product (after
# every constraint's id)
KEY_SPACE = "expansion rows"


def relax_quadratic(prog: Program, lo: np.ndarray, hi: np.ndarray,
                    prune: float = RoundsSettings.prune, mccormick: bool = False,
                    rows: np.ndarray | None = None) -> tuple[LinearRelaxation, Expansion] | None:
    """Valid inequalities over the box in the columns (t, y) (of the loop's rows `rows`
    only, if given); None if the program has no second-order models (a primitive without
    one, or an unbounded unknown)."""
    ex = expand(prog, lo, hi, rows)
    if ex is None:
        return None
    m = ex.rows.models
    ok = np.isfinite(m.r) & (np.isfinite(ex.rows.lo) | np.isfinite(ex.rows.hi))
    ok &= np.all(np.isfinite(m.c1), axis=1) & np.all(np.isfinite(m.c2), axis=1)
    ok &= np.isfinite(m.c0)
    if not np.any(ok):
        return None
    at = np.flatnonzero(ok)
    m = m.take(at)
    tlo, thi = ex.rows.lo[ok], ex.rows.hi[ok]
    keep, dropped = kept_products(m, tlo, thi, prune)
    ex.kept = keep
    n = m.c1.shape[1]
    pairs = ex.pairs
    slack = m.r + dropped
    err = RHS_REL * (np.abs(m.c0) + np.abs(np.where(np.isfinite(thi), thi, 0.0))
                  + np.abs(np.where(np.isfinite(tlo), tlo, 0.0)) + slack) + 1e-300
    with np.errstate(invalid="ignore"):
        b_up = up1(thi - m.c0) + slack + err
        b_lo = dn1(tlo - m.c0) - slack - err
    dense = np.hstack([m.c1, m.c2[:, keep]])
    ncols = n + len(keep)
    matrix = Rows.join(dense, np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), 0)
    clo = np.concatenate([-np.ones(n), np.where(pairs.diagonal[keep], 0.0, -1.0)])
    chi = np.ones(ncols)
    keys, targets = row_keys(ex, at), ex.rows.slots[at]
    if mccormick:
        matrix, b_up, b_lo = with_mccormick(matrix, b_up, b_lo, pairs, keep, n)
        keys, targets = mccormick_keys(prog, keys, targets, keep)
    rel = LinearRelaxation(matrix, b_up, clo, chi, main=n, b_lo=b_lo, keys=keys,
                           targets=targets,
                           scale=ex.half, family=FAMILY, key_space=KEY_SPACE, center=ex.center,
                           col_keys=np.concatenate([np.arange(n), n + keep]),
                           curvature=_curvature(m), slack=padded(slack, len(b_up)))
    return rel, ex


def row_keys(ex: Expansion, at: np.ndarray) -> np.ndarray:
    """The keys of the expansion's rows `at`: their constraints' ids in the whole program
    (taylor.constraint_ids), so that rows joining a relaxation leave the others' keys
    unchanged (the multipliers and rows carried from one relaxation to the next stay on
    their constraints)."""
    assert ex.rows.ids is not None  # (every expansion numbers its rows so)
    return ex.rows.ids[at]


def mccormick_keys(prog: Program, keys: np.ndarray, targets: np.ndarray, keep: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The keys and targets with McCormick's rows after the constraint rows: each known by
    its product and its place among the product's 4 rows, after every constraint's id; no
    target (-1)."""
    extra = ids_end(prog) + (4 * keep[:, None] + np.arange(4)).ravel()
    return (np.concatenate([keys, extra]),
            np.concatenate([targets, np.full(len(extra), -1, dtype=targets.dtype)]))


def _curvature(m: Models) -> float:
    """An estimate of the first-order relaxation's curvature on the same box (linearize:
    median over rows of its remainder over its first-order range) from the models: their
    second-order terms and remainder over their first-order terms. It runs below the
    first-order one but on the same side of `RoundsSettings.wide`, so it decides the same way; it
    spares a first-order relaxation only made to be measured."""
    with np.errstate(invalid="ignore", divide="ignore"):
        r = (np.abs(m.c2).sum(axis=1) + m.r) / np.abs(m.c1).sum(axis=1)
    r = r[np.isfinite(r)]
    return float(np.median(r)) if len(r) else 0.0


def padded(slack: np.ndarray, rows: int) -> np.ndarray:
    """The constraint rows' slack, and 0 for the rows after them (McCormick's: exact)."""
    return np.concatenate([slack, np.zeros(rows - len(slack))])


def kept_products(m: Models, tlo: np.ndarray, thi: np.ndarray,
                   prune: float) -> tuple[np.ndarray, np.ndarray]:
    """The product columns worth an LP column, and each row's remainder for the others
    (|c2_k| each: |t_i t_j| <= 1). Products go, smallest first, while no row's added
    remainder exceeds `prune` times its width."""
    width = np.where(np.isfinite(thi - tlo), 0.5 * (thi - tlo), np.inf) + m.r
    mag = np.abs(m.c2)
    used = np.flatnonzero(mag.max(axis=0, initial=0.0) > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        weight = np.where(width[:, None] > 0, mag[:, used] / width[:, None], np.inf)
    order = used[np.argsort(weight.max(axis=0, initial=0.0))]
    budget = prune * width
    added = np.zeros(len(width))
    drop = np.zeros(mag.shape[1], dtype=bool)
    for k in order:  # a few hundred columns: cheap
        trial = added + mag[:, k]
        if np.any(trial > budget):
            break
        added, drop[k] = trial, True
    keep = np.flatnonzero(~drop & (mag.max(axis=0, initial=0.0) > 0))
    return keep, added * (1 + 2.0**-40) + 1e-300  # the float sums, rounded up


def with_mccormick(rows: Rows, b_up: np.ndarray, b_lo: np.ndarray, pairs, keep: np.ndarray,
                    n: int) -> tuple[Rows, np.ndarray, np.ndarray]:
    """y = t_i t_j over [-1, 1]^2: y >= |t_i + t_j| - 1 and y <= 1 - |t_i - t_j| (i < j);
    y = t_i^2: y >= 2 a t_i - a^2 at a = +-1/2, +-1. Integer and half-integer coefficients:
    every row is exact in floating point."""
    r, c, v, lo, hi = [], [], [], [], []
    k = 0
    for col, q in enumerate(keep):
        i, j, y = int(pairs.i[q]), int(pairs.j[q]), n + col
        if i == j:
            for a in (-1.0, -0.5, 0.5, 1.0):
                r += [k, k]
                c += [y, i]
                v += [1.0, -2 * a]
                lo.append(-a * a)
                hi.append(np.inf)
                k += 1
        else:
            for si, sj, low, high in ((-1, -1, -1, np.inf), (1, 1, -1, np.inf),
                                      (-1, 1, -np.inf, 1), (1, -1, -np.inf, 1)):
                r += [k, k, k]
                c += [y, i, j]
                v += [1.0, float(si), float(sj)]
                lo.append(low)
                hi.append(high)
                k += 1
    extra = Rows.join(np.zeros((k, 0)), np.array(r, np.int64), np.array(c, np.int64),
                      np.array(v), rows.shape[1])
    joined = Rows(np.concatenate([rows.data, extra.data]),
                  np.concatenate([rows.indices, extra.indices]),
                  np.concatenate([rows.indptr, rows.indptr[-1] + extra.indptr[1:]]),
                  (rows.shape[0] + k, rows.shape[1]))
    return joined, np.concatenate([b_up, hi]), np.concatenate([b_lo, lo])


def narrowed(rel: LinearRelaxation, ex: Expansion, tl: np.ndarray,
             th: np.ndarray) -> LinearRelaxation:
    """The relaxation with its columns bounded by t in [tl, th] (clipped to [-1, 1]) and
    each product column by the product of its two factors' intervals (rounded outward): its
    rows hold on the whole box, so on every point of the smaller one, where [tl, th] holds
    every solution. The same multipliers then certify narrower bounds: the products shrink
    with the square of the box (and the reduced costs pay less of it)."""
    n = rel.main
    tl, th = np.maximum(tl, -1.0), np.minimum(th, 1.0)
    assert rel.col_keys is not None
    end = n + (len(ex.kept) if ex.kept is not None else rel.A.shape[1] - n)
    q = rel.col_keys[n:end] - n  # the kept products' positions among the pairs
    i, j = ex.pairs.i[q], ex.pairs.j[q]
    with iv.quiet():
        plo, phi = iv.mul((tl[i], th[i]), (tl[j], th[j]))
    plo = np.where(ex.pairs.diagonal[q], np.maximum(plo, 0.0), plo)  # a square: >= 0
    plo, phi = np.maximum(plo, rel.lo[n:end]), np.minimum(phi, rel.hi[n:end])
    # (columns after the products, a reading's error each, keep their bounds)
    return replace(rel, lo=np.concatenate([tl, plo, rel.lo[end:]]),
                   hi=np.concatenate([th, phi, rel.hi[end:]]))


def to_box(ex: Expansion, tl: np.ndarray, th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounds on p = c + w t for t in [tl, th] (clipped to [-1, 1]), rounded outward."""
    tl, th = np.maximum(tl, -1.0), np.minimum(th, 1.0)
    c, w = ex.center, ex.half
    low = dn1(c + dn1(w * tl)) - 2.0**-1074
    high = up1(c + up1(w * th)) + 2.0**-1074
    return low, high
