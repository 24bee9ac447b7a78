"""Progress of long work, for whoever shows it (the command line's one updating line).

A `Progress` is a plain callable, called now and then with
- a label: the stage or round just done ("start", "propagation", "LP round 3", ...);
- how wide the unknowns are after it: the mean over the declared unknowns of the box's width
  as a fraction of the unknown's search domain (unit-free: a sum of widths would add
  millimetres to radians; it never grows during one solve; an unbounded domain counts from
  the first finite width the box reaches); None where there is no box (simulation) or no
  unknown counts;
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


@dataclass
class Meter:
    """A box's widths over `slots`, each as a fraction of a reference width, reported to
    `report` as their mean with the time since `start`. The reference is the unknown's search
    domain; for an unbounded domain, the first finite width the box reaches (until then the
    unknown counts as 1, so the mean never grows); unknowns with a point domain are left out."""

    report: Progress
    slots: np.ndarray
    reference: np.ndarray
    start: float = field(default_factory=time.perf_counter)

    @classmethod
    def over(cls, report: Progress, slots: np.ndarray, lo: np.ndarray, hi: np.ndarray,
             start: float | None = None) -> Meter:
        """A meter of `slots` relative to their widths in the box (lo, hi): the domains."""
        w = hi[slots] - lo[slots]
        keep = w > 0
        return cls(report, slots[keep], w[keep].copy(),
                   time.perf_counter() if start is None else start)

    def __call__(self, label: str, lo: np.ndarray, hi: np.ndarray) -> None:
        lo, hi = lo[self.slots], hi[self.slots]
        if np.any(lo > hi):
            return  # an empty box: the work stops here and says so itself
        w = hi - lo
        first = np.isinf(self.reference) & np.isfinite(w) & (w > 0)
        self.reference[first] = w[first]
        bounded = np.isfinite(self.reference)
        frac = np.where(bounded, w / np.where(bounded, self.reference, 1.0),
                        np.where(np.isfinite(w), 0.0, 1.0))
        share = float(np.mean(frac)) if frac.size else None
        self.report(label, share, time.perf_counter() - self.start)


def labelled(progress: Progress | None, prefix: str) -> Progress | None:
    """`progress` with `prefix` before every label (one solve among several), or None."""
    if progress is None:
        return None
    report = progress
    return lambda label, width, seconds: report(prefix + label, width, seconds)
