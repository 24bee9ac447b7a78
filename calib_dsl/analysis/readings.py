"""The joint readings as unknowns of a linear model: each reading's error within its interval
(in units of its half-width) enters the rows of its configuration through their derivatives.
A point proof (certify_point.py) may then give each reading its own value."""

from __future__ import annotations

import numpy as np

from calib_dsl.analysis.certify_point import exact_inside, reading_slots
from calib_dsl.analysis.lsq import Linearized
from calib_dsl.ir.program import Program


class Readings:
    """The joint readings as LP columns: each one's error within its interval, in units of its
    half-width, entering the rows of its configuration through their derivatives."""

    def __init__(self, prog: Program) -> None:
        s = prog.slots
        self.at = reading_slots(prog)
        lo, hi = s.lo[self.at], s.hi[self.at]
        self.mid = 0.5 * lo + 0.5 * hi
        a, b = exact_inside(lo, hi)
        none = a > b  # no float inside (a few ulps wide): the check keeps its enclosure
        self.inside = (np.where(none, self.mid, a), np.where(none, self.mid, b))
        self.half = np.where(none, 1e-300, np.maximum(0.5 * (hi - lo), 1e-300))
        self.ncol, self.keys = 1, np.zeros(0, dtype=np.int64)
        if len(self.at) and s.cell_row is not None and s.cell_col is not None:
            self.ncol = int(s.cell_col.max()) + 1
            self.keys = s.cell_row[self.at] * self.ncol + s.cell_col[self.at]
        self.order = np.argsort(self.keys)

    def entries(self, lin: Linearized) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(row, column, value) of the rows' derivatives in the readings, scaled."""
        if not len(self.at) or lin.dq.shape[1] == 0:
            return (np.zeros(0, np.int64),) * 2 + (np.zeros(0),)
        rows, cols = np.nonzero((lin.dq != 0) & (lin.owner >= 0)[:, None])
        keys = lin.owner[rows] * self.ncol + cols
        pos = np.searchsorted(self.keys, keys, sorter=self.order)
        pos = np.minimum(pos, len(self.keys) - 1)
        var = self.order[pos]
        hit = self.keys[var] == keys  # a derivative in a compared value: not a reading
        rows, cols, var = rows[hit], cols[hit], var[hit]
        return rows, var, lin.dq[rows, cols] * self.half[var]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return (self.inside[0] - self.mid) / self.half, (self.inside[1] - self.mid) / self.half

    def by_cell(self, values: np.ndarray) -> dict[int, float]:
        """The readings' values by cell (a key that another load of the same model and data
        gives the same reading: its slots may be numbered otherwise)."""
        return dict(zip(self.keys.tolist(), values.tolist(), strict=True))

    def middles(self) -> np.ndarray:
        """Each reading at the middle of its interval (kept inside its exact one)."""
        return np.clip(self.mid, *self.inside)

    def from_cells(self, values: dict[int, float]) -> np.ndarray:
        """`by_cell`'s values in this program's order (the middle where a cell has none),
        each kept inside this program's interval: another program's (the same data at another
        error bound, --min-error's trials) may not hold it, and a value outside proves
        nothing."""
        mid = self.middles()
        got = np.array([values.get(k, m) for k, m in zip(self.keys.tolist(), mid, strict=True)])
        return np.clip(got, *self.inside)

    def values(self, z: np.ndarray) -> np.ndarray:
        """The readings at errors z (in units of their half-widths)."""
        return np.clip(self.mid + self.half * z, *self.inside)
