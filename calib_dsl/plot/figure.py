"""The figures a result supports, drawn and saved: `calibc plot`, `solve --plot`,
`validate --plot`.

All the kinds asked for go into one figure, one band per kind, top to bottom (domains,
residuals, accuracy, prediction, history): one file holds everything the result can show, and
`--kind` picks one. `figure()` returns the matplotlib Figure (the tests read what it draws).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.plot import (
    accuracy,
    backend,
    domains,
    history,
    prediction,
    residuals,
    workspace,
)

KINDS = {"domains": domains, "residuals": residuals, "accuracy": accuracy,
         "prediction": prediction, "history": history, "workspace": workspace}
CHOICES = (*KINDS, "all")
WIDTH = 10.0  # inches
# how to get each kind into a result's JSON
HOW = {"domains": "calibc solve MODEL --json FILE",
       "residuals": "calibc solve MODEL --residuals --json FILE",
       "accuracy": "calibc solve MODEL --json FILE (a model that compares predictions with "
                   "measured columns)",
       "prediction": "calibc validate MODEL --at HELDOUT --json FILE",
       "history": "calibc solve MODEL --json FILE (the tight strategy)",
       "workspace": "calibc predict MODEL --grid NAME=a:b:step,... --json FILE"}


def available(data: dict[str, Any]) -> list[str]:
    """The kinds of figure the result holds the data for."""
    return [k for k, module in KINDS.items() if module.supports(data)]


def chosen(data: dict[str, Any], kind: str = "all") -> list[str]:
    """The kinds to draw: those asked for, each checked against the result."""
    if kind == "all":
        kinds = available(data)
        if not kinds:
            raise CalError("the result holds nothing to plot (no parameters, residuals, "
                           "held-out rows or history)")
        return kinds
    if kind not in KINDS:
        raise CalError(f"unknown kind of figure '{kind}' (one of {', '.join(CHOICES)})")
    if not KINDS[kind].supports(data):
        raise CalError(f"the result holds no data for the {kind} figure: {HOW[kind]} "
                       "writes it")
    return [kind]


def _height(kind: str, data: dict[str, Any]) -> float:
    n = KINDS[kind].count(data)
    if kind == "domains":
        return max(2.5, 1.2 + 0.2 * n)
    if kind in ("accuracy", "workspace"):
        return 3.5
    return 3.0 * n if kind == "history" else 2.8 * n


def figure(data: dict[str, Any], kind: str = "all") -> Any:
    """The matplotlib Figure of the kinds asked for (`chosen`)."""
    kinds = chosen(data, kind)
    heights = [_height(k, data) for k in kinds]
    fig = backend.new_figure(WIDTH, sum(heights))
    bands = fig.subfigures(len(kinds), 1, height_ratios=heights, squeeze=False)[:, 0]
    for band, k in zip(bands, kinds, strict=True):
        KINDS[k].draw(band, data)
    return fig


def save_figure(data: dict[str, Any], path: str | Path, kind: str = "all") -> list[str]:
    """Draw and save (the format by the file's extension); the kinds drawn."""
    backend.file_format(path)
    fig = figure(data, kind)
    backend.save(fig, path)
    return chosen(data, kind)

