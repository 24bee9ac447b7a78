"""What the command line writes beside a result's report: figures (`calibc plot`, `--plot`),
residual ranges (`solve --residuals`), exports (`calibc export`, `solve --export-domains`);
and the shape of the campaign `calibc simulate` writes (`campaign_options`).
cli.py registers the two commands and calls the rest; kept apart so that the command line's
module stays one a reader can hold."""

from __future__ import annotations

import sys
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import click
from click.exceptions import NoArgsIsHelpError

from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.status import Status
from calib_dsl.plot.figure import CHOICES as PLOT_KINDS
from calib_dsl.report.export_point import POINTS as EXPORT_POINTS
from calib_dsl.report.exports import EXPORTS

PLOT = click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
                    help="Also draw the result's figures into this file (.png, .svg or .pdf; "
                         "needs matplotlib: pip install calibc[plot]).")


class Calibc(click.Group):
    """The command group, keeping the arguments it was run with (a result's provenance
    names the command that made it, also when run in-process, as tests and scripts do)."""

    argv: list[str] = []

    def main(self, args: Any = None, *rest: Any, **kwargs: Any) -> Any:
        self.argv = list(sys.argv[1:] if args is None else args)
        return super().main(args, *rest, **kwargs)

    # An option's bad value is a user error like any other: one `error: ...` line, exit 2
    # (click's own report is three lines: usage, a hint and the message). The group's own
    # options are parsed in make_context, a command's (and its name) in invoke.
    def make_context(self, *args: Any, **kwargs: Any) -> click.Context:
        with _one_line():
            return super().make_context(*args, **kwargs)

    def invoke(self, ctx: click.Context) -> Any:
        with _one_line():
            return super().invoke(ctx)


class OneLineUsageError(click.UsageError):
    """click's usage error, shown as one line naming where help is."""

    def show(self, file: Any = None) -> None:
        where = f" (see '{self.ctx.command_path} --help')" if self.ctx else ""
        message = " ".join(self.format_message().split())
        click.echo(f"error: {message}{where}", file=file or sys.stderr)


@contextmanager
def _one_line() -> Iterator[None]:
    try:
        yield
    except (OneLineUsageError, NoArgsIsHelpError):  # (no command given: the help is the answer)
        raise
    except click.UsageError as err:
        raise OneLineUsageError(err.format_message(), err.ctx) from None


def solve_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """solve's --residuals, --plot, --export-domains, --report."""
    options = [
        click.option("--residuals", is_flag=True,
                     help="Also enclose measured minus predicted over the result, per data "
                          "row (in the JSON; rows left out by --exclude too)."),
        PLOT,
        click.option("--export-domains", "export_domains", type=click.Path(dir_okay=False),
                     help="Also write the result as `param` declarations: the next run's "
                          "search domains."),
        click.option("--report", "report_path", type=click.Path(dir_okay=False),
                     help="Also write the handover report (HTML, self-contained: "
                          "`calibc report`)."),
    ]
    for option in reversed(options):
        fn = option(fn)
    return fn


def campaign_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """simulate's --poses, --repeats, --systematic, --noise, handed to `fn` as one
    `campaign` (studies/campaign.py)."""
    from functools import wraps

    from calib_dsl.studies.campaign import POSES, Campaign

    @wraps(fn)
    def run(*args: Any, poses: str, repeats: int, systematic: float, noise: bool,
            **kwargs: Any) -> Any:
        return fn(*args, campaign=Campaign(poses, repeats, systematic, noise), **kwargs)

    options = [
        click.option("--poses", type=click.Choice(POSES), default=POSES[0], show_default=True,
                     help="The poses (input columns): drawn uniformly, on a grid over their "
                          "ranges, or a few random poses each measured --repeats times."),
        click.option("--repeats", type=click.IntRange(min=1), default=5, show_default=True,
                     help="With --poses repeated: how many times each pose is measured."),
        click.option("--systematic", type=click.FloatRange(min=0.0), default=0.0,
                     show_default=True, metavar="A",
                     help="Add to each measured column a smooth error of the poses (a sum of "
                          "sinusoids of the inputs, drawn from the seed), at most A in size."),
        click.option("--noise/--no-noise", default=True, show_default=True,
                     help="Independent uniform noise within their tolerance on the measured "
                          "columns (the inputs always get theirs)."),
    ]
    for option in reversed(options):
        run = option(run)
    return run


