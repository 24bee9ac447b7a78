"""The inner bounds' LP (inner/bounds.py): the rows linearized at a point, the free
unknowns' steps and the joint readings' errors its columns, each row narrowed inside its
bounds; and the HiGHS models that solve it for one end after another, each in its own
thread, from the solve's final basis for that end where there is one (inner/starts.py).
"""

from __future__ import annotations

from dataclasses import replace
from functools import cached_property

import numpy as np

from calib_dsl.analysis.certify_point import PointCheck
from calib_dsl.analysis.lsq import linearized
from calib_dsl.analysis.readings import Readings
from calib_dsl.inner.starts import Starts
from calib_dsl.ir.program import Program
from calib_dsl.lp.highs import RowCheck, add_rows, load, optimal, set_basis
from calib_dsl.relax.layout import independents
from calib_dsl.relax.relaxation import LinearRelaxation, Rows
from calib_dsl.settings import InnerSettings, LPSettings


class LinearModel:
    """The rows linearized at the centre: each row's residual r + A y + B z (in units of the
    row's bound; y the free unknowns' step in units of their widths, z the readings' errors
    in units of their bounds) within its interval, narrowed by 1 - aim and `tighten` at each
    finite end, the variables within the box; solved by HiGHS models (Solver) whose
    objective and row bounds change from one end to the next."""

    def __init__(self, prog: Program, box: tuple[np.ndarray, np.ndarray], centre: np.ndarray,
                 free: np.ndarray, starts: Starts | None = None,
                 lp: LPSettings | None = None, inner: InnerSettings | None = None) -> None:
        lp = lp or LPSettings()
        self.inner = inner or InnerSettings()
        lo, hi = box
        lin = linearized(prog, centre)
        self.centre, self.free, self.box, self.starts = centre, free, box, starts
        self.lp_settings = lp
        self.scale = np.where(np.isfinite(hi - lo), hi - lo, 1.0)[free]
        with np.errstate(all="ignore"):
            dense = lin.jac[:, free] * self.scale
            # a row's unit: its bound, or for an inequality the size of its terms
            size = np.fmax(np.abs(np.where(np.isfinite(lin.r_lo), lin.r_lo, lin.r_hi)),
                           np.abs(dense).max(axis=1, initial=0.0))
            unit = np.where(np.isfinite(lin.half) & (lin.half > 0), lin.half, size)
            unit = np.maximum(np.where(np.isfinite(unit), unit, 1.0), 1e-300)
            self.lower, self.upper = -lin.r_hi / unit, -lin.r_lo / unit  # A y within these
            dense = dense / unit[:, None]
        self.slots, self.unit, self.nslots = lin.slots, unit, len(prog.slots.names)
        self.rows, self.n = len(unit), len(free)
        self.finite = bool(np.all(np.isfinite(dense))
                           and not np.any(np.isnan(self.lower) | np.isnan(self.upper)))
        if not self.finite:
            return
        self.readings = Readings(prog)
        # the readings as LP columns, at every size (each may take its own value within its
        # interval): at their middles the ends of a thin solution set, where many rows meet,
        # fall short (docs/decisions/14). A tall LP holds only the rows its row generation
        # added, so a reading of a row left out is an empty column
        rows, cols, vals = self.readings.entries(lin)
        self.width = len(self.readings.mid)
        A = Rows.join(dense, rows, cols, vals / unit[rows], self.width)
        ylo, yhi = (lo[free] - centre[free]) / self.scale, (hi[free] - centre[free]) / self.scale
        zlo, zhi = self.readings.bounds()
        b_lo, b = self.bounds(np.zeros(self.rows))
        self.rel = LinearRelaxation(A, b, np.r_[ylo, zlo], np.r_[yhi, zhi], b_lo=b_lo)
        # what its columns are, for the solve's bases: the unknowns' slots, the readings' cells
        self.unknowns = independents(prog)[free]
        keys = self.readings.keys[:self.width]
        self.cells = np.stack([keys // self.readings.ncol, keys % self.readings.ncol], axis=1)

    def start(self, j: int, sign: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The solve's final basis for this end, mapped onto this LP's rows and columns (the
        statuses of each row, then of each column), if the solve kept one."""
        if self.starts is None:
            return None
        return self.starts.statuses(int(self.unknowns[j]), sign, self.slots, self.unknowns,
                                    self.cells)

    def bounds(self, tighten: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rows' bounds narrowed by 1 - aim and `tighten` (an infinite end stays)."""
        inward = (1.0 - self.inner.aim) + tighten
        return self.lower + inward, self.upper - inward

    def solvers(self, count: int, rows: np.ndarray | None = None) -> list[Solver]:
        """`count` HiGHS models of this LP (at least one); a tall one holding `rows` at
        first where given (Solver)."""
        return [Solver(self, rows) for _ in range(max(1, count))]

    def point(self, step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The unknowns and the readings at `step` from the centre (kept in their bounds: a
        step to an edge may round out of it)."""
        p = self.centre.copy()
        p[self.free] = self.centre[self.free] + self.scale * step[:self.n]
        if not self.width:
            return np.clip(p, *self.box), self.readings.middles()
        return np.clip(p, *self.box), self.readings.values(step[self.n:])

    def excess(self, check: PointCheck) -> tuple[np.ndarray, np.ndarray]:
        """How far each row stuck out at a failed point, in units of its bound, and which
        failed rows compare two computed values."""
        assert check.computed is not None and check.ok is not None
        # (over this LP's slots, not every slot of the program: a tall program's slot
        # arrays, one per thread, would add to the peak memory)
        slots, back = self._lp_slots
        if not len(slots):
            return np.zeros(0), np.zeros(0, dtype=bool)
        at = np.minimum(np.searchsorted(slots, check.slots), len(slots) - 1)
        mine = slots[at] == check.slots
        plain = mine & ~check.computed
        out = np.zeros(len(slots))
        np.maximum.at(out, at[plain],
                      np.where(np.isfinite(check.excess[plain]), check.excess[plain], 0.0))
        failed = np.zeros(len(slots), dtype=bool)
        failed[at[mine & check.computed & ~check.ok]] = True
        return out[back] / self.unit, failed[back]

    @cached_property
    def _lp_slots(self) -> tuple[np.ndarray, np.ndarray]:
        """The LP's rows' slots, each once (sorted), and each row's place among them."""
        slots, back = np.unique(self.slots, return_inverse=True)
        return slots, back.reshape(-1)


class Solver:
    """A HiGHS model of a LinearModel's LP: its rows' bounds as last tightened, and the rows
    it holds (a tall model holds some, and those an optimum violates are added: row
    generation, each LP small, the optimum the whole model's). One per thread.

    `rows`: the rows a tall model holds at first (indices into the model's rows)."""

    def __init__(self, model: LinearModel, rows: np.ndarray | None = None) -> None:
        self.model, self.rel = model, model.rel
        lp = model.lp_settings
        tall = model.rows > lp.rows_at_once
        # a tall model starts from `rows` (those that bound another linearization's optima
        # nearby: the row generation then adds few), else from a few rows per unknown
        spread = np.unique(np.linspace(0, model.rows - 1, 8 * model.n).astype(np.int64))
        self.in_lp = (np.arange(model.rows) if not tall else spread if rows is None
                      else np.unique(rows[(rows >= 0) & (rows < model.rows)]))
        self.h = load(self.rel, self.in_lp if tall else None, lp.iterations, lp.scaling)
        self.tightened = np.zeros(model.rows)

    def extreme(self, j: int, sign: float, tighten: np.ndarray,
                start: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray | None:
        """The LP's optimum (y, z) for the largest (sign > 0) or smallest free unknown j, the
        simplex from the basis `start` (statuses of every row and column) if given, else
        from where it last ended."""
        m = self.model
        h, cols = self.h, m.n + m.width
        if start is not None:
            set_basis(h, start[0][self.in_lp], start[1])
        cost = np.zeros(cols)
        cost[j] = -sign  # HiGHS minimizes
        h.changeColsCost(cols, np.arange(cols, dtype=np.int32), cost)
        if np.any(tighten != self.tightened):
            b_lo, b = m.bounds(tighten)
            self.rel = replace(self.rel, b=b, b_lo=b_lo)
            inf = 1e300  # HiGHS's infinity: anything beyond 1e20
            at = self.in_lp
            h.changeRowsBounds(len(at), np.arange(len(at), dtype=np.int32),
                               np.maximum(b_lo[at], -inf), np.minimum(b[at], inf))
            self.tightened = tighten.copy()
        h.run()
        if start is not None and not optimal(h):
            # a mapped basis may leave the simplex stuck (status unknown): solve again from
            # HiGHS's own start
            h.clearSolver()
            h.run()
        check = RowCheck(self.rel, m.lp_settings.rows_added) if len(self.in_lp) < m.rows else None
        while check is not None and optimal(h) and len(self.in_lp) < m.rows:
            more = check.violated(np.asarray(h.getSolution().col_value), self.in_lp)
            if not len(more):
                break
            add_rows(h, self.rel, more)
            self.in_lp = np.concatenate([self.in_lp, more])
            h.run()
        if not optimal(h):
            return None
        return np.array(h.getSolution().col_value)
