"""The `calibc` command line: compile, solve, simulate."""

from __future__ import annotations

import math
import os
import sys
import traceback
from collections.abc import Callable
from functools import wraps
from typing import Any

import click

from calib_dsl import outputs
from calib_dsl.elaborate.chains import FORMULATIONS
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.handover.command import report as handover_report
from calib_dsl.ir.status import Status
from calib_dsl.plan import command as plan_command
from calib_dsl.settings import DEFAULT
from calib_dsl.strategy.tight import STRATEGIES

FORMULATION = click.option("--formulation", type=click.Choice(FORMULATIONS),
                           default="matrix", show_default=True,
                           help="How a robot chain becomes constraints.")
QUIET = click.option("-q", "--quiet", is_flag=True,
                     help="No progress line on standard error (drawn only on a terminal).")


def model_inputs(fn: Callable[..., Any]) -> Callable[..., Any]:
    """The options that add to a model what the command line knows: data files, rows,
    const values. TABLE= may be left out when the model has one table (it is the first)."""
    options = [
        click.option("--data", "data", multiple=True, metavar="[TABLE=]CSV",
                     help="CSV file replacing the one a table of the model names."),
        click.option("--rows", "rows", multiple=True, metavar="[TABLE=]RANGES",
                     help="Rows of a table to use, e.g. 1..1495:15 (every 15th from 1) or "
                          "1..100,200.. (rows count from 1, the first after the header)."),
        click.option("--exclude", "exclude", multiple=True, metavar="[TABLE=]ROWS",
                     help="Rows of a table to leave out, e.g. 533,856."),
        click.option("-D", "--define", "defines", multiple=True, metavar="NAME=VALUE",
                     help="Set a const of the model, e.g. -D e=1.2 (an error bound, a step)."),
    ]
    for option in reversed(options):
        fn = option(fn)
    return fn


UNROLL = click.option(
    "--unroll", is_flag=True,
    help="Compile each row of a loop over a table's rows on its own, as written, instead of "
         "the loop's body once for all rows (the same program, slower and larger: a check).")


def _inputs(data: tuple[str, ...], rows: tuple[str, ...], exclude: tuple[str, ...],
            defines: tuple[str, ...], unroll: bool = False) -> Any:
    from dataclasses import replace

    from calib_dsl.elaborate.options import inputs_from_options

    return replace(inputs_from_options(data, rows, exclude, defines), unroll=unroll)


def user_errors(fn: Callable[..., Any]) -> Callable[..., Any]:
    """User errors print `file:line:col: error: ...` and exit 2, never a traceback."""

    @wraps(fn)
    def run(*args: Any, **kwargs: Any) -> Any:
        try:
            with outputs.quiet_numerics():
                return fn(*args, **kwargs)
        except CalError as err:
            click.echo(err.render(), err=True)
            sys.exit(2)
        except RecursionError:
            click.echo("error: the model nests too deeply to elaborate", err=True)
            sys.exit(2)
        except (click.exceptions.Exit, click.ClickException, KeyboardInterrupt):
            raise
        except BrokenPipeError:  # `calibc solve ... | head`: the reader left, nothing is wrong
            sys.stderr.close()
            sys.exit(0)
        except OSError as err:  # the system's, not ours: a full disk, a lost file system
            click.echo(f"error: {outputs.os_error(err)}", err=True)
            sys.exit(2)
        except Exception as exc:  # a bug of ours: say so plainly
            if os.environ.get("CALIBC_DEBUG"):
                traceback.print_exc()
            click.echo(f"calibc: internal error: {type(exc).__name__}: {exc} "
                       "(set CALIBC_DEBUG=1 for the traceback)", err=True)
            sys.exit(3)

    return run


def _load(model: str, formulation: str, inputs: Any = None):
    from calib_dsl.pipeline import load

    return load(model, formulation, inputs=inputs)


@click.group(cls=outputs.Calibc)
@click.version_option(package_name="calibc")
def main() -> None:
    """calibc: guaranteed robot calibration by interval constraint propagation."""