def plot_ready(plot_path: str | None) -> None:
    """Before any work: a figure that cannot be drawn (its format, or no matplotlib) is a
    user error that costs no solve."""
    if plot_path:
        from calib_dsl.plot.backend import file_format, require

        file_format(plot_path)
        require()


def plotted(result: dict[str, Any], plot_path: str | None) -> None:
    if plot_path:
        from calib_dsl.plot.figure import available, save_figure

        if available(result):  # (an infeasible solve: its domains and history only)
            kinds = save_figure(result, plot_path)
            click.echo(f"calibc: drew {', '.join(kinds)} in {plot_path}", err=True)


def residuals(run: Any, quiet: bool) -> dict[str, Any]:
    """The solve JSON's `residuals` (`run`: the SolveReport); its summary printed unless
    `quiet`."""
    from calib_dsl.pipeline import residuals as ranges
    from calib_dsl.report.residuals import render_residuals, residuals_json

    found = residuals_json(*ranges(run.problem, run.prog, run.res))
    if not quiet:
        click.echo(render_residuals(found))
    return found


def export_domains(result: dict[str, Any], path: str | None) -> None:
    from calib_dsl.report.export import domains_cal

    if not path:
        return
    if result["status"] != Status.CONTRACTED:
        click.echo(f"calibc: no domains written to {path}: the data are inconsistent",
                   err=True)
        return
    write(path, domains_cal(result))


def json_out(json_path: str | None, data: dict) -> None:
    """`data` as strict JSON (docs/json.md) to the file json_path, '-' for stdout (None:
    nowhere)."""
    from calib_dsl.report.strict_json import dumps

    if json_path == "-":
        click.echo(dumps(data, indent=2))
    elif json_path:
        write(json_path, dumps(data, indent=2) + "\n")


@contextmanager
def quiet_numerics() -> Iterator[None]:
    """numpy's floating-point warnings (an overflow to inf, an inf - inf) kept off standard
    error: the code handles the inf and NaN they make (every bound stays sound), and a user
    can do nothing with "RuntimeWarning: overflow encountered in matmul"."""
    import numpy as np

    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        yield


def os_error(err: OSError) -> str:
    """An OSError in one line: what failed, and on which file when it names one (an
    output that fails on close names none: "No space left on device" on standard output)."""
    what = err.strerror or str(err) or type(err).__name__
    where = err.filename if err.filename is not None else None
    return f"{where}: {what}" if where else f"cannot write the output: {what}"


def write(path: str, text: str) -> None:
    try:
        Path(path).write_text(text, encoding="utf-8")
    except OSError as err:
        raise CalError(f"cannot write '{path}': {err.strerror or err}") from None


@click.command()
@click.argument("result", type=click.Path())
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True,
              help="The figure's file: .png, .svg or .pdf (the format is the extension's).")
@click.option("--kind", type=click.Choice(PLOT_KINDS), default="all", show_default=True,
              help="The figure to draw (all: every one the result holds data for, one band "
                   "each, in one file).")
def plot(result: str, output: str, kind: str) -> None:
    """Draw the figures of RESULT, a solve's or a validation's JSON, into OUTPUT (needs
    matplotlib: pip install calibc[plot])."""
    from calib_dsl.plot.figure import save_figure
    from calib_dsl.report.as_json import read_result

    data = read_result(result)
    try:
        kinds = save_figure(data, output, kind)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as err:
        # (read_result checks the intervals; another field a hand edit or another program
        # broke is the file's fault, as the report says of it)
        raise CalError(f"'{result}' is malformed: a field the figures read has an unexpected "
                       f"value ({err!r}); write it anew (calibc solve --json)") from None
    click.echo(f"drew {', '.join(kinds)} in {output}")


@click.command()
@click.argument("result", type=click.Path())
@click.option("--format", "fmt", type=click.Choice(tuple(EXPORTS)), required=True,
              help="dh-table, urdf, ur-kinematics (ROS ur_description), json: values with "
                   "guaranteed half-widths for a controller; cell: where the robot stands "
                   "in the measurement set-up; cal: the result as the next run's domains.")
@click.option("-o", "--output", type=click.Path(dir_okay=False),
              help="Write it here (default: standard output).")
@click.option("--model", type=click.Path(dir_okay=False),
              help="The model RESULT was solved from (default: the one it names).")
@click.option("--point", type=click.Choice(EXPORT_POINTS), default="midpoint",
              show_default=True,
              help="The parameter vector written: the result's midpoint, the least-squares "
                   "estimate (solve --lsq) or the certified centre.")
