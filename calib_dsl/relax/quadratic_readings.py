"""Second-order rows with the readings' errors as LP columns, for a box near its end.

quadratic.py folds each reading's error (a joint angle read to +-1e-5 rad) into every row's
remainder, where the rows of one configuration share it: near the end that costs more than
the curvature it keeps. linearize.py keeps the errors as LP columns but pays the curvature
in every row's right-hand side: a small share of a row's width becomes a large share of each
parameter's, since the feasible set's width is the rows' width less the least error the
data allow (docs/decisions/10). Here a row is split by the mean-value theorem in the readings alone:

    f(p, m + dq) = f(p, m) + D dq,      D over the box (p, and the readings in their ranges)

with m the readings' midpoints. f(p, m) comes from the second-order models over the box with
the readings fixed at m (taylor.py), D from the first-order evaluation (evaluation.py), so
every solution (p, dq) satisfies

    c0 + c1.t + c2.y + D^.dq  in  [lo, hi] + [-(r + rad(D).e), r + rad(D).e]

(D^ D's midpoint), each product y an LP column in [-1, 1] ([0, 1] for a square), shared by
all rows. McCormick's inequalities tying y to its factors are optional: they more than
triple the rows for little more narrowing (docs/decisions/10). The
two passes' rows are matched by their place in the program (layout.row_key). A row whose
readings come from two configurations (the evaluation folds those) is left out: the rows of
a valid relaxation, fewer, still hold every solution. A program with no readings gets None.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from calib_dsl.arith.interval import dn1, up1
from calib_dsl.compile.chunks import Chunk, chunked
from calib_dsl.ir.program import Program, derived
from calib_dsl.relax.chunked import in_threads, widest
from calib_dsl.relax.evaluation import Evaluation
from calib_dsl.relax.layout import independents
from calib_dsl.relax.linearize import cell_columns, mid_rad
from calib_dsl.relax.ownership import MIXED, NONE, combine, value_rows
from calib_dsl.relax.quadratic import (
    KEY_SPACE,
    kept_products,
    mccormick_keys,
    padded,
    row_keys,
    with_mccormick,
)
from calib_dsl.relax.relaxation import RHS_REL, LinearRelaxation, Rows
from calib_dsl.relax.taylor import CHUNK_SLOTS, Expansion, chunk_rows, expand, joined

FAMILY = "second order, readings as columns"  # LinearRelaxation.family of these


def relax_quadratic_readings(prog: Program, lo: np.ndarray, hi: np.ndarray,
                             mccormick: bool = False, prune: float = 0.0,
                             rows: np.ndarray | None = None
                             ) -> tuple[LinearRelaxation, Expansion] | None:
    """Valid inequalities over the box in the columns (t, y, dq), or None (see above);
    `prune` as in quadratic.relax_quadratic; of the loop's rows `rows` only, if given (fewer
    rows: still valid). A large program whose rows were compiled once is relaxed a chunk of
    rows at a time (compile/chunks.py): both passes run on a chunk's program, and its rows
    join the others' with slots and configurations renumbered."""
    ind = independents(prog)
    if len(ind) == 0:
        return None
    if not (np.all(np.isfinite(lo[ind])) and np.all(np.isfinite(hi[ind]))):
        return None
    reading = _readings(prog)
    if reading is None or not np.any(reading & (hi > lo)):
        return None
    centre = 0.5 * lo[ind] + 0.5 * hi[ind]
    chunks = chunked(prog, CHUNK_SLOTS, rows)
    if chunks is None:
        parts = [_part(prog, reading, lo, hi, ind, centre, None)]
    else:
        # (one program serves every chunk: its readings are found once)
        local = _readings(chunks[0].prog)
        if local is None:
            return None
        parts = in_threads(lambda ch: _part(ch.prog, local, ch.box(lo), ch.box(hi), ind,
                                            centre, ch), chunks)
    if any(part is None for part in parts):
        return None
    return _joined(prog, [part for part in parts if part is not None], mccormick, prune)


