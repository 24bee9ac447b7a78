"""A row at fault, in a solve's verdict and in `solve --outliers K`'s.

`against_rows` is the verdict's first attempt at a proof of inconsistency (the pipeline
hands it to strategy/verdict.py's `Effort`): each data row that the least-squares fit
leaves more than `verdict_outlier_bounds` error bounds off (outliers/far.py), the worst
first, is left out and the other rows are solved alone, on the same domains. Every solution
of all rows is one of theirs, so it lies in their box; where propagation and rounds of LPs
over all rows empty that box, there is none (the row fails wherever the others hold).

`of_outliers` is the verdict on S_K, the vectors that satisfy all rows but at most K.
"""

from __future__ import annotations

import time

import numpy as np

from calib_dsl.ir.program import Program
from calib_dsl.ir.status import SlotKind, Status
from calib_dsl.outliers.rows import data_rows
from calib_dsl.propagate.diagnose import Emptied
from calib_dsl.strategy.refute import Proof, Refuter
from calib_dsl.strategy.solution import Solution
from calib_dsl.strategy.tight import solve_tight
from calib_dsl.strategy.verdict import CONSISTENT, INCONSISTENT, UNDECIDED, Verdict, certified_point


def against_rows(r: Refuter) -> None:
    """A proof against each of the rows far beyond their bound (`r.found.far`), while the
    budget affords one at the mean cost of those before (the solve's time before any)."""
    costs: list[float] = []
    for rid, residual in r.found.far:
        if not r.affords(float(np.mean(costs)) if costs else r.res.seconds):
            r.found.tried.append(f"proof against {_row(r, rid)}: not "
                                 "tried (the budget was spent)")
            continue
        t = time.perf_counter()
        r.say(f"verdict: without {_row(r, rid)}")
        proof = _without(r, rid, residual)
        costs.append(time.perf_counter() - t)
        if proof is not None:
            r.found.proof = proof
            r.found.tried.append(f"proof against {_row(r, rid)}: proven "
                                 f"({costs[-1]:.2f} s)")
            return
        r.found.tried.append(f"proof against {_row(r, rid)} "
                             f"({residual:.3g} bounds off by least squares): not "
                             f"proven ({costs[-1]:.2f} s)")


def _without(r: Refuter, rid: int, residual: float) -> Proof | None:
    assert r.load is not None
    other = r.load([rid])
    sol = solve_tight(other, tol=r.tol, max_sweeps=r.max_sweeps, settings=r.settings)
    row = _row(r, rid)
    if sol.status == Status.INFEASIBLE:  # a part of the data is inconsistent: so is the whole
        assert sol.emptied is not None
        return Proof(sol.emptied, f"the data without {row} were proven inconsistent "
                     "(and so are all the data)")
    lo, hi = r.res.lo.copy(), r.res.hi.copy()
    names = {other.slots.names[j]: j for j in other.slots.declared
             if other.slots.kinds[j] == SlotKind.PARAM}
    for i in r.prog.slots.declared:
        j = names.get(r.prog.slots.names[i])
        if j is not None and r.prog.slots.kinds[i] == SlotKind.PARAM:
            lo[i], hi[i] = max(lo[i], sol.lo[j]), min(hi[i], sol.hi[j])
    if np.any(lo > hi):
        return Proof(Emptied(r.prog.slots.names[int(np.flatnonzero(lo > hi)[0])], None,
                             None), _outlier_text(row, residual))
    out = r.contract(lo, hi, first_order=True)
    if out.emptied is None:
        return None
    return Proof(out.emptied, _outlier_text(row, residual))


def _outlier_text(row: str, residual: float) -> str:
    return (f"{row} ({residual:.3g} bounds off by least squares) fails wherever the "
            "other rows hold (their solutions lie in a box where it fails), so no "
            "parameter vector satisfies every row")


def _row(r: Refuter, rid: int) -> str:
    assert r.model is not None
    d = data_rows(r.model, r.prog, [rid])[0]
    return f"{d.file}:{d.line} (data row {d.row})"


def of_outliers(res: Solution, kept: Program | None, k: int) -> Verdict:
    """The verdict of `solve --outliers K` on S_K (the vectors that satisfy all rows but at
    most K): inconsistent when the solve proved it empty, consistent when a point is proven
    to satisfy the rows `kept` (all but at most K: those left once the certain outliers are
    out), else undecided."""
    rows = f"all data rows but at most {k}"
    if res.status == Status.INFEASIBLE:
        return Verdict(INCONSISTENT, f"no parameter vector satisfies {rows}")
    start = time.perf_counter()
    proven, largest = certified_point(kept, None) if kept is not None else (False, None)
    seconds = time.perf_counter() - start
    if proven:
        return Verdict(CONSISTENT, f"a parameter vector is proven to satisfy {rows} (every "
                       "row but the certain outliers)", seconds, largest=largest)
    return Verdict(UNDECIDED, f"no parameter vector was proven to satisfy {rows}, nor was "
                   "that proven impossible", seconds, largest=largest,
                   next_step=f"calibc solve MODEL (with the same options) --outliers {k + 1}")