@main.command()
@click.argument("model", type=click.Path())
@click.option("-o", "--output", type=click.Path(dir_okay=False),
              help="Write the output (the listing, or the JSON with --json) to this file "
                   "instead of standard output.")
@click.option("--json", "as_json", is_flag=True,
              help="The program's counts as JSON instead of the listing.")
@FORMULATION
@UNROLL
@model_inputs
@user_errors
def compile(model: str, output: str | None, as_json: bool, formulation: str,
            data: tuple[str, ...], rows: tuple[str, ...], exclude: tuple[str, ...],
            defines: tuple[str, ...], unroll: bool) -> None:
    """Compile MODEL into its primitive-constraint listing."""
    from calib_dsl.compile.listing import render_listing
    from calib_dsl.report.strict_json import dumps

    prog = _load(model, formulation, _inputs(data, rows, exclude, defines, unroll))
    text = dumps(prog.counts(), indent=2) + "\n" if as_json else render_listing(prog)
    if output:
        outputs.write(output, text)
    else:
        click.echo(text, nl=False)


class _FiniteTol(click.ParamType):
    """A non-negative finite float: click's FloatRange lets nan through (nan < 0 is false)."""

    name = "float"

    def convert(self, value: object, param: click.Parameter | None,
                ctx: click.Context | None) -> float:
        try:
            x = float(value)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        if not (math.isfinite(x) and x >= 0):
            self.fail(f"{value!r} is not a finite number >= 0", param, ctx)
        return x


FINITE_TOL = _FiniteTol()
MAX_CONFIGS = 1_000_000  # simulate: a table beyond this is a typo, not a campaign


@main.command()
@click.argument("model", type=click.Path())
@click.option("--tol", type=FINITE_TOL, default=1e-5, show_default=True,
              help="Stop when a sweep contracts every declared unknown by less than this "
                   "relative amount.")
@click.option("--max-sweeps", type=click.IntRange(min=1), default=1000, show_default=True,
              help="At most this many propagation sweeps in the whole solve.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False),
              help="Also write the result as JSON to this file ('-' for stdout).")
@click.option("--strategy", type=click.Choice(STRATEGIES), default=STRATEGIES[0],
              show_default=True,
              help="hc4: forward-backward propagation only (the paper's method); tight: "
                   "propagation alternated with a certified linear relaxation (LP).")
@click.option("--identify/--no-identify", default=True, show_default=True,
              help="Report which parameters the data cannot separate.")
@click.option("--lsq", is_flag=True, help="Also report a least-squares estimate.")
@click.option("--all", "every", is_flag=True,
              help="List every unknown, also those that kept their whole search domain.")
@click.option("--inner/--no-inner", default=None,
              help="Certify values each unknown provably takes at solutions (how much of "
                   "the result is real). Default: on with tight, at every size.")
@click.option("--shave", type=click.IntRange(min=0), metavar="N",
              help="Contract the ends of the N loosest unknowns towards their inner bounds. "
                   f"Default: those {DEFAULT.shave_above}x looser, for up to "
                   f"{DEFAULT.shave_share:.0%} of the solve's time; 0: none.")
@click.option("--diagnose/--no-diagnose", default=True, show_default=True,
              help="When the data are inconsistent, find the rows without which the rest is "
                   "proven consistent.")
@click.option("--outliers", type=click.IntRange(min=0), default=0, metavar="K",
              help="Enclose every parameter vector consistent with all data rows but at "
                   "most K (a row: a configuration with all its measured values), and name "
                   "the rows that are certainly and possibly outliers. 0: every row holds.")
@click.option("--min-error", "min_error", metavar="NAME",
              help="Instead of one solve, bracket the smallest value of the const NAME (the "
                   "error bound) for which the data are consistent.")
