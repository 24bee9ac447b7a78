"""Units to check, for data proven inconsistent: a column or an error bound off by a unit's
factor makes every row look wrong, and the rows are not what to blame.

Each rule measures a ratio and names a column when the ratio sits within a factor
(FitSettings.unit_near) of a unit factor (1000: mm and m; 180/pi: deg and rad):
- a measured column's values spread that many times more or less than the model's
  predictions of them at the middle of the search domains (the file's unit is not the one
  declared);
- least squares leaves most of a measured column's residuals (OutlierSettings.unit_quantile)
  within that many times its error bound, by a fit that gross rows do not pull, and most
  rows beyond it (the bound is in another unit than the model's);
- a joint reading column declared `in deg` whose values all lie within one 180/pi-th of a
  half turn (radians declared as degrees), or declared `in rad` with values beyond
  OutlierSettings.unit_turns turns either way (degrees declared as radians);
- and least squares that does not converge from the middle of the domains is said too.
"""

from __future__ import annotations

import math

import numpy as np

from calib_dsl.analysis.lsq import estimate, residuals
from calib_dsl.analysis.unit_spreads import by_column, near, spreads
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents
from calib_dsl.settings import OutlierSettings, SamplingSettings
from calib_dsl.settings_analysis import FitSettings


def unit_hints(model: Model, prog: Program, settings: OutlierSettings,
               fits: FitSettings, sampling: SamplingSettings) -> list[str]:
    """A line per column (or bound) whose unit to check; empty when no ratio points at one."""
    s = prog.slots
    ind = independents(prog)
    lo, hi = s.lo[ind], s.hi[ind]
    middle = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), np.clip(0.0, lo, hi))
    out = (spreads(prog, middle, fits.unit_near) + _readings(model, prog)
           + _turns(model, prog, settings.unit_turns))
    est = estimate(prog, start=middle, max_evaluations=fits.lsq_evaluations, sampling=sampling)
    if not est.converged:
        out.append("least squares did not converge from the middle of the search domains: "
                   "check the units of the table's columns (`in mm`, `in deg`) and of the "
                   "error bounds")
    elif np.all(np.isfinite(est.values)):
        out += _bounds(prog, _robust(prog, est.values, settings.unit_evaluations), settings,
                       fits.unit_near)
    return out


def _robust(prog: Program, start: np.ndarray, evaluations: int) -> np.ndarray:
    """A fit that gross rows do not pull: least squares with a soft L1 loss past one bound
    (least squares spreads one gross row's error over every row, and most residuals would
    be large for it alone)."""
    from scipy.optimize import least_squares

    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    with np.errstate(invalid="ignore", over="ignore"):
        sol = least_squares(lambda p: residuals(prog, p)[0], np.clip(start, lo, hi),
                            jac=lambda p: residuals(prog, p)[1], bounds=(lo, hi), method="trf",
                            x_scale="jac", loss="soft_l1", f_scale=1.0,
                            max_nfev=evaluations)
    return np.asarray(sol.x) if np.all(np.isfinite(sol.x)) else start


def _bounds(prog: Program, p: np.ndarray, settings: OutlierSettings,
            within: float) -> list[str]:
    found: dict[str, list[tuple[str, float]]] = {}
    columns = by_column(prog, p)
    over = [np.abs(d) > half for _, d, half in columns.values()]
    if not over or np.mean(np.concatenate(over)) < settings.unit_most:
        return []  # most rows hold: a few gross ones, not a unit
    for name, (_, d, half) in columns.items():
        ok = half > 0
        if not ok.any():
            continue
        ratio = float(np.quantile(np.abs(d[ok]) / half[ok], settings.unit_quantile))
        label = near(ratio, within) if ratio > 1 else None
        if label is not None:
            found.setdefault(label, []).append((name, ratio))
    out = []
    for label, cols in found.items():
        r = float(np.median([x for _, x in cols]))
        out.append(f"column{'s' if len(cols) > 1 else ''} {', '.join(n for n, _ in cols)}: "
                   f"least squares leaves {settings.unit_quantile:.0%} of the residuals "
                   f"within {r:.3g} "
                   f"times the error bound, about {label}: check that the bound is in the "
                   "model's units (a -D value, a const)")
    return out


def _readings(model: Model, prog: Program) -> list[str]:
    """Columns declared `in deg` that are not measured sides (joint readings) whose values
    all lie within a 180/pi-th of a half turn: radians declared as degrees."""
    s = prog.slots
    measured = {s.col_keys[c] for _, c in (s.measured_sides or {}).values()} \
        if s.col_keys is not None else set()
    cols, top = [], 0.0
    for t in model.tables:
        for c in t.columns:
            if c.unit != "deg" or c.name not in t.bounds or (t.name, c.name) in measured:
                continue
            lo, hi = t.bounds[c.name]
            most = float(np.max(np.maximum(np.abs(lo), np.abs(hi)))) if len(lo) else 0.0
            if 0 < most <= math.pi / (180 / math.pi):
                cols.append(c.name)
                top = max(top, most)
    out = []
    if cols:
        out.append(f"column{'s' if len(cols) > 1 else ''} {', '.join(cols)}: declared `in deg`"
                   f", but every value is within {math.degrees(top):.3g} in the file "
                   f"({top:.3g} rad): are they radians?")
    return out


def _turns(model: Model, prog: Program, turns: int) -> list[str]:
    """Columns declared `in rad` that are not measured sides (joint readings) with a value
    beyond `turns` turns either way: degrees declared as radians."""
    s = prog.slots
    measured = {s.col_keys[c] for _, c in (s.measured_sides or {}).values()} \
        if s.col_keys is not None else set()
    found = []
    for t in model.tables:
        for c in t.columns:
            if c.unit != "rad" or c.name not in t.bounds or (t.name, c.name) in measured:
                continue
            lo, hi = t.bounds[c.name]
            most = float(np.max(np.maximum(np.abs(lo), np.abs(hi)))) / c.factor[0] \
                if len(lo) else 0.0
            if most > turns * 2 * math.pi:
                found.append(f"{c.name} (up to {most:.4g})")
    if not found:
        return []
    return [f"column{'s' if len(found) > 1 else ''} {', '.join(found)}: declared `in rad`, "
            f"but a joint does not turn {turns} turns ({turns * 360} deg) either way: are "
            "they degrees?"]
