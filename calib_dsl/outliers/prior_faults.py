"""The priors at fault: for data proven inconsistent, whether they are consistent once some
search domains are widened, and which.

A domain is a prior, a statement the user made about where a parameter is; when it is wrong,
every row looks wrong, and blaming rows would have the user delete good data. So before any
row is blamed, the fits run again with every finite domain widened about its middle
(OutlierSettings.prior_widen times its half-width): least squares, then the Chebyshev fit
in units of the rows' bounds. The parameters that fit leaves outside their declared
domains are the suspects; the fit runs once more with only theirs widened, and when its
point is certified (certify_point.py: every row holds under interval evaluation at it) the
data are proven consistent with those priors widened: they are named, with the value the
data want and the end of the domain it passes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.analysis.certify_point import check_point
from calib_dsl.analysis.chebyshev import chebyshev, with_readings
from calib_dsl.analysis.lsq import estimate
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents
from calib_dsl.settings import SamplingSettings
from calib_dsl.settings_analysis import FitSettings


@dataclass(frozen=True)
class PriorFault:
    name: str
    wanted: float  # where the certified point has it
    end: float  # the end of its declared domain it lies beyond
    lo: float
    hi: float  # its declared domain

    def text(self) -> str:
        side = "ends" if self.wanted > self.end else "starts"
        return (f"{self.name}: the data want {self.wanted:+.4g}, its domain {side} at "
                f"{self.end:+.4g} ([{self.lo:.6g}, {self.hi:.6g}], in the model's units)")


def prior_faults(prog: Program, widen: float, fits: FitSettings | None = None,
                 sampling: SamplingSettings | None = None) -> list[PriorFault]:
    """The declared domains a certified point needs widened (widest miss first); empty when
    widening them does not prove the data consistent. `prog` is the caller's to change: its
    domains are restored before the return. `widen`: the widened domains' half-widths,
    in declared half-widths; `fits`: the fits' settings; `sampling`: least squares'."""
    fits = fits or FitSettings()
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind].copy(), prog.slots.hi[ind].copy()
    finite = np.isfinite(lo) & np.isfinite(hi) & (hi > lo)
    if not finite.any():
        return []
    try:
        point = _fit(prog, ind, (lo, hi), finite, widen, (fits, sampling))
        if point is None:
            return []
        out = finite & ((point < lo) | (point > hi))
        if not out.any():
            return []
        point = _fit(prog, ind, (lo, hi), out, widen, (fits, sampling))
        if point is None:
            return []
    finally:
        prog.slots.lo[ind], prog.slots.hi[ind] = lo, hi
    names = [prog.slots.names[i] for i in ind]
    miss = np.where(point > hi, point - hi, lo - point) / np.maximum(0.5 * (hi - lo), 1e-300)
    found = [PriorFault(names[j], float(point[j]), float(hi[j] if point[j] > hi[j] else lo[j]),
                        float(lo[j]), float(hi[j]))
             for j in np.flatnonzero((point < lo) | (point > hi))]
    return sorted(found, key=lambda f: -miss[names.index(f.name)])


def _fit(prog: Program, ind: np.ndarray, box: tuple[np.ndarray, np.ndarray],
         widen: np.ndarray, factor: float,
         settings: tuple[FitSettings, SamplingSettings | None]) -> np.ndarray | None:
    """A point certified on the program with the `widen` domains widened `factor` times,
    else None."""
    fits, sampling = settings
    lo, hi = box
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    prog.slots.lo[ind] = np.where(widen, mid - factor * half, lo)
    prog.slots.hi[ind] = np.where(widen, mid + factor * half, hi)
    start = estimate(prog, start=np.where(np.isfinite(mid), mid, 0.0),
                     max_evaluations=fits.lsq_evaluations, sampling=sampling)
    if not np.all(np.isfinite(start.values)):
        return None
    point, need = chebyshev(prog, normalized=True, start=start.values, fits=fits)
    if need <= 1.0 and check_point(prog, point).holds:
        return point
    step = with_readings(prog, point)
    if step is not None and check_point(prog, step[0], step[1]).holds:
        return step[0]
    return None
