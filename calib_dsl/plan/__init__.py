"""Planning a measurement campaign from Python (issue #43; the guide is docs/planning.md):
which configurations to measure, and how many, for the guaranteed enclosure to be smallest.

    from calib_dsl import plan
    asked = plan.PlanRequest("models/ur10_simulated.cal", "candidates.csv",
                             defines={"e": 0.5})
    p = plan.plan(asked, 30)
    p.rows                      # the chosen rows of the file (0-based), p.configs their poses
    p.predicted                 # each unknown's predicted guaranteed width (p.names)
    s = plan.sweep(asked, range(10, 121, 10), targets={"d3": 0.1})
    s.enough                    # the smallest count whose predicted widths meet the targets

A request's `candidates` is a file in the table's dialect (its measured columns may be
absent), or None to draw them within the model's joint limits. The functions run what
`calibc plan` and `calibc simulate --at` run (the modules load on first call: the command
line imports this package for its options alone). A mistake raises `CalError`, as everywhere.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from calib_dsl.plan.planner import Plan, Problem, Sweep
    from calib_dsl.settings import Settings

__all__ = ["PlanRequest", "plan", "simulate_at", "sweep"]

Number = int | float | Fraction | str


def problem_of(model: str | Path, defines: Mapping[str, Number] | None, seed: int,
             formulation: str, settings: Settings | None) -> Problem:
    """What every plan of the model shares (-D values as the command line's text)."""
    from calib_dsl.plan.planner import Problem
    from calib_dsl.settings import DEFAULT

    consts = {n: repr(v) if isinstance(v, float) else str(v) for n, v in (defines or {}).items()}
    return Problem(model, settings or DEFAULT, formulation, consts, seed)


def _pool(problem: Problem, candidates: str | Path | None, table: str) -> Any:
    from calib_dsl.plan.command import candidate_pool

    return candidate_pool(problem, None if candidates is None else str(candidates), table)


@dataclass(frozen=True)
class PlanRequest:
    """A campaign to plan: `calibc plan MODEL --candidates [TABLE=]CANDIDATES [--given FILE]
    [-D NAME=VALUE] [--seed S] [--formulation F]`, as data."""

    model: str | Path
    candidates: str | Path | None = None  # None: drawn within the model's joint limits
    table: str = ""  # the table the candidates are rows of ("": the first)
    given: str | Path | None = None  # rows measured already, which every plan keeps
    defines: Mapping[str, Number] | None = None  # top-level consts (-D)
    seed: int = 0
    formulation: str = "matrix"
    settings: Settings | None = None  # None: the process's DEFAULT


def _start(request: PlanRequest) -> tuple[Problem, Any, Any]:
    """The request's problem, its pool of candidates and its rows given (or None)."""
    from calib_dsl.plan.planner import given_rows

    r = request
    problem = problem_of(r.model, r.defines, r.seed, r.formulation, r.settings)
    done = None if r.given is None else given_rows(problem, r.given, r.table)
    return problem, _pool(problem, r.candidates, r.table), done


def plan(request: PlanRequest, n: int) -> Plan:
    """`calibc plan ... --n N`: the n configurations to measure."""
    from calib_dsl.plan.planner import plan as make

    problem, pool, done = _start(request)
    return make(problem, pool, n, done)


def sweep(request: PlanRequest, counts: Iterable[int],
          targets: Mapping[str, float] | None = None) -> Sweep:
    """`calibc plan ... --n FIRST..LAST:STEP --target NAME=WIDTH`: the predicted widths at
    each count, and the smallest count meeting every target."""
    from calib_dsl.plan.planner import sweep as run

    problem, pool, done = _start(request)
    return run(problem, pool, list(counts), dict(targets or {}), done)


def simulate_at(model: str | Path, at: str | Path, out: str | Path, *, seed: int = 0,
                table: str = "", defines: Mapping[str, Number] | None = None,
                formulation: str = "matrix") -> int:
    """`calibc simulate MODEL --at [TABLE=]AT -o OUT`: the rows written."""
    from calib_dsl.plan.measure import simulate_at as run

    problem = problem_of(model, defines, seed, formulation, None)
    return run(model, at, seed, out, formulation, consts=problem.consts, table=table)[0]