@dataclass
class _Part:
    """The rows of one pass (the whole program or a chunk): the expansion (readings at their
    midpoints) of every row the pass keeps, which of them are usable (`ok`), and for those
    the readings' derivatives (midpoints q, radii qrad), each row's configuration (as the
    whole program numbers it) and the readings' error bounds `e`."""

    ex: Expansion
    ok: np.ndarray
    q: np.ndarray
    qrad: np.ndarray
    owner: np.ndarray
    e: np.ndarray


def _part(prog: Program, reading: np.ndarray, lo: np.ndarray, hi: np.ndarray,
          ind: np.ndarray, centre: np.ndarray, chunk: Chunk | None) -> _Part | None:
    # the readings' derivatives D and each row's configuration alone: the gradient in the
    # unknowns (the models' c1 holds that part) is not computed (G with no columns). D is
    # made from the slots' ranges over the box, never from G or the centre: the same bits
    ev = Evaluation(prog, lo, hi, ind[:0], centre[:0])
    forms = ev.run()
    if not forms:
        return None
    # the models with every reading at the midpoint the evaluation's errors are about
    at = np.flatnonzero(reading)
    mlo, mhi = lo.copy(), hi.copy()
    mlo[at] = mhi[at] = 0.5 * (lo[at] + hi[at])  # (as the evaluation's midpoints)
    ex = expand(prog, mlo, mhi)
    if ex is None or ex.rows.keys is None:
        return None
    if chunk is not None:  # this chunk's own rows, in the whole program's numbering
        ex.rows = chunk_rows(ex.rows, chunk)
    keys = ex.rows.keys
    assert keys is not None  # (a chunk's rows keep their keys)
    ekeys = np.concatenate(ev.keys)
    dlo, dhi = (np.concatenate([f[2][i] for f in forms]) for i in (0, 1))
    owner = np.concatenate([f[3] for f in forms])
    order = np.argsort(ekeys)
    found = np.minimum(np.searchsorted(ekeys[order], keys), len(ekeys) - 1)
    e_at = order[found]
    matched = ekeys[e_at] == keys
    own = _own_configuration(prog, ind, reading, ev)[e_at]
    m = ex.rows.models
    ok = matched & own & np.isfinite(m.r) & np.isfinite(m.c0)
    ok &= np.isfinite(ex.rows.lo) | np.isfinite(ex.rows.hi)
    ok &= np.all(np.isfinite(m.c1), axis=1) & np.all(np.isfinite(m.c2), axis=1)
    with np.errstate(invalid="ignore"):
        q, qrad = mid_rad(dlo[e_at], dhi[e_at])
    ok &= np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(qrad), axis=1)
    owner = owner[e_at[ok]]
    if chunk is not None:
        owner = chunk.row_ids(owner)
    return _Part(ex, ok, q[ok], qrad[ok], owner, ev.e)


def _joined(prog: Program, parts: list[_Part], mccormick: bool, prune: float
            ) -> tuple[LinearRelaxation, Expansion] | None:
    """One relaxation of the parts' usable rows of `prog`, each known by its constraint's id
    in it (as quadratic.relax_quadratic numbers them)."""
    first = parts[0].ex
    if len(parts) == 1:
        ex = first
    else:
        ex = Expansion(first.center, first.half, first.pairs,
                       joined([p.ex.rows for p in parts]))
    ok = np.concatenate([p.ok for p in parts])
    if not np.any(ok):
        return None
    # (the chunks' program is one: the same readings' columns, each chunk's own bounds)
    q, qrad = (np.concatenate([getattr(p, a) for p in parts]) for a in ("q", "qrad"))
    e = functools.reduce(widest, [p.e for p in parts])
    return _relaxation(prog, ex, ok, (q, qrad, np.concatenate([p.owner for p in parts]), e),
                       mccormick, prune)


