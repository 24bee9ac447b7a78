"""A measured column in another unit than the one its table declares: its values spread a
unit's factor (1000: mm and m; 180/pi: deg and rad) more or less than the model's predictions
of them. The rule needs no fit (a column off by 1000 stops least squares from converging), so
it can name the column when the estimate fails (analysis/priors.py) as well as when the data
are proven inconsistent (outliers/unit_hints.py)."""

from __future__ import annotations

import math

import numpy as np

from calib_dsl.analysis.lsq import linearized
from calib_dsl.ir.program import Program

FACTORS = ((1000.0, "1000 (mm and m)"), (180 / math.pi, "57 (deg and rad)"))


def near(ratio: float, within: float) -> str | None:
    """The unit factor `ratio` sits within the factor `within` of (either way; FitSettings'
    unit_near), as a label; None if none."""
    for factor, label in FACTORS:
        for f in (factor, 1 / factor):
            if ratio > 0 and abs(math.log(ratio / f)) <= math.log(within):
                return label
    return None


def by_column(prog: Program, p: np.ndarray) -> dict[str, tuple[np.ndarray, ...]]:
    """Per measured column: its values (the middles of the cells), the model's residuals at
    p (predicted minus measured) and the bounds."""
    s = prog.slots
    sides = s.measured_sides or {}
    lin = linearized(prog, p, owners=False)
    cols: dict[str, list[int]] = {}
    for i, slot in enumerate(lin.slots.tolist()):
        if slot in sides and s.col_keys is not None:
            cols.setdefault(s.col_keys[sides[slot][1]][1], []).append(i)
    out: dict[str, tuple[np.ndarray, ...]] = {}
    for name, rows in cols.items():
        at = lin.slots[rows]
        out[name] = (0.5 * s.lo[at] + 0.5 * s.hi[at], lin.d[rows], lin.half[rows])
    return out


def spreads(prog: Program, p: np.ndarray, within: float) -> list[str]:
    """A line per group of measured columns whose values spread a unit's factor (to within
    the factor `within`) more or less than the model predicts them at p."""
    found: dict[tuple[str, bool], list[tuple[str, float]]] = {}
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        for name, (values, d, _) in by_column(prog, p).items():
            ratio = float(np.std(values) / np.std(values + d))
            label = near(ratio, within) if np.isfinite(ratio) else None
            if label is not None:
                found.setdefault((label, ratio > 1), []).append((name, ratio))
    out = []
    for (label, more), cols in found.items():
        names = ", ".join(n for n, _ in cols)
        r = float(np.median([max(x, 1 / x) for _, x in cols]))
        out.append(f"column{'s' if len(cols) > 1 else ''} {names}: the values spread {r:.3g} "
                   f"times {'more' if more else 'less'} than the model predicts them at the "
                   f"middle of the domains, about {label}: check the unit the table declares")
    return out
