"""A reference for how tight an enclosure can be: the hull of the model linearized at the
true parameter values (not a guarantee: a yardstick for benchmarks and tests).

The hull is the smallest box holding every parameter vector consistent with the data. Near the
truth the model is linear to within (box width)^2, far below the measurement errors, so the LP
"min/max each parameter subject to the linearized constraints, the search domains, and each
measured value's error within its bound" gives the hull to a few parts in a thousand.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.program import Program
from calib_dsl.lp.hull import HullFailed, linear_hull
from calib_dsl.relax.chunked import evaluation
from calib_dsl.relax.layout import independents
from calib_dsl.relax.linearize import inequalities
from calib_dsl.settings import Settings


def linearized_hull(prog: Program,
                    names: list[str] | None = None) -> dict[str, tuple[float, float]]:
    ind = independents(prog)
    all_names = [prog.slots.names[i] for i in ind]
    truth = []
    for n in all_names:
        t = prog.true_values.get(n)
        if t is None:
            raise CalError(f"the reference hull needs the true value of '{n}'")
        truth.append(t)
    p = np.array(truth, dtype=float)
    lo, hi = prog.slots.lo.copy(), prog.slots.hi.copy()
    lo[ind], hi[ind] = p, p
    ev = evaluation(prog, lo, hi, p)
    rel = inequalities(ev.run(), p, p, p, ev.e, cell_variables=True)
    domains = prog.domains or {}
    box = [domains.get(n, (-np.inf, np.inf)) for n in all_names]
    lo = np.concatenate([[a for a, _ in box], rel.lo[rel.main:]])
    hi = np.concatenate([[b for _, b in box], rel.hi[rel.main:]])
    wanted = [k for k, n in enumerate(all_names) if names is None or n in names]
    try:
        hull = linear_hull(rel.A, rel.b_lo, rel.b, lo, hi, wanted)
    except HullFailed as err:
        raise CalError(f"the reference hull LP failed: {err}") from None
    return {all_names[k]: (float(hull.lo[i]), float(hull.hi[i]))
            for i, k in enumerate(wanted)}


def yardstick(prog: Program, settings: Settings | None = None
              ) -> dict[str, tuple[float, float]]:
    """The linearized hull at the least-squares estimate of the data (for real data, whose
    truth is unknown: what the data hold to first order; not rigorous). Sets the program's
    true values to the estimate (`settings`' fits and sampling: its defaults where None)."""
    from calib_dsl.analysis.lsq import estimate

    st = settings or Settings()
    ind = independents(prog)
    est = estimate(prog, max_evaluations=st.fits.lsq_evaluations, sampling=st.sampling)
    for k, v in zip(ind, est.values, strict=True):
        prog.true_values[prog.slots.names[k]] = float(v)
    return linearized_hull(prog)
