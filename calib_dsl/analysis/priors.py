"""Search domains centred on the data at hand: `param x in lsq +- w` (or `lsq(start) +- w`).

A robot measured by a laser tracker stands somewhere else in every campaign, metres apart, so
no fixed domain fits the tracker-to-base transform of every data set. Such a parameter's
domain is centred on a least-squares estimate of the data being solved: [estimate - w,
estimate + w]. That domain is a *prior*, a statement about where the parameter is, which the
report states as such; the enclosures are guaranteed within it, like within any other domain.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.analysis.lsq import Estimate, estimate
from calib_dsl.analysis.unit_spreads import spreads
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents
from calib_dsl.settings import SamplingSettings
from calib_dsl.settings_analysis import FitSettings


def centre_on_least_squares(prog: Program, fits: FitSettings | None = None,
                            sampling: SamplingSettings | None = None) -> Estimate | None:
    """Give each `lsq +- w` parameter its domain around the least-squares estimate (in place:
    the program's slots and declared domains); the other parameters keep theirs and bound
    the estimate (at most `fits`' prior_evaluations evaluations of the residuals; least
    squares' sample of rows: `sampling`'s). The estimate, converged (None: no `lsq +- w`
    parameter): the least-squares point of the program on its new domains too, as they
    hold it and the others are unchanged."""
    f = fits or FitSettings()
    if not prog.priors:
        return None
    ind = independents(prog)
    names = [prog.slots.names[i] for i in ind]
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    with np.errstate(invalid="ignore"):  # (the middle of an unbounded domain is not used)
        start = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi),
                         np.clip(0.0, lo, hi))
    for name, (s, _) in prog.priors.items():
        start[names.index(name)] = s
    est = estimate(prog, start=start, max_evaluations=f.prior_evaluations, sampling=sampling)
    values = dict(zip(names, est.values.tolist(), strict=True))
    bad = [n for n in prog.priors if not np.isfinite(values[n])]
    if bad or not est.converged:
        # a column off by a unit's factor, named if one is
        units = spreads(prog, start, f.unit_near)
        raise CalError("the least-squares estimate that centres the lsq domains ("
                       f"{', '.join(prog.priors)}) did not converge: "
                       + ("; ".join(units) if units else
                          "give a start nearer the solution, as lsq(start) +- w, or check "
                          "the units the table declares (a position in m where the file has "
                          "mm, joints in deg where it has rad)"))
    for name, (_, w) in prog.priors.items():
        v = values[name]
        slot = prog.slots.names.index(name)
        prog.slots.lo[slot], prog.slots.hi[slot] = v - w, v + w
        if prog.domains is not None:
            prog.domains[name] = (v - w, v + w)
        prog.centred[name] = (v, w)
    return est