@click.option("--convention", type=click.Choice(("mdh", "dh")),
              help="dh-table: the joints in modified or standard DH (default: the model's).")
def export(result: str, fmt: str, output: str | None, model: str | None, point: str,
           convention: str | None) -> None:
    """Export RESULT, a solve's JSON, for a controller or the next run."""
    from calib_dsl.report import exports
    from calib_dsl.report.as_json import read_result
    from calib_dsl.studies.robot_frames import robot_tables

    job = exports.asked(read_result(result), exports.Request(fmt, model, point, convention))
    tables, units = robot_tables(job.source, job.box, job.point) if job.source else ([], {})
    text = exports.export(job, tables, units)
    if output:
        write(output, text)
    else:
        click.echo(text, nl=False)


def at_selection(at: str, at_rows: str | None, at_skip: str | None) -> Any:
    """The rows of the --at file to predict at (--at-rows, --at-skip), or None: all."""
    from calib_dsl.elaborate.rows import Selection, parse_ranges, select

    if at_rows is None and at_skip is None:
        return None
    try:
        ranges = parse_ranges(at_rows) if at_rows else ()
        skip: tuple[int, ...] = ()
        if at_skip:
            with open(at, encoding="utf-8") as f:
                n = sum(1 for line in f if line.strip()) - 1
            skip = tuple(int(k) + 1 for k in select(Selection(parse_ranges(at_skip)), n))
        return Selection(ranges, skip)
    except (ValueError, OSError) as err:
        raise CalError(f"--at-rows/--at-skip: {err}") from None


def grid_prediction(model: str, spec: str, formulation: str, inputs: Any, strategy: str,
                    progress: Any, settings: Any = None
                    ) -> tuple[Any, list[tuple[float, ...]], list[str]]:
    """`predict --grid SPEC`: the prediction at every pose of the grid (None: the data are
    inconsistent), the poses and the names of their columns (`settings`: the process's
    DEFAULT where None)."""
    import itertools
    import tempfile
    from dataclasses import replace

    from calib_dsl.accuracy.grid import check_size, grid_file, parse_grid
    from calib_dsl.pipeline import predict_at
    from calib_dsl.problem import Problem
    from calib_dsl.settings import DEFAULT

    settings = settings or DEFAULT
    values = parse_grid(spec)
    problem = Problem.load(model, formulation, inputs, settings.fits, settings.sampling)
    if not problem.model.tables:
        raise CalError("the model has no table: there is nothing to predict")
    t = problem.model.tables[0]
    # A measured column's values are not where the robot stands: a grid over one repeats
    # each pose, its predictions alike, as if they were poses of their own.
    measured = [c.name for c in t.columns if c.name in values and c.sim is None]
    if measured:
        inputs_ = (", ".join(c.name for c in t.columns if c.sim is not None)
                   or "none: an input is a column group with `simulate in [lo, hi]`")
        raise CalError(f"--grid: {', '.join(measured)}: a measured column, not an input of "
                       f"the table '{t.name}' (its inputs: {inputs_})")
    layout = problem.program.rows
    check_size(values, layout.width if layout is not None else len(problem.program.slots.names))
    with tempfile.TemporaryDirectory(prefix="calibc-grid-") as tmp:
        path = grid_file(values, t, Path(tmp) / "grid.csv")
        _, found = predict_at(problem, path, strategy=strategy, progress=progress,
                              settings=settings)
    names = [c.name for c in t.columns if c.name in values and not c.derived]
    poses = list(itertools.product(*(values[n] for n in names)))
    return (None if found is None else replace(found, file=f"--grid {spec}")), poses, names


def grid_outputs(model: str, spec: str, formulation: str, inputs: Any, strategy: str,
                 progress: Any) -> tuple[str, dict[str, Any], str]:
    """`predict --grid`: its text, JSON and CSV; exit 1 when the data are inconsistent."""
    import sys

    from calib_dsl.report.prediction import grid_csv, grid_json, render_grid

    found, poses, names = grid_prediction(model, spec, formulation, inputs, strategy,
                                          progress)
    if found is None:
        click.echo("the data are inconsistent (the solve proved it): nothing to predict",
                   err=True)
        sys.exit(1)
    doc = {"model": model, **grid_json(found, poses, names)}
    return render_grid(doc), doc, grid_csv(doc)
