"""Where the propagator proved the model and data inconsistent: the primitive whose
projection emptied a domain, found by replaying the failing sweep group by group.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.compile.listing import render_primitive
from calib_dsl.frontend.diagnostics import Loc
from calib_dsl.ir.program import Program
from calib_dsl.ir.rows import tiled_mask
from calib_dsl.propagate.kernels import backward_step, forward_step


@dataclass
class Emptied:
    """Where propagation proved the model and data inconsistent."""

    variable: str
    loc: Loc | None
    primitive: str | None  # the primitive whose projection emptied it (listing text)


def diagnose(prog: Program, lo: np.ndarray, hi: np.ndarray) -> Emptied:
    """Replay the failing sweep group by group to find the primitive that emptied a domain."""
    order = ([(g, forward_step) for g in prog.groups]
             + [(g, backward_step) for g in reversed(prog.groups)])
    known = tiled_mask(prog.slots.kinds, ("const",))
    for g, step in order:
        cols = np.concatenate([g.out, g.args], axis=1)
        before = (lo[cols], hi[cols])  # a step writes only its group's slots
        step(g, lo, hi)
        bad = lo[cols] > hi[cols]
        if np.any(bad):
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
    return Emptied("?", None, None)
