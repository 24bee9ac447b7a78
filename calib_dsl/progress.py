"""Progress of long work, for whoever shows it (the command line's one updating line).

A `Progress` is a plain callable, called now and then with
- a label: the stage or round just done ("start", "propagation", "LP round 3", ...);
- the total width of the unknowns after it (the sum over the declared unknowns of the box's
  widths: it never grows during one solve, and may be infinite); None where there is no box
  (simulation);
- the seconds since the work began.
It only observes: nothing it does changes a result. Where no one watches, it is None and the
work pays one `is None` test per stage.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

Progress = Callable[[str, float | None, float], None]


@dataclass(frozen=True)
class Meter:
    """A box's total width over `slots`, reported to `report` with the time since `start`."""

    report: Progress
    slots: np.ndarray
    start: float = field(default_factory=time.perf_counter)

    def __call__(self, label: str, lo: np.ndarray, hi: np.ndarray) -> None:
        lo, hi = lo[self.slots], hi[self.slots]
        if np.any(lo > hi):
            return  # an empty box: the work stops here and says so itself
        self.report(label, float(np.sum(hi - lo)), time.perf_counter() - self.start)


def labelled(progress: Progress | None, prefix: str) -> Progress | None:
    """`progress` with `prefix` before every label (one solve among several), or None."""
    if progress is None:
        return None
    report = progress
    return lambda label, width, seconds: report(prefix + label, width, seconds)
