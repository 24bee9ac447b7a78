"""What the tight strategy did, step by step: the width of each declared unknown after each
step and each round of LPs, with the seconds since the solve began (`calibc plot --kind
history` draws it).

Recording reads the box and copies a few floats per step: it never changes one, so the
solve's results are exactly those it computes without a history.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Step:
    label: str  # "start", a contractor's name, or "LP round 3 (first order)"
    seconds: float  # since the solve began
    widths: np.ndarray  # of the recorded slots, in their order


@dataclass
class History:
    """Widths of the slots `slots` (a program's declared unknowns) as the solve goes.
    Mutable and shared by the contractors of one solve, as their certificates are."""

    slots: np.ndarray
    start: float = field(default_factory=time.perf_counter)
    steps: list[Step] = field(default_factory=list)

    def record(self, label: str, lo: np.ndarray, hi: np.ndarray) -> None:
        with np.errstate(invalid="ignore"):  # inf - inf: an unbounded slot's width is inf
            widths = hi[self.slots] - lo[self.slots]
        self.steps.append(Step(label, time.perf_counter() - self.start, widths))
