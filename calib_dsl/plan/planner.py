"""A plan: N of the candidates (after the rows already measured, if any), the stages that
chose them, and what their solve is predicted to give; a sweep over N with targets."""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.elaborate.tables import Dialect, read_csv
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.status import Status
from calib_dsl.pipeline import load_model, solve
from calib_dsl.plan.choose import Stage, predicted, stages
from calib_dsl.plan.configs import Configurations, read_configurations, table_of
from calib_dsl.plan.final import Solved, solved
from calib_dsl.plan.linear import Linear, linearize
from calib_dsl.relax.layout import independents
from calib_dsl.settings import Settings


@dataclass(frozen=True)
class Problem:
    """What every plan of a model shares: the model, its formulation and consts (-D), the
    seed of its simulated draws, the settings."""

    model: str | Path
    settings: Settings
    formulation: str = "matrix"
    consts: Mapping[str, str] = field(default_factory=dict)
    seed: int = 0


@dataclass(frozen=True)
class Given:
    """Rows already measured: their configurations, their cells (file units, by column),
    and the domains their solve gives."""

    configs: Configurations
    cells: dict[str, np.ndarray]
    domains: dict[str, tuple[float, float]]


@dataclass(frozen=True)
class Plan:
    """N candidates chosen: `rows` (0-based, in the candidates' order), the finalists, the
    one chosen and its simulated solve (None when no solve could be made), and each
    unknown's predicted width and domain (model units)."""

    rows: np.ndarray
    configs: Configurations
    names: list[str]
    domain: np.ndarray
    predicted: np.ndarray
    stages: list[Stage]
    chosen: str
    solved: dict[str, Solved | None]
    seconds: float


def given_rows(problem: Problem, path: str | Path, table: str = "") -> Given:
    """The measured file `path` of table `table`: solved, for its domains."""
    inputs = Inputs(data={table: str(path)}, consts=dict(problem.consts))
    model, prog = load_model(problem.model, problem.formulation, inputs=inputs)
    t = table_of(model, table)
    sol = solve(prog, "tight", settings=problem.settings)
    if sol.status != Status.CONTRACTED:
        raise CalError(f"the measured rows of '{path}' are inconsistent with the model (the "
                       "solve proved it): there are no domains to plan in")
    names = [c.name for c in t.columns if not c.derived]
    data = read_csv(path, names, dialect=Dialect(t.separator, t.decimal),
                    headers={c.name: c.header for c in t.columns if c.header})
    domains = {prog.slots.names[k]: (float(sol.lo[k]), float(sol.hi[k]))
               for k in independents(prog)}
    return Given(read_configurations(t, path), dict(data.columns), domains)


def plan(problem: Problem, candidates: Configurations, count: int,
         given: Given | None = None, final: bool = True,
         prepared: tuple[Linear, np.ndarray | None] | None = None) -> Plan:
    """Choose `count` of the candidates; with `final`, among the stages' designs by
    simulated solves, else by the LP score (`prepared`: the candidates linearized)."""
    start = time.perf_counter()
    if not 1 <= count <= len(candidates):
        raise CalError(f"--n {count}: a count from 1 to the {len(candidates)} candidates")
    lin, fixed = prepared or linear(problem, candidates, given)
    found = stages(lin, count, problem.settings, fixed)
    results: dict[str, Solved | None] = {}
    if final:  # the LP stage's design, and the better classical one by the LP score
        classical = min(found[:-1], key=lambda s: s.score)
        seen: dict[bytes, Solved | None] = {}
        for s in (classical, found[-1]):
            key = np.sort(s.rows).tobytes()
            if key not in seen:
                seen[key] = solved(problem.model, candidates.subset(np.sort(s.rows)),
                                   problem.seed, problem.formulation, problem.consts,
                                   problem.settings, None if given is None else given.cells,
                                   None if given is None else given.domains)
            results[s.name] = seen[key]
    best = _best(found, results)
    rows = np.sort(best.rows)
    widths = predicted(lin, rows, problem.settings.plan_draws, problem.seed, fixed)
    return Plan(rows, candidates.subset(rows), lin.names, lin.hi - lin.lo, widths, found,
                best.name, results, time.perf_counter() - start)


def linear(problem: Problem, candidates: Configurations,
           given: Given | None) -> tuple[Linear, np.ndarray | None]:
    """The candidates linearized, and the given rows' own rows (None without)."""
    domains = None if given is None else given.domains
    lin = linearize(problem.model, candidates, problem.formulation, problem.consts, domains)
    if given is None:
        return lin, None
    done = linearize(problem.model, given.configs, problem.formulation, problem.consts,
                     domains)
    return lin, done.blocks.reshape(-1, done.blocks.shape[2])


def _best(found: list[Stage], results: dict[str, Solved | None]) -> Stage:
    """The stage whose simulated solve scored lowest; by LP score where none was solved."""
    scored = [(results[s.name].score, i) for i, s in enumerate(found)  # type: ignore[union-attr]
              if results.get(s.name) is not None]
    if scored:
        return found[min(scored)[1]]
    return min(found, key=lambda s: s.score)


@dataclass(frozen=True)
class Sweep:
    """Predicted widths (counts, unknowns) for each count of a sweep, and the smallest count
    whose every target is met (None: none is)."""

    counts: list[int]
    names: list[str]
    widths: np.ndarray
    targets: dict[str, float]
    enough: int | None
    plans: list[Plan]


def sweep(problem: Problem, candidates: Configurations, counts: Sequence[int],
          targets: Mapping[str, float], given: Given | None = None) -> Sweep:
    """A plan for each count and its predicted widths: the classical stages and the LP
    score only (no LP exchange, no solves: a sweep predicts; the plan written is made
    after it, in full, at the count chosen)."""
    quick = replace(problem, settings=replace(problem.settings, plan_lp_hulls=0))
    prepared = linear(problem, candidates, given)
    plans = [plan(quick, candidates, n, given, False, prepared) for n in counts]
    names = plans[0].names
    unknown = [t for t in targets if t not in names]
    if unknown:
        raise CalError(f"--target {unknown[0]}: the model has no unknown '{unknown[0]}' "
                       f"(its unknowns: {', '.join(names)})")
    widths = np.array([p.predicted for p in plans])
    enough = None
    for n, w in zip(counts, widths, strict=True):
        if all(w[names.index(t)] <= v for t, v in targets.items()):
            enough = n
            break
    return Sweep(list(counts), names, widths, dict(targets), enough, plans)
