"""The report's figures: those of `calibc plot` that the documents hold data for, drawn as
inline SVG (text as paths: no font is fetched, the file renders the same anywhere)."""

from __future__ import annotations

import io
from dataclasses import dataclass
from typing import Any

from calib_dsl.handover.documents import Documents
from calib_dsl.plot import figure as plot

CAPTIONS = {
    "domains": "Per unknown, one panel per unit: the width of its search domain, of its "
               "guaranteed result and of its certified inner interval.",
    "residuals": "Per data row, the range of each measured coordinate's residual over the "
                 "result box, against the error bound.",
    "prediction": "Held-out poses: the guaranteed range of each coordinate's prediction "
                  "error, against the error bound.",
    "history": "The unknowns' widths after each step and round of linear programs, one panel "
               "per unit.",
}


@dataclass(frozen=True)
class Figure:
    kind: str
    caption: str
    svg: str  # an <svg> element


def figures(docs: Documents) -> list[Figure]:
    """Every figure the documents support, in the report's order (none without matplotlib:
    the report says so instead)."""
    out = []
    for kind, data in (("domains", docs.result), ("residuals", docs.result),
                       ("prediction", docs.validation), ("history", docs.result)):
        if data is not None and kind in plot.available(data):
            out.append(Figure(kind, CAPTIONS[kind], svg(plot.figure(data, kind))))
    return out


def svg(fig: Any) -> str:
    """A matplotlib Figure as an inline <svg> element (no XML prolog, no DOCTYPE)."""
    fig.set_dpi(72)
    buf = io.StringIO()
    fig.savefig(buf, format="svg", metadata={"Date": None})
    text = buf.getvalue()
    return text[text.index("<svg"):]
