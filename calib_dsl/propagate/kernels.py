"""One sweep of the propagator over the flat program, group by group: the general steps,
which accept empty intervals, and the fast steps used until a domain becomes empty.

A fast step of a large group (a loop's rows: thousands of entries) may be shared among
threads (`Share`, numpy's array work runs outside the GIL): each thread reads its own entries'
arguments off the box and computes their new bounds, and only once all are done are they
written, in one thread, as one step writes them. Every function of a step is element for
element (arith/: each entry's result depends on its own arguments, and on the arrays' size
only across `ROUNDING_SIZE`: dn1/up1 round small arrays by nextafter, large ones by two
operations, so every share of a step is larger than that, as the whole is), and the shares
start at multiples of `ALIGN` entries, so each element is computed by the same vector loop
in the same position as in the whole arrays: the box after the step is the same, bit for bit.
"""

from __future__ import annotations

import inspect
import itertools
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from calib_dsl.arith.interval import ROUNDING_SIZE
from calib_dsl.arith.projections import BACKWARD, FAST_BACKWARD, FORWARD, backward, forward
from calib_dsl.arith.rotation import rot_contract, rot_contract_raw
from calib_dsl.ir.program import Group, Program, derived


def sweep(groups: list[Group], lo: np.ndarray, hi: np.ndarray) -> None:
    for g in groups:
        forward_step(g, lo, hi)
    for g in reversed(groups):
        backward_step(g, lo, hi)


def forward_step(g: Group, lo: np.ndarray, hi: np.ndarray) -> None:
    if g.op == "rot":
        _rotation(g, lo, hi)
        return
    args = [(lo[c], hi[c]) for c in g.args.T]
    zlo, zhi = forward(g.op, args, g.param)
    _tighten(lo, hi, g.out[:, 0], zlo, zhi, g.out_unique[0])


def backward_step(g: Group, lo: np.ndarray, hi: np.ndarray) -> None:
    if g.op == "rot":
        _rotation(g, lo, hi)
        return
    out = g.out[:, 0]
    args = [(lo[c], hi[c]) for c in g.args.T]
    new = backward(g.op, (lo[out], hi[out]), args, g.param)
    for c, (alo, ahi), unique in zip(g.args.T, new, g.args_unique, strict=True):
        _tighten(lo, hi, c, alo, ahi, unique)


# A fast step: (lo, hi, stamp, share) -> whether it would have emptied a domain (its writes
# then undone).
Step = Callable[[np.ndarray, np.ndarray, np.ndarray, "Share | None"], bool]


Steps = list[tuple[tuple[np.ndarray, ...], Step]]  # each with its group's columns of slots

ALIGN = 64  # (elements: a multiple of any SIMD loop's width, so no share ends mid-vector)

# A slot's stamp (one byte): MOVED where a step moved it in this sweep, 1 where it moved in
# the sweep before and not since (fast_sweep halves every stamp as a sweep begins).
MOVED = 2


