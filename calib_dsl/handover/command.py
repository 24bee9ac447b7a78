"""`calibc report` and `solve --report`: the handover report written to a file."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.handover.documents import Documents, read
from calib_dsl.handover.render import render


def write_report(docs: Documents, output: str, given: str | None = None) -> None:
    """The report of `docs` into `output`; `given`: the file they were read from, whose
    malformed field (a hand edit, another program's JSON) is a user error, not a bug."""
    try:
        html = render(docs)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as err:
        if given is None:
            raise
        raise CalError(f"'{given}' is malformed: a field the report reads has an unexpected "
                       f"value ({err!r}); write it anew (calibc solve --json)") from None
    try:
        Path(output).write_text(html, encoding="utf-8")
    except OSError as err:
        raise CalError(f"cannot write '{output}': {err.strerror or err}") from None


@click.command("report")
@click.argument("result", type=click.Path())
@click.option("--validation", type=click.Path(dir_okay=False),
              help="The JSON of `calibc validate --json`: the accuracy on held-out poses.")
@click.option("--identify", "identify", type=click.Path(dir_okay=False),
              help="The JSON of `calibc identify --json`: what the data cannot separate.")
@click.option("--min-error", "min_error", type=click.Path(dir_okay=False),
              help="The JSON of `calibc solve MODEL --min-error NAME --json`: the bracket of "
                   "the smallest consistent error bound.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="The HTML file to write (one self-contained file: figures and style "
                   "inline, nothing fetched).")
def report(result: str, validation: str | None, identify: str | None,
           min_error: str | None, output: str) -> None:
    """A handover report of RESULT (the JSON of `calibc solve --json`) as one HTML file:
    the verdict, the accuracy, the parameters, the data and where the result came from;
    printable to PDF from a browser."""
    given = ", ".join(f for f in (result, validation, identify, min_error) if f)
    write_report(read(result, validation, identify, min_error), output, given)
    click.echo(f"wrote the report to {output}")


def from_result(result: dict[str, Any], output: str | None) -> None:
    """`solve --report FILE`: the same report, made from the solve's JSON in memory."""
    if output is not None:
        write_report(Documents(result, names=()), output)
        click.echo(f"calibc: wrote the report to {output}", err=True)  # (stdout: the JSON)
