"""A strategy's result: the box, or the proof that there is none, and the work it took."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.inner.starts import Starts
from calib_dsl.ir.status import Status, Stop
from calib_dsl.propagate.diagnose import Emptied
from calib_dsl.strategy.contractor import Outcome, Work
from calib_dsl.strategy.history import History


@dataclass(frozen=True)
class Solution:
    strategy: str  # "tight" | "hc4"
    lo: np.ndarray  # the box over the program's slots (meaningless when infeasible)
    hi: np.ndarray
    stop: Stop  # why the last propagation stopped
    seconds: float
    work: Work
    emptied: Emptied | None = None  # where the model and data were proven inconsistent
    # the unknowns cut into pieces (not identifiable alone), and each piece's box that holds
    # solutions: the box is their hull
    split: tuple[str, ...] = ()
    pieces: tuple[tuple[np.ndarray, np.ndarray], ...] = ()
    # certified bounds of the identifiable combinations solved for, as (text, lo, hi)
    combinations: tuple[tuple[str, float, float], ...] = ()
    # the widths of the declared unknowns after each step (the tight strategy's)
    history: History | None = None
    # the final bases of its last first-order LPs: warm starts for the inner bounds' LPs
    starts: Starts | None = None

    @property
    def status(self) -> Status:
        return Status.INFEASIBLE if self.emptied is not None else Status.CONTRACTED

    @property
    def sweeps(self) -> int:
        return self.work.sweeps

    @property
    def lp_rounds(self) -> int:
        return self.work.lp_rounds

    @property
    def reused_rounds(self) -> int:
        return self.work.reused_rounds


def solution(strategy: str, out: Outcome, seconds: float,
             combinations: tuple[tuple[str, float, float], ...] = (),
             history: History | None = None, starts: Starts | None = None) -> Solution:
    return Solution(strategy, out.lo, out.hi, out.stop, seconds, out.work, out.emptied,
                    out.split, out.pieces, combinations, history, starts)
