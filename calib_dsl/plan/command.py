"""The command line of planning: `calibc plan`, and `calibc simulate`'s `--at` and `-D`
(cli.py registers and calls them; heavy imports wait until a command runs)."""

from __future__ import annotations

from collections.abc import Callable
from functools import wraps
from typing import Any

import click

from calib_dsl.frontend.diagnostics import CalError


def simulate_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """simulate's --at [TABLE=]FILE and -D NAME=VALUE (handed on as `at`, `consts`)."""

    @wraps(fn)
    def run(*args: Any, defines: tuple[str, ...], **kwargs: Any) -> Any:
        from calib_dsl.elaborate.options import consts

        return fn(*args, consts=consts(defines), **kwargs)

    options = [
        click.option("--at", "at", metavar="[TABLE=]CSV",
                     help="Measure at the configurations of this file (in the table's "
                          "dialect; its measured columns may be absent) instead of drawing "
                          "--configs of them."),
        click.option("-D", "--define", "defines", multiple=True, metavar="NAME=VALUE",
                     help="Set a const of the model, e.g. -D e=0.5 (the noise's bound)."),
    ]
    for option in reversed(options):
        run = option(run)
    return run


def simulated(model: str, configs: int | None, at: str | None, seed: int, output: str,
              formulation: str, campaign: Any, consts: dict[str, str],
              progress: Any) -> int:
    """`calibc simulate`: drawn configurations or those of --at; the row count written."""
    from pathlib import Path

    if (configs is None) == (at is None):
        raise CalError("simulate: give either --configs N (drawn configurations) or --at "
                       "FILE (given ones)")
    if at is None:
        from calib_dsl.analysis.simulate import simulate

        assert configs is not None
        simulate(model, configs, seed, formulation=formulation, out_csv=Path(output),
                 progress=progress, campaign=campaign, consts=consts)
        return configs
    from calib_dsl.elaborate.options import named
    from calib_dsl.plan.measure import simulate_at

    table, path = named(at, "--at")
    return simulate_at(model, path, seed, output, formulation, campaign, consts, table)
