"""Planning a measurement campaign from Python (issue #43; the guide is docs/planning.md):
which configurations to measure, and how many, for the guaranteed enclosure to be smallest.

    from calib_dsl import plan
    p = plan.plan("models/ur10_simulated.cal", "candidates.csv", 30, defines={"e": 0.5})
    p.rows                      # the chosen rows of the file (0-based), p.configs their poses
    p.predicted                 # each unknown's predicted guaranteed width (p.names)
    s = plan.sweep("models/ur10_simulated.cal", "candidates.csv", range(10, 121, 10),
                   targets={"d3": 0.1}, defines={"e": 0.5})
    s.enough                    # the smallest count whose predicted widths meet the targets

`candidates` is a file in the table's dialect (its measured columns may be absent), or None
to draw them within the model's joint limits. The functions run what `calibc plan` and
`calibc simulate --at` run (the modules load on first call: the command line imports this
package for its options alone). A mistake raises `CalError`, as everywhere.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from calib_dsl.plan.planner import Plan, Problem, Sweep
    from calib_dsl.settings import Settings

__all__ = ["plan", "simulate_at", "sweep"]

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


def plan(model: str | Path, candidates: str | Path | None, n: int, *, table: str = "",
         given: str | Path | None = None, defines: Mapping[str, Number] | None = None,
         seed: int = 0, formulation: str = "matrix", settings: Settings | None = None
         ) -> Plan:
    """`calibc plan MODEL --candidates [TABLE=]CANDIDATES --n N [--given FILE]`."""
    from calib_dsl.plan.planner import given_rows
    from calib_dsl.plan.planner import plan as make

    problem = problem_of(model, defines, seed, formulation, settings)
    done = None if given is None else given_rows(problem, given, table)
    return make(problem, _pool(problem, candidates, table), n, done)


def sweep(model: str | Path, candidates: str | Path | None, counts: Iterable[int], *,
          targets: Mapping[str, float] | None = None, table: str = "",
          given: str | Path | None = None, defines: Mapping[str, Number] | None = None,
          seed: int = 0, formulation: str = "matrix", settings: Settings | None = None
          ) -> Sweep:
    """`calibc plan ... --n FIRST..LAST:STEP --target NAME=WIDTH`: the predicted widths at
    each count, and the smallest count meeting every target."""
    from calib_dsl.plan.planner import given_rows
    from calib_dsl.plan.planner import sweep as run

    problem = problem_of(model, defines, seed, formulation, settings)
    done = None if given is None else given_rows(problem, given, table)
    return run(problem, _pool(problem, candidates, table), list(counts), dict(targets or {}),
               done)


def simulate_at(model: str | Path, at: str | Path, out: str | Path, *, seed: int = 0,
                table: str = "", defines: Mapping[str, Number] | None = None,
                formulation: str = "matrix") -> int:
    """`calibc simulate MODEL --at [TABLE=]AT -o OUT`: the rows written."""
    from calib_dsl.plan.measure import simulate_at as run

    problem = problem_of(model, defines, seed, formulation, None)
    return run(model, at, seed, out, formulation, consts=problem.consts, table=table)