@dataclass(frozen=True)
class Share:
    """How a large step's entries are shared: `run(fn, parts)` is [fn(p) for p in parts]
    in `threads` threads (relax/chunked.in_threads), for a step of at least `least` entries
    per thread."""

    run: Callable[[Callable[[slice], Any], list[slice]], list[Any]]
    threads: int
    least: int

    def parts(self, n: int) -> list[slice] | None:
        """The entries' shares (slices), or None to run the step whole."""
        count = min(self.threads, n // max(self.least, 1))
        if count <= 1:
            return None
        ends = sorted({0, n, *((n * k // count) // ALIGN * ALIGN for k in range(1, count))})
        # (each share above the size where arith/interval rounds outward by another rule)
        if len(ends) <= 2 or min(b - a for a, b in itertools.pairwise(ends)) <= ROUNDING_SIZE:
            return None
        return [slice(a, b) for a, b in itertools.pairwise(ends)]


def _shared(share: Share | None, n: int, fn: Callable[[slice], list[tuple]]) -> list[tuple]:
    """fn(all entries) (a list of (lo, hi) pairs), computed in shares where `share` says, the
    shares' arrays joined in their order."""
    parts = share.parts(n) if share is not None else None
    if parts is None:
        return fn(slice(None))
    done = share.run(fn, parts)  # type: ignore[union-attr]
    return [(np.concatenate([d[j][0] for d in done]), np.concatenate([d[j][1] for d in done]))
            for j in range(len(done[0]))]


# the general step's rot_contract runs its default number of inner sweeps: so does the fast one
_ROT_SWEEPS = inspect.signature(rot_contract).parameters["sweeps"].default


def fast_sweep(steps: tuple[Steps, Steps], lo: np.ndarray, hi: np.ndarray,
               stamp: np.ndarray, k: int, share: Share | None = None) -> int | None:
    """Sweep number k (1, 2, ...), large steps shared as `share` says; a step none of whose
    slots moved in this sweep or the one before is skipped (it would move nothing). The fast
    steps equal the general ones until a domain first becomes empty: a step that would empty
    one is undone and the sweep stops before it, its position returned (the forward steps
    in the groups' order, then the backward ones: diagnose.sweep_from goes on from there)."""
    with np.errstate(all="ignore"):
        if k > 1:
            np.right_shift(stamp, 1, out=stamp)
        at = 0
        for part in steps:
            for cols, step in part:
                if (k == 1 or _moved(stamp, cols)) and step(lo, hi, stamp, share):
                    return at
                at += 1
    return None


def _moved(stamp: np.ndarray, cols: tuple[np.ndarray, ...]) -> bool:
    return any(stamp[c].any() for c in cols)


def kernels(prog: Program) -> tuple[Steps, Steps]:
    """The fast steps of a program (made once per program: the tight strategy propagates the
    same program several times)."""
    return derived(prog, "kernels", lambda: _make_kernels(prog))


def _make_kernels(prog: Program) -> tuple[Steps, Steps]:
    fw: Steps = []
    bw: Steps = []
    for g in prog.groups:
        # (the group's own columns, views: a large program's index arrays are held once)
        cols = (*g.out.T, *g.args.T)
        f, b = _group_kernels(g)
        fw.append((cols, f))
        bw.append((cols, b))
    return fw, bw[::-1]


def _group_kernels(g: Group) -> tuple[Step, Step]:
    n = len(g.out)
    if g.op == "rot":
        cols = [*g.args.T, *g.out.T]
        uniq = (*g.args_unique, *g.out_unique)

        def rot(lo: np.ndarray, hi: np.ndarray, stamp: np.ndarray,
                share: Share | None) -> bool:
            def some(s: slice) -> list[tuple]:
                beta, u, v, u2, v2 = [(lo[c[s]], hi[c[s]]) for c in cols]
                return list(rot_contract_raw(beta, u, v, u2, v2, sweeps=_ROT_SWEEPS))
            new = _shared(share, n, some)
            return _write_all(lo, hi, stamp, zip(cols, new, uniq, strict=True))
        return rot, rot

    out = g.out[:, 0]
    out_u = g.out_unique[0]
    acols = list(g.args.T)
    aunique = g.args_unique
    param = g.param
    fw_fn = FORWARD[g.op]
    bw_fn = FAST_BACKWARD.get(g.op, BACKWARD[g.op])

    def fw(lo: np.ndarray, hi: np.ndarray, stamp: np.ndarray, share: Share | None) -> bool:
        def some(s: slice) -> list[tuple]:
            return [fw_fn([(lo[c[s]], hi[c[s]]) for c in acols],
                          None if param is None else param[s])]
        new = _shared(share, n, some)
        return _write_all(lo, hi, stamp, zip([out], new, [out_u], strict=True))

    def bw(lo: np.ndarray, hi: np.ndarray, stamp: np.ndarray, share: Share | None) -> bool:
        def some(s: slice) -> list[tuple]:
            o = out[s]
            return list(bw_fn((lo[o], hi[o]), [(lo[c[s]], hi[c[s]]) for c in acols],
                              None if param is None else param[s]))
        new = _shared(share, n, some)
        return _write_all(lo, hi, stamp, zip(acols, new, aunique, strict=True))
    return fw, bw


def _write_all(lo: np.ndarray, hi: np.ndarray, stamp: np.ndarray,
               writes: Iterable[tuple[np.ndarray, tuple[np.ndarray, np.ndarray], bool]]
               ) -> bool:
    """Each (slots, (new lo, new hi), unique) of one step written as _tighten writes it, the
    slots it moved stamped; where that empties a domain, every write undone (last first: the
    box as before the step) and True."""
    undo = []
    for idx, (nlo, nhi), unique in writes:
        olo, ohi = lo[idx], hi[idx]
        undo.append((idx, olo, ohi))
        if unique:
            wlo, whi = np.fmax(olo, nlo), np.fmin(ohi, nhi)
            lo[idx] = wlo
            hi[idx] = whi
        else:
            np.fmax.at(lo, idx, nlo)
            np.fmin.at(hi, idx, nhi)
            wlo, whi = lo[idx], hi[idx]
        if np.any(wlo > whi):
            for c, clo, chi in reversed(undo):
                lo[c], hi[c] = clo, chi
            return True
        moved = (wlo != olo) | (whi != ohi)
        stamp[idx[moved]] = MOVED
    return False


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
