"""The data rows a fit leaves far beyond their error bound: the candidates for a proof that
a row is at fault (outliers/at_fault.py), and what a solve that decided nothing suggests
(`--outliers K`, strategy/verdict.py's next step)."""

from __future__ import annotations

import numpy as np

from calib_dsl.analysis.lsq import linearized
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.program import Program
from calib_dsl.settings import Settings

Attempts = list[tuple[int, float]]  # data row ids and their residuals in bounds
# what a linearization at a far or non-finite point raises: then no row is named
FIT_FAILURES = (CalError, ValueError, ArithmeticError, np.linalg.LinAlgError, MemoryError)


def far_rows(prog: Program, values: np.ndarray, s: Settings) -> Attempts:
    """The data rows that the parameter vector `values` (a least-squares fit) leaves more
    than verdict_outlier_bounds off, worst first (at most verdict_outlier_rows)."""
    try:
        with np.errstate(all="ignore"):
            lin = linearized(prog, values)
            r = np.abs(lin.d) / np.maximum(lin.half, 1e-300)
    except FIT_FAILURES:
        return []
    worst: dict[int, float] = {}
    for row, x in zip(lin.data_row.tolist(), r.tolist(), strict=True):
        if row >= 0 and np.isfinite(x):
            worst[row] = max(worst.get(row, 0.0), x)
    far = sorted(((k, v) for k, v in worst.items() if v > s.verdict_outlier_bounds),
                 key=lambda kv: -kv[1])
    return far[:s.verdict_outlier_rows]