@QUIET
@outputs.solve_options
@FORMULATION
@UNROLL
@model_inputs
@user_errors
def solve(model: str, tol: float, max_sweeps: int, json_path: str | None, strategy: str,
          identify: bool, lsq: bool, every: bool, inner: bool | None, shave: int | None,
          diagnose: bool, outliers: int, min_error: str | None, quiet: bool, residuals: bool,
          plot_path: str | None, export_domains: str | None, report_path: str | None,
          formulation: str,
          data: tuple[str, ...], rows: tuple[str, ...], exclude: tuple[str, ...],
          defines: tuple[str, ...], unroll: bool) -> None:
    """Contract every unknown of MODEL to an interval proven to hold all its solutions."""
    from calib_dsl.handover.command import from_result
    from calib_dsl.handover.provenance import provenance
    from calib_dsl.pipeline import SolveRequest, solve_report
    from calib_dsl.report.progress_line import progress_line

    inputs = _inputs(data, rows, exclude, defines, unroll)
    if min_error is not None:
        _min_error(model, min_error, formulation, inputs, strategy, json_path, quiet)
        return
    outputs.plot_ready(plot_path)
    with progress_line("solving", quiet) as progress:
        asked = SolveRequest(model, formulation, inputs, strategy, tol, max_sweeps, identify,
                             lsq, inner, diagnose, outliers, shave)
        run = solve_report(asked, progress)
    for line in run.stderr_lines():  # the warnings, and a verdict left undecided
        click.echo(line, err=True)
    if json_path != "-":
        click.echo(run.text(every))
    result = {**run.as_json(), "provenance": provenance(run.prog, main.argv)}
    if (residuals or plot_path or report_path) and run.res.status == Status.CONTRACTED:
        result["residuals"] = outputs.residuals(run,
                                                quiet=json_path == "-")
    outputs.json_out(json_path, result)
    outputs.plotted(result, plot_path)
    outputs.export_domains(result, export_domains)
    from_result(result, report_path)
    if run.exit_code:  # 1: proven inconsistent; 4: undecided (docs/decisions/verdicts.md)
        sys.exit(run.exit_code)


def _min_error(model: str, name: str, formulation: str, inputs: Any, strategy: str,
               json_path: str | None, quiet: bool) -> None:
    from calib_dsl.pipeline import min_error
    from calib_dsl.report.min_error import min_error_json, render_min_error
    from calib_dsl.report.progress_line import progress_line

    with progress_line(f"bracketing {name}", quiet) as progress:
        found = min_error(model, name, formulation, inputs, strategy, progress)
    _out(json_path, render_min_error(found), {"model": model,
                                              "min_error": min_error_json(found)})


@main.command()
@click.argument("model", type=click.Path())
@click.option("--json", "as_json", is_flag=True, help="Print the analysis as JSON.")
@FORMULATION
@UNROLL
@model_inputs
@user_errors
def identify(model: str, as_json: bool, formulation: str, data: tuple[str, ...],
             rows: tuple[str, ...], exclude: tuple[str, ...], defines: tuple[str, ...],
            unroll: bool) -> None:
    """Which parameters of MODEL the measurements can determine, which move with which, and
    a well-conditioned subset to calibrate (judged against the data's error bounds)."""
    from calib_dsl.report.strict_json import dumps
    from calib_dsl.studies.advice import advice_json, advise, render

    info = advise(_load(model, formulation, _inputs(data, rows, exclude, defines, unroll)))
    click.echo(dumps(advice_json(info), indent=2) if as_json else render(info))


def at_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """The configurations to predict at: a file in the format of the model's table."""
    options = [
        click.option("--at", "at", type=click.Path(),
                     help="Configurations: a file in the format of the model's table (the "
                          "measurement columns may be absent for predict)."),
        click.option("--at-rows", metavar="RANGES",
                     help="Rows of the --at file to use, e.g. 1..100 (all by default)."),
        click.option("--at-skip", metavar="RANGES",
                     help="Rows of the --at file to leave out, e.g. 1..1495:15 (the rows "
                          "calibrated on, to validate on the others)."),
        click.option("--strategy", type=click.Choice(STRATEGIES), default=STRATEGIES[0],
                     show_default=True, help="The calibration's strategy."),
        click.option("--json", "json_path", type=click.Path(dir_okay=False),
                     help="Also write the result as JSON to this file ('-' for stdout)."),
        QUIET,
    ]
    for option in reversed(options):
        fn = option(fn)
    return fn


