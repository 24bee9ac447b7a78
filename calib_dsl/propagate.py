"""The fixed-point propagator: forward-backward sweeps over the flat program.

A sweep evaluates the groups upward (each output intersected with the enclosure of its
primitive's image) and projects them downward (each argument intersected with its optimal
projection). Everything is a numpy call per group; a slot that receives several projections in
one group intersects them all at once (`fmax.at` / `fmin.at`). fmax/fmin ignore NaN, so a NaN
could only ever mean "no contraction", never a lost solution.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .errors import Loc
from .program import Group, Program
from .projections import backward, forward
from .rotation import rot_contract


@dataclass
class Emptied:
    """Where propagation proved the model and data inconsistent."""

    variable: str
    loc: Loc | None
    primitive: str | None  # the primitive whose projection emptied it (listing text)


@dataclass
class Result:
    status: str  # "contracted" | "infeasible"
    lo: np.ndarray
    hi: np.ndarray
    sweeps: int
    seconds: float
    stop: str  # why the loop stopped: "fixed point", "tolerance", "max sweeps", "empty"
    emptied: Emptied | None = None
    rounds: int = 0  # LP rounds (tight strategy)


def propagate(prog: Program, tol: float = 1e-5, max_sweeps: int = 1000,
              lo: np.ndarray | None = None, hi: np.ndarray | None = None) -> Result:
    """Contract the program's domains (or the given box) to a fixed point."""
    start = time.perf_counter()
    box = [prog.slots.lo.copy() if lo is None else lo.copy(),
           prog.slots.hi.copy() if hi is None else hi.copy()]
    watch = _watched(prog)
    if np.any(box[0] > box[1]):
        s = int(np.flatnonzero(box[0] > box[1])[0])
        return _infeasible(box, 0, start, Emptied(prog.slots.names[s], prog.slots.origin[s], None))
    sweeps, stop = 0, "max sweeps"
    while sweeps < max_sweeps:
        before = (box[0][watch].copy(), box[1][watch].copy())
        saved = (box[0].copy(), box[1].copy())
        sweep(prog.groups, box[0], box[1])
        sweeps += 1
        if np.any(box[0] > box[1]):
            return _infeasible(box, sweeps, start, _diagnose(prog, *saved))
        gain = _contraction(before, (box[0][watch], box[1][watch]))
        if gain == 0.0:
            stop = "fixed point"
            break
        if gain < tol:
            stop = "tolerance"
            break
    return Result("contracted", box[0], box[1], sweeps, time.perf_counter() - start, stop)


def sweep(groups: list[Group], lo: np.ndarray, hi: np.ndarray) -> None:
    for g in groups:
        _forward(g, lo, hi)
    for g in reversed(groups):
        _backward(g, lo, hi)


def _forward(g: Group, lo: np.ndarray, hi: np.ndarray) -> None:
    if g.op == "rot":
        _rotation(g, lo, hi)
        return
    args = [(lo[c], hi[c]) for c in g.args.T]
    zlo, zhi = forward(g.op, args, g.param)
    _tighten(lo, hi, g.out[:, 0], zlo, zhi, g.out_unique[0])


def _backward(g: Group, lo: np.ndarray, hi: np.ndarray) -> None:
    if g.op == "rot":
        _rotation(g, lo, hi)
        return
    out = g.out[:, 0]
    args = [(lo[c], hi[c]) for c in g.args.T]
    new = backward(g.op, (lo[out], hi[out]), args, g.param)
    for c, (alo, ahi), unique in zip(g.args.T, new, g.args_unique, strict=True):
        _tighten(lo, hi, c, alo, ahi, unique)


def _rotation(g: Group, lo: np.ndarray, hi: np.ndarray) -> None:
    cols = [g.args[:, 0], g.args[:, 1], g.args[:, 2], g.out[:, 0], g.out[:, 1]]
    uniq = [*g.args_unique, *g.out_unique]
    new = rot_contract(*[(lo[c], hi[c]) for c in cols])
    for c, (alo, ahi), unique in zip(cols, new, uniq, strict=True):
        _tighten(lo, hi, c, alo, ahi, unique)


def _tighten(lo: np.ndarray, hi: np.ndarray, idx: np.ndarray, nlo: np.ndarray,
             nhi: np.ndarray, unique: bool) -> None:
    if unique:
        lo[idx] = np.fmax(lo[idx], nlo)
        hi[idx] = np.fmin(hi[idx], nhi)
    else:
        np.fmax.at(lo, idx, nlo)
        np.fmin.at(hi, idx, nhi)


def _watched(prog: Program) -> np.ndarray:
    """The slots whose contraction decides when to stop: the declared unknowns."""
    s = prog.slots
    idx = [i for i in s.declared if s.kinds[i] in ("param", "var")]
    if not idx:
        idx = [i for i, k in enumerate(s.kinds) if k != "const"]
    return np.array(sorted(set(idx)), dtype=np.int64)


def _contraction(before: tuple, after: tuple) -> float:
    """The largest relative width reduction of one sweep (1 for a bound leaving infinity)."""
    (blo, bhi), (alo, ahi) = before, after
    if len(blo) == 0:
        return 0.0
    moved = (alo != blo) | (ahi != bhi)
    if not np.any(moved):
        return 0.0
    wb, wa = bhi - blo, ahi - alo
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.where(np.isfinite(wb) & (wb > 0), (wb - wa) / wb, np.where(moved, 1.0, 0.0))
    return float(np.nanmax(rel))


def _diagnose(prog: Program, lo: np.ndarray, hi: np.ndarray) -> Emptied:
    """Replay the failing sweep group by group to find the primitive that emptied a domain."""
    from .listing import render_primitive

    order = [(g, _forward) for g in prog.groups] + [(g, _backward) for g in reversed(prog.groups)]
    for g, step in order:
        step(g, lo, hi)
        cols = np.concatenate([g.out, g.args], axis=1)
        bad = lo[cols] > hi[cols]
        if np.any(bad):
            row, col = (int(x[0]) for x in np.nonzero(bad))
            p = prog.primitives[int(g.prim[row])]
            slot = int(cols[row, col])
            return Emptied(prog.slots.names[slot], p.loc, render_primitive(p, prog.slots.names))
    return Emptied("?", None, None)


def _infeasible(box, sweeps: int, start: float, emptied: Emptied) -> Result:
    return Result("infeasible", box[0], box[1], sweeps, time.perf_counter() - start, "empty",
                  emptied)
