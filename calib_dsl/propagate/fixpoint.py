"""The fixed-point propagator: forward-backward sweeps over the flat program.

A sweep evaluates the groups upward (each output intersected with the enclosure of its
primitive's image) and projects them downward (each argument intersected with its optimal
projection). Everything is a numpy call per group; a slot that receives several projections in
one group intersects them all at once (`fmax.at` / `fmin.at`). fmax/fmin ignore NaN, so a NaN
could only ever mean "no contraction", never a lost solution.
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from calib_dsl.arith.projections import BACKWARD, FAST_BACKWARD, FORWARD, backward, forward
from calib_dsl.arith.rotation import rot_contract, rot_contract_raw
from calib_dsl.frontend.diagnostics import Loc
from calib_dsl.ir.program import Group, Program, derived


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
    reused: int = 0  # rounds that reused earlier LPs' multipliers instead (tight strategy)
    # tight strategy: the parameters cut into pieces (not identifiable alone), and each
    # piece's box that holds solutions; the result is their hull
    split: list[str] = field(default_factory=list)
    pieces: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    # tight strategy: certified bounds of the identifiable combinations it solved for
    # (reparametrize.py), as (text, lo, hi)
    combinations: list[tuple[str, float, float]] = field(default_factory=list)


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
    steps = _kernels(prog)
    stamp = np.zeros(len(box[0]), dtype=np.int64)  # the last sweep that moved each slot
    while sweeps < max_sweeps:
        before = (box[0][watch].copy(), box[1][watch].copy())
        saved = (box[0].copy(), box[1].copy())
        sweeps += 1
        _fast_sweep(steps, box[0], box[1], stamp, sweeps)
        if np.any(box[0] > box[1]):
            # The fast sweep equals the general one until a domain first becomes empty; from
            # there only the general one spreads emptiness exactly: replay the sweep with it.
            box[0][:], box[1][:] = saved
            sweep(prog.groups, box[0], box[1])
            if np.any(box[0] > box[1]):
                return _infeasible(box, sweeps, start, _diagnose(prog, *saved))
            stamp[:] = sweeps  # (cannot happen) as if everything moved
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


# -- the fast sweep -----------------------------------------------------------------------
# The general steps above go through projections.forward/backward, which accept empty
# intervals: they check every input for emptiness, intersect each projection with its
# argument and spread an empty projection to all arguments of the primitive. Inside a sweep
# none of that is needed until a domain becomes empty (the box only shrinks, and the writes
# intersect anyway): the fast steps call the raw operations (which never return NaN for
# non-empty inputs) under one errstate. For non-empty inputs they compute the same bounds as
# the general steps, element for element; the first empty domain makes `propagate` replay the
# sweep with the general steps.
#
# A fast step is also skipped when it cannot change anything: when no slot of its group
# (outputs and arguments) moved since the start of the previous sweep. The step then ran in
# the previous sweep on these very values and moved none of them, and it is a deterministic
# function of them: it would move nothing now either. `stamp` holds, per slot, the last sweep
# in which a write moved it.

Step = Callable[[np.ndarray, np.ndarray, np.ndarray, int], None]
Steps = list[tuple[np.ndarray, Step]]
# the general step's rot_contract runs its default number of inner sweeps: so does the fast one
_ROT_SWEEPS = inspect.signature(rot_contract).parameters["sweeps"].default


def _fast_sweep(steps: tuple[Steps, Steps], lo: np.ndarray, hi: np.ndarray,
                stamp: np.ndarray, k: int) -> None:
    """Sweep number k (1, 2, ...)."""
    with np.errstate(all="ignore"):
        for part in steps:
            for slots, step in part:
                if k > 1 and stamp[slots].max() < k - 1:
                    continue
                step(lo, hi, stamp, k)


def _kernels(prog: Program) -> tuple[Steps, Steps]:
    """The fast steps of a program (made once per program: the tight strategy propagates the
    same program several times)."""
    return derived(prog, "kernels", lambda: _make_kernels(prog))


def _make_kernels(prog: Program) -> tuple[Steps, Steps]:
    fw: Steps = []
    bw: Steps = []
    for g in prog.groups:
        slots = np.sort(np.concatenate([g.out.ravel(), g.args.ravel()]))
        slots = slots[np.concatenate([[True], slots[1:] != slots[:-1]])]
        f, b = _group_kernels(g)
        fw.append((slots, f))
        bw.append((slots, b))
    return fw, bw[::-1]


def _group_kernels(g: Group) -> tuple[Step, Step]:
    if g.op == "rot":
        cols = [np.ascontiguousarray(c) for c in (*g.args.T, *g.out.T)]
        uniq = (*g.args_unique, *g.out_unique)

        def rot(lo: np.ndarray, hi: np.ndarray, stamp: np.ndarray, k: int) -> None:
            beta, u, v, u2, v2 = [(lo[c], hi[c]) for c in cols]
            new = rot_contract_raw(beta, u, v, u2, v2, sweeps=_ROT_SWEEPS)
            for c, (nlo, nhi), one in zip(cols, new, uniq, strict=True):
                _write(lo, hi, c, nlo, nhi, one, stamp, k)
        return rot, rot

    out = np.ascontiguousarray(g.out[:, 0])
    out_u = g.out_unique[0]
    acols = [np.ascontiguousarray(c) for c in g.args.T]
    aunique = g.args_unique
    param = g.param
    fw_fn = FORWARD[g.op]
    bw_fn = FAST_BACKWARD.get(g.op, BACKWARD[g.op])

    def fw(lo: np.ndarray, hi: np.ndarray, stamp: np.ndarray, k: int) -> None:
        zlo, zhi = fw_fn([(lo[c], hi[c]) for c in acols], param)
        _write(lo, hi, out, zlo, zhi, out_u, stamp, k)

    def bw(lo: np.ndarray, hi: np.ndarray, stamp: np.ndarray, k: int) -> None:
        new = bw_fn((lo[out], hi[out]), [(lo[c], hi[c]) for c in acols], param)
        for c, (nlo, nhi), u in zip(acols, new, aunique, strict=True):
            _write(lo, hi, c, nlo, nhi, u, stamp, k)
    return fw, bw


def _write(lo: np.ndarray, hi: np.ndarray, idx: np.ndarray, nlo: np.ndarray, nhi: np.ndarray,
           unique: bool, stamp: np.ndarray, k: int) -> None:
    """_tighten, and stamp the slots it moved with sweep k."""
    olo, ohi = lo[idx], hi[idx]
    if unique:
        wlo, whi = np.fmax(olo, nlo), np.fmin(ohi, nhi)
        lo[idx] = wlo
        hi[idx] = whi
    else:
        np.fmax.at(lo, idx, nlo)
        np.fmin.at(hi, idx, nhi)
        wlo, whi = lo[idx], hi[idx]
    moved = (wlo != olo) | (whi != ohi)
    stamp[idx[moved]] = k


def _rotation(g: Group, lo: np.ndarray, hi: np.ndarray) -> None:
    cols = [g.args[:, 0], g.args[:, 1], g.args[:, 2], g.out[:, 0], g.out[:, 1]]
    uniq = [*g.args_unique, *g.out_unique]
    b, u, v, u2, v2 = [(lo[c], hi[c]) for c in cols]
    new = rot_contract(b, u, v, u2, v2)
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
    left_infinity = (np.isinf(blo) & np.isfinite(alo)) | (np.isinf(bhi) & np.isfinite(ahi))
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.where(np.isfinite(wb) & (wb > 0), (wb - wa) / wb,
                       np.where(left_infinity, 1.0, 0.0))
    return float(np.nanmax(rel))


def _diagnose(prog: Program, lo: np.ndarray, hi: np.ndarray) -> Emptied:
    """Replay the failing sweep group by group to find the primitive that emptied a domain."""
    from calib_dsl.compile.listing import render_primitive

    order = [(g, _forward) for g in prog.groups] + [(g, _backward) for g in reversed(prog.groups)]
    known = np.array([k == "const" for k in prog.slots.kinds])
    for g, step in order:
        cols = np.concatenate([g.out, g.args], axis=1)
        before = (lo[cols], hi[cols])  # a step writes only its group's slots
        step(g, lo, hi)
        bad = lo[cols] > hi[cols]
        if np.any(bad):
            unknown = ~known[cols]
            if not np.any(bad & unknown) and step is _forward:
                # `x + y == 3`: the forward step empties the constant 3, which is not what
                # is wrong; the same primitive projected backward empties x or y
                blo, bhi = lo.copy(), hi.copy()
                blo[cols], bhi[cols] = before
                _backward(g, blo, bhi)
                back = blo[cols] > bhi[cols]
                if np.any(back & unknown):
                    bad = back
            # name an unknown rather than a constant when the primitive empties both
            pick = bad & unknown if np.any(bad & unknown) else bad
            row, col = (int(x[0]) for x in np.nonzero(pick))
            p = prog.primitives[int(g.prim[row])]
            slot = int(cols[row, col])
            return Emptied(prog.slots.names[slot], p.loc, render_primitive(p, prog.slots.names))
    return Emptied("?", None, None)


def _infeasible(box, sweeps: int, start: float, emptied: Emptied) -> Result:
    return Result("infeasible", box[0], box[1], sweeps, time.perf_counter() - start, "empty",
                  emptied)