def _predicted(model: str, at: str, at_rows: str | None, at_skip: str | None,
               strategy: str, formulation: str, inputs: Any, quiet: bool) -> Any:
    from calib_dsl.pipeline import predict_at
    from calib_dsl.report.progress_line import progress_line

    if at is None:
        raise CalError("--at FILE is required (predict: or --grid)")
    with progress_line("calibrating", quiet) as progress:
        sol, found = predict_at(model, at, formulation, inputs, strategy,
                                outputs.at_selection(at, at_rows, at_skip), progress)
    if found is None:
        click.echo("the data are inconsistent (the solve proved it): nothing to predict",
                   err=True)
        sys.exit(1)
    for warning in found.warnings:
        click.echo(f"calibc: warning: {warning}", err=True)
    return found


def _out(json_path: str | None, text: str, data: dict) -> None:
    if json_path != "-":
        click.echo(text)
    outputs.json_out(json_path, data)


@main.command()
@click.argument("model", type=click.Path())
@at_options
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False),
              help="Also write the boxes as CSV (row, line, then each column's lo and hi).")
@click.option("--grid", metavar="NAME=a:b:step,...",
              help="Instead of --at: every pose of a grid of the table's inputs (file units), "
                   "with the guaranteed error bound at each.")
@FORMULATION
@UNROLL
@model_inputs
@user_errors
def predict(model: str, at: str, at_rows: str | None, at_skip: str | None, strategy: str,
            json_path: str | None, quiet: bool, csv_path: str | None, grid: str | None,
            formulation: str, data: tuple[str, ...], rows: tuple[str, ...],
            exclude: tuple[str, ...], defines: tuple[str, ...], unroll: bool) -> None:
    """Calibrate MODEL on its data, then give for each configuration of --at a box proven to
    hold the predicted measurement for every parameter vector consistent with the data."""
    from calib_dsl.report.prediction import prediction_csv, prediction_json, render_prediction

    if grid is not None and at is not None:
        raise CalError("predict: give either --grid (poses of a grid) or --at FILE, not both")
    if grid is not None:
        from calib_dsl.report.progress_line import progress_line

        with progress_line("calibrating", quiet) as progress:
            text, doc, table = outputs.grid_outputs(model, grid, formulation, _inputs(
                data, rows, exclude, defines, unroll), strategy, progress)
        if csv_path:
            outputs.write(csv_path, table)
        return _out(json_path, text, doc)
    found = _predicted(model, at, at_rows, at_skip, strategy, formulation,
                       _inputs(data, rows, exclude, defines, unroll), quiet)
    if csv_path:
        outputs.write(csv_path, prediction_csv(found))
    _out(json_path, render_prediction(found), {"model": model, **prediction_json(found)})


@main.command()
@click.argument("model", type=click.Path())
@at_options
@outputs.PLOT
@FORMULATION
@UNROLL
@model_inputs
@user_errors
def validate(model: str, at: str, at_rows: str | None, at_skip: str | None, strategy: str,
             json_path: str | None, quiet: bool, plot_path: str | None, formulation: str,
             data: tuple[str, ...], rows: tuple[str, ...], exclude: tuple[str, ...],
             defines: tuple[str, ...],
            unroll: bool) -> None:
    """Calibrate MODEL on its data, predict the held-out measurements of --at and compare:
    the share of rows inside their boxes widened by the error bound, and the boxes' widths."""
    from calib_dsl.report.prediction import render_validation, validation_json

    outputs.plot_ready(plot_path)
    found = _predicted(model, at, at_rows, at_skip, strategy, formulation,
                       _inputs(data, rows, exclude, defines, unroll), quiet)
    result = {"model": model, **validation_json(found)}
    _out(json_path, render_validation(found), result)
    outputs.plotted(result, plot_path)


