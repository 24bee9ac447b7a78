"""The yardstick of any benchmark table: the linearized hull at the data's least-squares
estimate (studies/reference.py: the LP over the model linearized there, the same domains,
each measured value within its bound). Not rigorous: what the data hold to first order. It
can under- or over-state the true hull where the estimate's largest residual exceeds the
bound; the certified outer/inner of a result is the honest measure beside it.

`yardstick(model, inputs)` works on any model and campaign; `ratios(result, yard)` turns a
solve's JSON into calibc's width over the yardstick's, per parameter.
"""

from __future__ import annotations

import statistics
from pathlib import Path
from typing import Any


def yardstick(model: Path, inputs: Any) -> dict[str, tuple[float, float, float]]:
    """name: (domain width, yardstick width, least-squares value), for `model` loaded with
    `inputs` (an elaborate.elaborator.Inputs)."""
    from calib_dsl.pipeline import load
    from calib_dsl.relax.layout import independents
    from calib_dsl.studies.reference import yardstick as hull_at_estimate

    prog = load(model, inputs=inputs)
    hull = hull_at_estimate(prog)
    out = {}
    for k in independents(prog):
        n = prog.slots.names[k]
        out[n] = (float(prog.slots.hi[k] - prog.slots.lo[k]), hull[n][1] - hull[n][0],
                  float(prog.true_values[n] or 0.0))
    return out


def ratios(result: dict, yard: dict[str, tuple[float, float, float]]) -> dict[str, float]:
    """Each parameter's result width over its yardstick width (a solve's --json)."""
    out = {}
    for n, p in result["parameters"].items():
        if n in yard and yard[n][1] > 0:
            lo, hi = p["result"]
            out[n] = (hi - lo) / yard[n][1]
    return out


def summary(values: dict[str, float]) -> str:
    """'median M, worst W (name)' of per-parameter ratios."""
    if not values:
        return "none"
    worst = max(values, key=lambda n: values[n])
    return (f"median {statistics.median(values.values()):.2f}, worst {values[worst]:.2f} "
            f"({worst})")
