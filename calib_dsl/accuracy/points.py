"""The solve's accuracy statement at its three points: before calibration (the nominal
point), the least-squares point and the certified centre, with the bounds over the result
box."""

from __future__ import annotations

from typing import Any

import numpy as np

from calib_dsl.accuracy.fit import Seen, polish
from calib_dsl.accuracy.statement import Accuracy, accuracy, nominal_point
from calib_dsl.analysis.lsq import Estimate
from calib_dsl.analysis.residuals import residual_ranges
from calib_dsl.inner.bounds import Inner, Witness
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents
from calib_dsl.settings import Settings


def solve_statement(prog: Program, lo: np.ndarray, hi: np.ndarray, lsq: Any,
                    inner: Inner | None, angles: frozenset[str],
                    settings: Settings, fit: Estimate | None = None) -> Accuracy:
    """The accuracy over the result box [lo, hi] (the program's slots) at the nominal point,
    the least-squares point (`lsq`, an Estimate the solve was asked for, else polished here
    from `fit`, the least-squares estimate the load made of this program with its rows, or
    from the certified centre or the box's middle) and the certified centre."""
    ind = independents(prog)
    points = {"nominal": nominal_point(prog)}
    centre = certified_centre(inner)
    seen: Seen = {}  # (the polish's rows at its start, the centre, and at its result)
    if lsq is None:
        mid = 0.5 * (lo[ind] + hi[ind])
        start, rows = (centre if centre is not None else mid), None
        if fit is not None and fit.rows is not None and np.all(np.isfinite(fit.values)):
            start, rows = fit.values, fit.rows
        if np.all(np.isfinite(start)):
            lsq = polish(prog, start, settings, seen, rows)
    if lsq is not None and np.all(np.isfinite(lsq.values)):
        points["least_squares"] = lsq.values
    if centre is not None:
        points["certified"] = centre
    box = {prog.slots.names[k]: (float(lo[k]), float(hi[k])) for k in ind}
    return accuracy(prog, residual_ranges(prog, box), points, angles, seen)


def certified_centre(inner: Inner | None) -> np.ndarray | None:
    """The point of centre_witness (None: no certified point)."""
    w = centre_witness(inner)
    return None if w is None else w.point


def centre_witness(inner: Inner | None) -> Witness | None:
    """The certified centre (inner/bounds.py `Inner.centre`: the certified point nearest the
    middle of the inner intervals), the one point the JSON, the exports and the statement
    share; None where none was certified."""
    return None if inner is None else inner.centre
