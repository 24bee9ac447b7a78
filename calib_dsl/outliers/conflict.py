"""Which priors or data rows make the data inconsistent: the domains with which widened, or the
rows without which, the rest is proven consistent.

The priors come first (prior_faults.py), then the units (unit_hints.py): a wrong domain or
unit makes every row look wrong, and rows are named only when neither is found.

The solve proved the whole data set inconsistent. The rows are ranked by their least-squares
residual (in units of their bounds; a configuration's rows count as one data row), and the
k worst are left out, k = 1, 2, ... up to OutlierSettings.conflict_rows: once a Chebyshev
fit of the rest satisfies every remaining row under interval evaluation (certify_point.py),
the rest is proven consistent. Then every conflicting subset of the data contains one of
the rows left out: they are what is wrong, or what the model does not explain. For more
than one row, each is left in again in turn: where the rest stays unproven, that row is
needed too.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from calib_dsl.analysis.chebyshev import proven_consistent
from calib_dsl.analysis.lsq import estimate, residuals
from calib_dsl.analysis.min_error import Loader, row_owners
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.elaborate.rows import EVERY_ROW, Selection
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program
from calib_dsl.outliers.prior_faults import PriorFault, prior_faults
from calib_dsl.outliers.rows import Row
from calib_dsl.outliers.unit_hints import unit_hints
from calib_dsl.settings import SamplingSettings, Settings
from calib_dsl.settings_analysis import FitSettings


@dataclass(frozen=True)
class DataRow(Row):
    residual: float  # its largest least-squares residual, in error bounds


@dataclass(frozen=True)
class Conflict:
    rows: list[DataRow]  # left out: the rest is proven consistent when `consistent`
    consistent: bool
    needed: bool | None  # each of them needed (the rest with any one back not proven); None
    #                      for one row (removing nothing was refuted by the solve)
    # domains with which widened every row is proven to hold (then no row is named)
    priors: list[PriorFault] = field(default_factory=list)
    units: list[str] = field(default_factory=list)  # columns or bounds whose unit to check


def find_conflict(inputs: Inputs, load: Loader, everything: Settings) -> Conflict | None:
    """The smallest set of worst rows (at most settings.conflict_rows, `settings` the
    outliers' group) without which the data are proven consistent; None when the model has
    no table to name rows of."""
    settings, fits, sampling = everything.outliers, everything.fits, everything.sampling
    model, prog = load(inputs)
    if not model.tables:
        return None
    try:
        priors = prior_faults(prog, settings.prior_widen, fits, sampling)
    except (CalError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        priors = []  # not proven: the rows are looked at
    if priors:
        return Conflict([], True, None, priors)
    try:
        units = unit_hints(model, prog, settings, fits, sampling)
    except (CalError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        units = []
    if units:  # every row looks wrong: naming some would mislead
        return Conflict([], False, None, units=units)
    try:
        ranked = ranked_rows(model, prog, fits, sampling)
    except (CalError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None  # no least-squares ranking here (an empty domain, say): nothing to name
    if not ranked:
        return None
    del prog
    most = settings.conflict_rows
    for k in range(1, min(most, len(ranked) - 1) + 1):
        out = ranked[:k]
        if _consistent_without(inputs, load, out, everything):
            needed = None if k == 1 else not any(
                _consistent_without(inputs, load, [r for r in out if r is not back],
                                    everything)
                for back in out)
            return Conflict(out, True, needed)
    return Conflict(ranked[:most], False, None)


def ranked_rows(model: Model, prog: Program, fits: FitSettings,
                sampling: SamplingSettings) -> list[DataRow]:
    """The data rows by their largest least-squares residual (in bounds), largest first."""
    tables = {t.name: t for t in model.tables}
    rows = []
    for (table, k), r in _ranked(prog, fits, sampling):
        t = tables.get(table)
        if t is not None and k - 1 < len(t.numbers):
            rows.append(DataRow(table, t.path, t.lines[k - 1], t.numbers[k - 1], r))
    return rows


def ranked_ids(prog: Program, fits: FitSettings,
               sampling: SamplingSettings) -> list[tuple[int, float]]:
    """ranked_rows as data row ids (`Slots.row_keys`) and residuals."""
    ids = {key: i for i, key in enumerate(prog.slots.row_keys or [])}
    return [(ids[key], r) for key, r in _ranked(prog, fits, sampling) if key in ids]


def _ranked(prog: Program, fits: FitSettings,
            sampling: SamplingSettings) -> list[tuple[tuple[str, int], float]]:
    """Each data row's key (table, k) and largest least-squares residual, largest first."""
    est = estimate(prog, max_evaluations=fits.lsq_evaluations, sampling=sampling)
    d, _ = residuals(prog, est.values)
    worst: dict[tuple[str, int], float] = {}
    for key, r in zip(row_owners(prog), np.abs(d).tolist(), strict=False):
        if key is not None:
            worst[key] = max(worst.get(key, 0.0), r)
    return sorted(worst.items(), key=lambda kv: -kv[1])


def _consistent_without(inputs: Inputs, load: Loader, out: list[DataRow],
                        settings: Settings) -> bool:
    """Whether the data less the rows `out` are proven consistent (by a certified point)."""
    rows = dict(inputs.rows)
    for r in out:
        sel = rows.get(r.table, EVERY_ROW)
        rows[r.table] = Selection(sel.ranges, tuple(sorted({*sel.excluded, r.row})))
    try:
        _, prog = load(replace(inputs, rows=rows))
        return proven_consistent(prog, settings.fits, settings.sampling)
    except (CalError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return False  # not proven