@main.command()
@click.argument("model", type=click.Path())
@click.option("--configs", type=click.IntRange(min=1, max=MAX_CONFIGS),
              help=f"Number of configurations (rows) to draw, at most {MAX_CONFIGS:,}.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of the random draws (a non-negative integer): the same seed gives "
                   "the same file.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True,
              help="The CSV file to write (in the dialect of the model's table); '-' for "
                   "standard output.")
@QUIET
@FORMULATION
@user_errors
@outputs.campaign_options
@plan_command.simulate_options
def simulate(model: str, configs: int | None, seed: int, output: str, quiet: bool,
             formulation: str, campaign: Any, at: str | None, consts: Any) -> None:
    """Simulate measurements of MODEL by the paper's protocol, into a CSV file: at --configs
    drawn configurations, or at those of the file --at."""
    from calib_dsl.report.progress_line import progress_line

    with progress_line("simulating", quiet) as progress:
        n = plan_command.simulated(plan_command.Simulation(
            model, configs, at, seed, output, formulation, campaign, consts), progress)
    click.echo(f"wrote {n} configurations to {output}", err=output == "-")


@main.command()
@click.argument("source", metavar="JOBS|MODEL", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="The results: one JSON object per line, a job per line.")
@click.option("--data-glob", metavar="[TABLE=]PATTERN",
              help="SOURCE is a model: solve it once per CSV file matching PATTERN "
                   "(e.g. 'runs/*.csv'), the file's path as the job's id.")
@click.option("--scheduler", metavar="ADDRESS",
              help="A running Dask scheduler (tcp://host:port); by default a local cluster.")
@click.option("--workers", type=click.IntRange(min=1), default=min(2, os.cpu_count() or 1),
              show_default=True, help="Worker processes of the local cluster.")
@click.option("--force", is_flag=True, help="Run every job again (the output starts empty).")
@click.option("--retry-errors", is_flag=True,
              help="Run again the jobs whose line is an error or a failure.")
@click.option("--quiet", is_flag=True, help="No progress on standard error.")
@click.option("--strategy", type=click.Choice(STRATEGIES), help="With --data-glob: as solve's.")
@click.option("--formulation", type=click.Choice(FORMULATIONS),
              help="With --data-glob: as solve's.")
@model_inputs
@user_errors
def batch(source: str, output: str, data_glob: str | None, scheduler: str | None,
          workers: int, force: bool, retry_errors: bool, quiet: bool, strategy: str | None,
          formulation: str | None, data: tuple[str, ...], rows: tuple[str, ...],
          exclude: tuple[str, ...], defines: tuple[str, ...]) -> None:
    """Run many solves on Dask: the jobs of the TOML file SOURCE (docs/batch.md), or the
    model SOURCE once per file of --data-glob. A rerun skips the jobs --output holds; exit 1
    when a job ended in an error or a failure (its line says why)."""
    from calib_dsl.batch.jobs import batch_jobs
    from calib_dsl.batch.schedule import run_batch
    from calib_dsl.batch.summary import render_summary

    jobs = batch_jobs(source, data_glob, strategy=strategy, formulation=formulation,
                      data=data, rows=rows, exclude=exclude, defines=defines)
    lines = run_batch(jobs, output, scheduler=scheduler, workers=workers, force=force,
                      retry_errors=retry_errors,
                      say=(lambda s: None) if quiet else
                      (lambda s: click.echo(f"calibc batch: {s}", err=True)))
    click.echo(render_summary(lines))
    if any(line["status"] in ("error", "failed") for line in lines):
        sys.exit(1)

# `plot`, `export` (calib_dsl/outputs.py), `report` (the handover report) and `plan`
# (calib_dsl/plan/command.py), with this module's handling of user errors
for _command in (outputs.plot, outputs.export, handover_report, plan_command.plan):
    _command.callback = user_errors(_command.callback)  # type: ignore[arg-type]
    main.add_command(_command)
