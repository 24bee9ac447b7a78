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
from collections.abc import Callable
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


Step = Callable[[np.ndarray, np.ndarray, np.ndarray, int, "Share | None"], None]


Steps = list[tuple[np.ndarray, Step]]

ALIGN = 64  # (elements: a multiple of any SIMD loop's width, so no share ends mid-vector)


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
               stamp: np.ndarray, k: int, share: Share | None = None) -> None:
    """Sweep number k (1, 2, ...); large steps shared as `share` says."""
    with np.errstate(all="ignore"):
        for part in steps:
            for slots, step in part:
                if k > 1 and stamp[slots].max() < k - 1:
                    continue
                step(lo, hi, stamp, k, share)


def kernels(prog: Program) -> tuple[Steps, Steps]:
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
    n = len(g.out)
    if g.op == "rot":
        cols = [np.ascontiguousarray(c) for c in (*g.args.T, *g.out.T)]
        uniq = (*g.args_unique, *g.out_unique)

        def rot(lo: np.ndarray, hi: np.ndarray, stamp: np.ndarray, k: int,
                share: Share | None) -> None:
            def some(s: slice) -> list[tuple]:
                beta, u, v, u2, v2 = [(lo[c[s]], hi[c[s]]) for c in cols]
                return list(rot_contract_raw(beta, u, v, u2, v2, sweeps=_ROT_SWEEPS))
            new = _shared(share, n, some)
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

    def fw(lo: np.ndarray, hi: np.ndarray, stamp: np.ndarray, k: int,
           share: Share | None) -> None:
        def some(s: slice) -> list[tuple]:
            return [fw_fn([(lo[c[s]], hi[c[s]]) for c in acols],
                          None if param is None else param[s])]
        ((zlo, zhi),) = _shared(share, n, some)
        _write(lo, hi, out, zlo, zhi, out_u, stamp, k)

    def bw(lo: np.ndarray, hi: np.ndarray, stamp: np.ndarray, k: int,
           share: Share | None) -> None:
        def some(s: slice) -> list[tuple]:
            o = out[s]
            return list(bw_fn((lo[o], hi[o]), [(lo[c[s]], hi[c[s]]) for c in acols],
                              None if param is None else param[s]))
        new = _shared(share, n, some)
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