def _relaxation(prog: Program, ex: Expansion, ok: np.ndarray,
                readings: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
                mccormick: bool, prune: float) -> tuple[LinearRelaxation, Expansion]:
    """The relaxation of the expansion's rows where `ok` holds; `readings`: their readings'
    derivatives (midpoints q, radii qrad), configurations and error bounds."""
    q, qrad, owner, e = readings
    at = np.flatnonzero(ok)
    m = ex.rows.models.take(at)
    tlo, thi = ex.rows.lo[at], ex.rows.hi[at]
    keep, dropped = kept_products(m, tlo, thi, prune)
    ex.kept = keep
    n, pairs = m.c1.shape[1], ex.pairs
    slack = up1(up1(m.r + dropped) + up1(qrad @ e) * (1 + RHS_REL))
    err = RHS_REL * (np.abs(m.c0) + np.abs(np.where(np.isfinite(thi), thi, 0.0))
                     + np.abs(np.where(np.isfinite(tlo), tlo, 0.0)) + slack) + 1e-300
    with np.errstate(invalid="ignore"):
        b_up = up1(thi - m.c0) + slack + err
        b_lo = dn1(tlo - m.c0) - slack - err
    (rows, cols, vals), xlo, xhi, cells = cell_columns(q, owner, e)
    matrix = Rows.join(np.hstack([m.c1, m.c2[:, keep]]), rows, cols, vals, len(xlo))
    keys, targets = row_keys(ex, at), ex.rows.slots[at]
    if mccormick:
        matrix, b_up, b_lo = with_mccormick(matrix, b_up, b_lo, pairs, keep, n)
        keys, targets = mccormick_keys(prog, keys, targets, keep)
    clo = np.concatenate([-np.ones(n), np.where(pairs.diagonal[keep], 0.0, -1.0), xlo])
    chi = np.concatenate([np.ones(n + len(keep)), xhi])
    cell_keys = n + len(pairs.i) + cells[:, 0] * q.shape[1] + cells[:, 1]
    rel = LinearRelaxation(
        matrix, b_up, clo, chi, main=n, b_lo=b_lo, scale=ex.half, center=ex.center, family=FAMILY,
        key_space=KEY_SPACE, slack=padded(slack, len(b_up)),
        keys=keys, targets=targets, col_keys=np.concatenate([np.arange(n), n + keep, cell_keys]))
    return rel, ex


def _readings(prog: Program) -> np.ndarray | None:
    """The measured values that enter the model as arguments (a mask), or None where one is
    also a compared side (fixing it at its midpoint would fix that row's target too)."""
    rows = prog.slots.cell_row
    if rows is None:
        return None
    # (which slots are arguments and outputs depends on the groups alone: found once per
    # program, not once per group of rows a relaxed check relaxes; the domains may change)
    argument, compared = derived(prog, "arguments and outputs", lambda: _roles(prog))
    lo, hi = prog.slots.lo, prog.slots.hi
    measured = (rows >= 0) & np.isfinite(lo) & np.isfinite(hi)
    reading = measured & argument
    if np.any(reading & compared & (hi > lo)):
        return None
    return reading


def _roles(prog: Program) -> tuple[np.ndarray, np.ndarray]:
    """Which slots some primitive reads (an argument), and which some primitive sets."""
    n = len(prog.slots.lo)
    argument, compared = np.zeros(n, bool), np.zeros(n, bool)
    for g in prog.groups:
        argument[g.args[g.args >= 0]] = True
        compared[g.out[g.out >= 0]] = True
    return argument, compared


def _own_configuration(prog: Program, ind: np.ndarray, reading: np.ndarray,
                       ev: Evaluation) -> np.ndarray:
    """For each row of the run evaluation `ev` (in its order): whether its readings, if any,
    are all of one configuration, with none of two configurations met on the way (the
    evaluation folds those into its constants, where the models at the midpoints cannot see
    them), and whether it compares with a measured value (between two computed sides, the
    evaluation folds its readings too)."""
    value = np.concatenate([value_rows(prog, ind, only=reading), [NONE]])
    out = []
    for args, row in zip(ev.sources, ev.rows, strict=True):
        slots, by_domain = row[5], row[6]
        v = np.full(len(slots), NONE)
        for j in range(args.shape[1]):
            v = combine(v, value[args[:, j]])
        out.append(v != MIXED if by_domain else (v == NONE) & (value[slots] == NONE))
    return np.concatenate(out)
