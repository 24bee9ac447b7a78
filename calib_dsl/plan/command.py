"""The command line of planning: `calibc plan`, and `calibc simulate`'s `--at` and `-D`
(cli.py registers and calls them; heavy imports wait until a command runs)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import wraps
from typing import Any

import click

from calib_dsl.elaborate.chains import FORMULATIONS
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


@dataclass(frozen=True)
class Simulation:
    """What `calibc simulate` was asked: --configs N drawn, or the configurations of --at."""

    model: str
    configs: int | None
    at: str | None
    seed: int
    output: str
    formulation: str
    campaign: Any
    consts: dict[str, str]


def simulated(asked: Simulation, progress: Any) -> int:
    """`calibc simulate`: drawn configurations or those of --at; the row count written."""
    from pathlib import Path

    model, configs, at, seed = asked.model, asked.configs, asked.at, asked.seed
    output, formulation, campaign, consts = (asked.output, asked.formulation, asked.campaign,
                                             asked.consts)
    if (configs is None) == (at is None):
        raise CalError("simulate: give either --configs N (drawn configurations) or --at "
                       "FILE (given ones)")
    if at is None:
        from calib_dsl.studies.simulate import simulate

        assert configs is not None
        simulate(model, configs, seed, formulation=formulation, out_csv=Path(output),
                 progress=progress, campaign=campaign, consts=consts)
        return configs
    from calib_dsl.elaborate.options import named
    from calib_dsl.plan.measure import simulate_at

    table, path = named(at, "--at")
    n, warnings = simulate_at(model, path, seed, output, formulation, campaign, consts, table)
    for warning in warnings:
        click.echo(f"calibc: warning: {warning}", err=True)
    return n


def counts(text: str) -> list[int]:
    """--n: `30`, or `10..120` (every 10), or `10..120:5`."""
    try:
        if ".." not in text:
            n = int(text)
            if n < 1:
                raise ValueError
            return [n]
        first, _, rest = text.partition("..")
        last, _, step = rest.partition(":")
        a, b, s = int(first), int(last), int(step) if step else SWEEP_STEP
        if a < 1 or b < a or s < 1:
            raise ValueError
    except ValueError:
        raise CalError(f"--n {text}: write a count (30) or a range FIRST..LAST[:STEP] "
                       "(10..120, 10..120:5), counts >= 1") from None
    return list(range(a, b + 1, s)) + ([b] if (b - a) % s else [])


SWEEP_STEP = 10  # --n A..B without a step: every 10 configurations


def targets(items: tuple[str, ...]) -> dict[str, float]:
    """--target NAME=WIDTH items."""
    import math

    out = {}
    for item in items:
        name, eq, value = item.partition("=")
        try:
            width = float(value)
        except ValueError:
            width = math.nan
        if not eq or not name.strip() or not (math.isfinite(width) and width > 0):
            raise CalError(f"--target {item}: write NAME=WIDTH, a width > 0 in the model's "
                           "units (e.g. --target d3=0.1)")
        out[name.strip()] = width
    return out


@click.command()
@click.argument("model", type=click.Path())
@click.option("--candidates", metavar="[TABLE=]CSV",
              help="The configurations to choose from (a file in the table's dialect; its "
                   "measured columns may be absent). Default: drawn within the joint limits.")
@click.option("--n", "n", required=True, metavar="N|FIRST..LAST[:STEP]",
              help="How many to choose; a range predicts the widths at each count.")
@click.option("--target", "target", multiple=True, metavar="NAME=WIDTH",
              help="With a range: the width an unknown must reach (model units).")
@click.option("--given", metavar="[TABLE=]CSV",
              help="Rows already measured: plan the next N after them (their solve gives "
                   "the domains).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="The plan: the chosen rows of the candidates, as they are written there.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of the simulated draws (candidates, noise).")
@click.option("--json", "json_path", type=click.Path(dir_okay=False),
              help="Also write the plan as JSON to this file ('-' for stdout).")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="With a range: draw the predicted widths against N into this file.")
@click.option("-D", "--define", "defines", multiple=True, metavar="NAME=VALUE",
              help="Set a const of the model, e.g. -D e=0.5.")
@click.option("--formulation", type=click.Choice(FORMULATIONS), default="matrix",
              show_default=True, help="How a robot chain becomes constraints.")
def plan(model: str, candidates: str | None, n: str, target: tuple[str, ...],
         given: str | None, output: str, seed: int, json_path: str | None,
         plot_path: str | None, defines: tuple[str, ...], formulation: str) -> None:
    """Choose N configurations of MODEL to measure, for the smallest guaranteed
    enclosure (docs/planning.md)."""
    from calib_dsl.elaborate.options import consts
    from calib_dsl.plan import report
    from calib_dsl.plan.planner import Problem, given_rows, sweep
    from calib_dsl.plan.planner import plan as make
    from calib_dsl.settings import DEFAULT

    sizes, goals = counts(n), targets(target)
    if len(sizes) == 1 and (goals or plot_path):
        raise CalError("--target and --plot are for a range of counts: --n FIRST..LAST")
    if plot_path:  # (before any work: a figure that cannot be drawn costs no plan)
        from calib_dsl.plot.backend import file_format, require

        file_format(plot_path)
        require()
    problem = Problem(model, DEFAULT, formulation, consts(defines), seed)
    pool = _candidates(problem, candidates)
    done = None if given is None else given_rows(problem, *_file(given, "--given"))
    if len(sizes) == 1:
        chosen = make(problem, pool, sizes[0], done)
        text, data = report.render_plan(chosen), report.plan_json(chosen)
    else:
        swept = sweep(problem, pool, sizes, goals, done)
        at = swept.enough if swept.enough is not None else sizes[-1]
        chosen = make(problem, pool, at, done)
        text = report.render_sweep(swept) + f"\n\nthe plan at N = {at}:\n" + \
            report.render_plan(chosen)
        data = {"sweep": report.sweep_json(swept), "plan": report.plan_json(chosen)}
        if plot_path:
            report.draw_sweep(swept, plot_path)
    write_plan(problem, chosen.configs, output)
    if json_path != "-":
        click.echo(text)
    _json_out(json_path, data)


def _json_out(json_path: str | None, data: dict) -> None:
    from pathlib import Path

    from calib_dsl.report.strict_json import dumps

    if json_path == "-":
        click.echo(dumps(data, indent=2))
    elif json_path:
        try:
            Path(json_path).write_text(dumps(data, indent=2) + "\n", encoding="utf-8")
        except OSError as err:
            raise CalError(f"cannot write '{json_path}': {err.strerror or err}") from None


def _file(item: str, option: str) -> tuple[str, str]:
    from calib_dsl.elaborate.options import named

    table, path = named(item, option)
    return path, table


def _candidates(problem: Any, item: str | None) -> Any:
    path, table = _file(item, "--candidates") if item else (None, "")
    return candidate_pool(problem, path, table)


def candidate_pool(problem: Any, path: str | None, table: str = "") -> Any:
    """The candidate configurations: the file's, or drawn within the joint limits (the
    table's `simulate in` ranges where a joint has none)."""
    import numpy as np

    from calib_dsl.elaborate.elaborator import Inputs, elaborate
    from calib_dsl.plan.configs import draw_configurations, read_configurations, table_of

    model = elaborate(str(problem.model), formulation=problem.formulation, simulate_rows=1,
                      inputs=Inputs(consts=dict(problem.consts)))
    t = table_of(model, table)
    if path:
        return read_configurations(t, path)
    limits = {c: lim for (tab, c), lim in model.joint_limits.items() if tab == t.name}
    return draw_configurations(t, problem.settings.plan_candidates,
                               np.random.default_rng([problem.seed, 7]), limits)


def write_plan(problem: Any, configs: Any, output: str) -> None:
    from calib_dsl.elaborate.elaborator import Inputs, elaborate
    from calib_dsl.plan.configs import table_of, write_configurations

    model = elaborate(str(problem.model), formulation=problem.formulation, simulate_rows=1,
                      inputs=Inputs(consts=dict(problem.consts)))
    write_configurations(configs, table_of(model, configs.table), output)
