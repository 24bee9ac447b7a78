"""The final choice: each finalist measured (simulated at the model's true values, with its
error model) and solved as `calibc solve` would; the design whose guaranteed enclosure is
smallest (mean log width over domain, as the LP score) wins. One seed for all, so that the
finalists meet the same truth and noise draws of the same kind.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.elaborate.values import Values
from calib_dsl.ir.status import Status
from calib_dsl.pipeline import load_model, solve
from calib_dsl.plan.configs import Configurations, table_of
from calib_dsl.plan.measure import measured_at
from calib_dsl.relax.layout import independents
from calib_dsl.settings import Settings
from calib_dsl.studies.campaign import PLAIN


@dataclass(frozen=True)
class Solved:
    """A design's simulated solve: each unknown's guaranteed width and domain (model
    units), whether the truth lay inside, and the score."""

    names: list[str]
    width: np.ndarray
    domain: np.ndarray
    truth_inside: bool
    score: float

    @property
    def median_ratio(self) -> float:
        return float(np.median(self.width / self.domain))


def solved(model_path: str | Path, configs: Configurations, seed: int, formulation: str,
           consts: Mapping[str, str] | None, settings: Settings,
           given: Mapping[str, np.ndarray] | None = None,
           domains: Mapping[str, tuple[float, float]] | None = None) -> Solved | None:
    """Simulate the configurations, solve (the `given` table's columns, in file units,
    measured before them), and measure the enclosure against the solve's domains (or
    `domains`, the given rows' box); None if the solve found the data inconsistent (a
    model whose truth breaks its own bounds)."""
    model, data = measured_at(model_path, configs, seed, formulation, PLAIN, consts)
    t = table_of(model, configs.table)
    files = [c for c in t.columns if not c.derived]
    factor = np.array([0.5 * (c.factor[0] + c.factor[1]) for c in t.columns])
    cells = {c.name: data[:, j] / factor[j] for j, c in enumerate(t.columns)
             if not c.derived}
    if given is not None:
        cells = {c.name: np.concatenate([given[c.name], cells[c.name]]) for c in files}
    inputs = Inputs(data={t.name: Values(cells, "<simulated plan>")},
                    consts=dict(consts or {}))
    _, prog = load_model(model_path, formulation, inputs=inputs)
    sol = solve(prog, "tight", settings=settings)
    if sol.status != Status.CONTRACTED:
        return None
    ind = independents(prog)
    names = [prog.slots.names[k] for k in ind]
    width = np.array([float(sol.hi[k] - sol.lo[k]) for k in ind])
    domain = np.array([float(prog.slots.hi[k] - prog.slots.lo[k]) if domains is None
                       else domains[n][1] - domains[n][0] for k, n in zip(ind, names,
                                                                          strict=True)])
    truth = [prog.true_values.get(n) for n in names]
    inside = all(t is None or sol.lo[k] <= t <= sol.hi[k] for k, t in zip(ind, truth,
                                                                           strict=True))
    ratio = np.maximum(width / domain, 1e-6)
    return Solved(names, width, domain, inside, float(np.mean(np.log(ratio))))
