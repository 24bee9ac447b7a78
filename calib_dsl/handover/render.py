"""The report as one HTML file: the template (report.html.j2, Jinja2: autoescaped, so no text
from a model or a data file can inject markup) filled with the sections, the style sheet and
the figures inline. Nothing is fetched: no script, no font, no image by address."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from calib_dsl.elaborate.units import LENGTHS
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.handover import sections
from calib_dsl.handover.documents import Documents
from calib_dsl.handover.figures import figures

HERE = Path(__file__).resolve().parent


def render(docs: Documents) -> str:
    from jinja2 import Environment, FileSystemLoader, StrictUndefined, select_autoescape

    env = Environment(loader=FileSystemLoader(HERE), autoescape=select_autoescape(["j2"]),
                      undefined=StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    return env.get_template("report.html.j2").render(**context(docs))


def context(docs: Documents) -> dict[str, Any]:
    r = docs.result
    try:
        drawn, none = figures(docs), ""
    except CalError as err:  # matplotlib missing: the report says how to get the figures
        drawn, none = [], str(err)
    return {"model": r.get("model", ""), "verdict": sections.verdict(docs),
            "accuracy": sections.accuracy(docs), "parameters": sections.parameters(r),
            "unidentified": sections.unidentified(docs), "data": sections.data(docs),
            "figures": drawn, "no_figures": none or "The result holds nothing to draw.",
            "prov": sections.provenance(docs), "length_unit": length_unit(r),
            "css": (HERE / "report.css").read_text(encoding="utf-8")}


def length_unit(r: dict[str, Any]) -> str:
    """The model's length unit, as its unknowns say (the residuals are in it)."""
    found = {p.get("unit") for p in r["parameters"].values()} & set(LENGTHS)
    return found.pop() if len(found) == 1 else "the model's length unit"
