"""Where the propagator proved the model and data inconsistent: the primitive whose
projection emptied a domain, found by running the failing sweep on in the general steps,
group by group.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from calib_dsl.compile.listing import render_primitive
from calib_dsl.frontend.diagnostics import Loc
from calib_dsl.ir.program import Group, Program
from calib_dsl.ir.rows import tiled_mask
from calib_dsl.propagate.kernels import backward_step, forward_step


@dataclass
class Emptied:
    """Where propagation proved the model and data inconsistent."""

    variable: str
    loc: Loc | None
    primitive: str | None  # the primitive whose projection emptied it (listing text)


def sweep_from(prog: Program, lo: np.ndarray, hi: np.ndarray, at: int) -> Emptied | None:
    """The rest of a sweep in the general steps, from its step number `at` on (the forward
    steps in the groups' order, then the backward ones), on lo, hi in place: where a step
    empties a domain, which one and the primitive (the first such step), else None. The
    whole sweep is run either way: the box after it is the general sweep's."""
    order = ([(g, forward_step) for g in prog.groups]
             + [(g, backward_step) for g in reversed(prog.groups)])
    found = None
    for g, step in order[at:]:
        if found is not None:
            step(g, lo, hi)
            continue
        cols = np.concatenate([g.out, g.args], axis=1)
        before = (lo[cols], hi[cols])  # a step writes only its group's slots
        step(g, lo, hi)
        bad = lo[cols] > hi[cols]
        if np.any(bad):
            found = _emptied(prog, g, step, lo, hi, cols, before, bad)
    return found


def _emptied(prog: Program, g: Group, step: Callable, lo: np.ndarray, hi: np.ndarray,
             cols: np.ndarray, before: tuple[np.ndarray, np.ndarray], bad: np.ndarray
             ) -> Emptied:
    """What the step of group g that emptied the domains `bad` (of `cols`) names."""
    known = tiled_mask(prog.slots.kinds, ("const",))
    unknown = ~known[cols]
    if not np.any(bad & unknown) and step is forward_step:
        # `x + y == 3`: the forward step empties the constant 3, which is not what
        # is wrong; the same primitive projected backward empties x or y
        blo, bhi = lo.copy(), hi.copy()
        blo[cols], bhi[cols] = before
        backward_step(g, blo, bhi)
        back = blo[cols] > bhi[cols]
        if np.any(back & unknown):
            bad = back
    # name an unknown rather than a constant when the primitive empties both
    pick = bad & unknown if np.any(bad & unknown) else bad
    row, col = (int(x[0]) for x in np.nonzero(pick))
    p = prog.primitives[int(g.prim[row])]
    slot = int(cols[row, col])
    return Emptied(prog.slots.names[slot], p.loc, render_primitive(p, prog.slots.names))
