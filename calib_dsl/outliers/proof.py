"""Rows proven to be outliers before any LP, for `solve --outliers K`.

S_K is the set of parameter vectors (within the program's domains) that satisfy all data rows
but at most K. A row r fails for every vector of S_K when K + 1 disjoint sets of the other
rows are each proven inconsistent together with r (a tight solve's proof, on the same
domains): a vector that satisfies r fails a row of each set, K + 1 rows in all, so it is not
in S_K. Then S_K lies in S_{K-1} of the rows without r, and the next candidate is proven
against K rows, and so on. With K rows proven, S_K lies in the solutions of the other rows:
their tight solve encloses it, and no other row can fail for any vector of it.

Candidates are the rows with the largest least-squares residuals (outliers/conflict.py); a
candidate that is not proven costs one solve (the first set's, or none when a set is proven
consistent with it) and is passed over, and tried again after another row is proven (then
with one set fewer, each larger: a row that no small set refutes may fail with every
large one).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from calib_dsl.analysis.chebyshev import proven_consistent
from calib_dsl.analysis.min_error import Loader
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.elaborate.rows import RowRange, Selection
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program
from calib_dsl.ir.status import Status
from calib_dsl.outliers.conflict import DataRow, ranked_rows
from calib_dsl.progress import Progress, labelled
from calib_dsl.settings import Settings
from calib_dsl.strategy.tight import solve_tight


@dataclass(frozen=True)
class Proof:
    row: DataRow
    sets: int  # disjoint sets of other rows, each proven inconsistent with it
    rows: int  # rows in each set (about)
    seconds: float


def pinned(load: Loader, prog: Program) -> Loader:
    """`load`, each program's declared unknowns given `prog`'s domains: a proof about other
    rows must hold on the same box (an `lsq +- w` domain would be centred on other data)."""
    names = {prog.slots.names[i]: i for i in prog.slots.declared}

    def run(inputs: Inputs) -> tuple[Model, Program]:
        model, other = load(inputs)
        for j in other.slots.declared:
            i = names.get(other.slots.names[j])
            if i is not None:
                other.slots.lo[j], other.slots.hi[j] = prog.slots.lo[i], prog.slots.hi[i]
        other.domains = None if prog.domains is None else dict(prog.domains)
        other.centred = dict(prog.centred)
        return model, other

    return run


def prove_outliers(inputs: Inputs, load: Loader, k: int, model: Model, prog: Program,
                   settings: Settings | None = None,
                   progress: Progress | None = None) -> list[Proof]:
    """The rows proven to fail for every vector of S_K, at most k, in the order proven
    (`load` must give programs on `prog`'s domains: `pinned`)."""
    settings = settings or Settings()
    if k < 1 or len(model.tables) != 1 or _consistent(prog, settings):
        return []  # a vector satisfies every row: no row fails for all of S_K
    table = model.tables[0]
    least = settings.outliers.min_residual
    try:
        ranked = [r for r in ranked_rows(model, prog, settings.fits, settings.sampling)
                  if r.residual > least]
    except (CalError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return []
    proven: list[Proof] = []
    out: set[int] = set()
    tried: dict[int, int] = {}  # row: how many sets it was last tried with
    while (left := k - len(proven)) > 0:
        # the first candidate not yet tried with left + 1 sets: a row passed over needs one
        # set fewer, each of more rows, once another row is proven
        r = next((c for c in ranked[:k + settings.outliers.extra_candidates]
                  if c.row not in out and tried.get(c.row) != left + 1), None)
        if r is None:
            break
        tried[r.row] = left + 1
        start = time.perf_counter()
        others = [n for n in table.numbers if n != r.row and n not in out]
        sets = [others[j::left + 1] for j in range(left + 1)]
        progs = _unproven(inputs, load, model, [s + [r.row] for s in sets], settings)
        if progs is not None and all(
                _inconsistent(p, settings, labelled(progress, f"outlier proof, row {r.row}, "
                                                              f"set {j + 1}/{len(sets)}: "))
                for j, p in enumerate(progs)):
            proven.append(Proof(r, len(sets), len(sets[0]), time.perf_counter() - start))
            out.add(r.row)
    return proven


def _unproven(inputs: Inputs, load: Loader, model: Model, sets: list[list[int]],
              settings: Settings) -> list[Program] | None:
    """The programs of these sets of data rows, or None when one is proven consistent (a
    certified point: no proof can follow; a few LPs instead of a solve)."""
    progs = []
    for numbers in sets:
        try:
            _, prog = load(only(inputs, model, numbers))
        except (CalError, ValueError, ArithmeticError, np.linalg.LinAlgError):
            return None
        if _consistent(prog, settings):
            return None
        progs.append(prog)
    return progs


def _consistent(prog: Program, settings: Settings) -> bool:
    """A point proven to satisfy every row (analysis/chebyshev.py)."""
    try:
        return proven_consistent(prog, settings.fits, settings.sampling)
    except (CalError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return False


def _inconsistent(prog: Program, settings: Settings, progress: Progress | None) -> bool:
    """Whether the program's rows are proven inconsistent (the tight strategy's proof)."""
    try:
        return solve_tight(prog, settings=settings, progress=progress).status == Status.INFEASIBLE
    except (CalError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return False  # not proven


def only(inputs: Inputs, model: Model, numbers: list[int]) -> Inputs:
    """The inputs with the model's (one) table reduced to these data rows."""
    name = model.tables[0].name
    sel = dict(inputs.rows)
    key = "" if "" in sel and name not in sel else name
    sel[key] = Selection(tuple(RowRange(n, n) for n in sorted(numbers)), ())
    return replace(inputs, rows=sel)
