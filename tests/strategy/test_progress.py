"""Progress of long work: what the callback is told (labels, widths that never grow, time
that never runs back), that telling it changes no result, and that the command line draws
its line only on a terminal and never with --quiet."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from calib_dsl import cli
from calib_dsl.pipeline import load, solve
from calib_dsl.progress import labelled
from calib_dsl.report.progress_line import describe, progress_line
from calib_dsl.studies.simulate import simulate

EXAMPLES = Path(__file__).resolve().parents[2] / "models" / "examples"


class Recorder:
    def __init__(self) -> None:
        self.calls: list[tuple[str, float | None, float]] = []

    def __call__(self, label: str, width: float | None, seconds: float) -> None:
        self.calls.append((label, width, seconds))


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def assert_monotone(calls: list[tuple[str, float | None, float]]) -> None:
    widths = [w for _, w, _ in calls]
    seconds = [t for _, _, t in calls]
    assert all(w is not None and 0 <= w <= 1 for w in widths)  # fractions of the domains
    assert all(a >= b for a, b in zip(widths, widths[1:], strict=False)), widths  # never grows
    assert all(a <= b for a, b in zip(seconds, seconds[1:], strict=False)), seconds


@pytest.mark.parametrize("name", ["circle_fit.cal", "language_tour.cal", "planar_arm.cal"])
def test_tight_reports_its_steps_and_rounds_and_changes_nothing(name):
    prog = load(EXAMPLES / name)
    plain = solve(prog, "tight")
    seen = Recorder()
    watched = solve(prog, "tight", progress=seen)
    assert np.array_equal(plain.lo, watched.lo) and np.array_equal(plain.hi, watched.hi)
    assert (plain.stop, plain.work) == (watched.stop, watched.work)
    labels = [label for label, _, _ in seen.calls]
    assert labels[0] == "start"
    rounds = [label for label in labels if label.startswith("LP round ")]
    assert rounds == [f"LP round {k}" for k in range(1, len(rounds) + 1)]
    assert len(rounds) == watched.lp_rounds + watched.reused_rounds >= 1
    steps = [label for label in labels[1:] if not label.startswith("LP round ")]
    assert steps == ["propagation", "rounds of LPs", "propagation", "split"]
    assert_monotone(seen.calls)
    s = prog.slots  # the line falls exactly when an unknown narrows from a bounded domain
    bounded = [i for i in s.declared if np.isfinite(s.hi[i] - s.lo[i])]
    narrowed = any(watched.hi[i] - watched.lo[i] < s.hi[i] - s.lo[i] for i in bounded)
    assert (seen.calls[-1][1] < seen.calls[0][1]) == narrowed


def test_hc4_reports_start_and_end_and_changes_nothing():
    prog = load(EXAMPLES / "paper_propagation.cal")
    plain = solve(prog, "hc4")
    seen = Recorder()
    watched = solve(prog, "hc4", progress=seen)
    assert np.array_equal(plain.lo, watched.lo) and np.array_equal(plain.hi, watched.hi)
    assert [label for label, _, _ in seen.calls] == ["start", "propagation"]
    assert_monotone(seen.calls)


def test_an_infeasible_solve_reports_no_empty_box(write_model):
    prog = load(write_model("var x in [0, 1];\nvar y in [0, 1];\nvar z in [3, 4];\n"
                            "z == x + y;\n"))
    seen = Recorder()
    assert solve(prog, "tight", progress=seen).status == "infeasible"
    assert [label for label, _, _ in seen.calls] == ["start"]


def test_simulate_reports_its_stages(tmp_path):
    seen = Recorder()
    simulate(EXAMPLES / "planar_arm.cal", 5, 1, out_csv=tmp_path / "c.csv", progress=seen)
    assert [label for label, _, _ in seen.calls] == [
        "elaborated for 5 configurations", "measurements computed", "written"]
    assert all(width is None for _, width, _ in seen.calls)


def test_labelled_prefixes_and_none_stays_none():
    seen = Recorder()
    tell = labelled(seen, "trial 2: ")
    assert tell is not None
    tell("LP round 1", 1.5, 0.25)
    assert seen.calls == [("trial 2: LP round 1", 1.5, 0.25)]
    assert labelled(None, "trial 1: ") is None


# -- the command line's line ---------------------------------------------------------------
def test_the_line_is_drawn_on_a_terminal_only():
    term = FakeTerminal()
    with progress_line("solving", file=term) as progress:
        assert progress is not None
        progress("LP round 2", 0.0123456, 2.44)
    shown = term.getvalue()
    assert "calibc: solving  LP round 2, widths 1.23 % of the domains, 2.4 s" in shown
    assert shown.endswith("\n")
    for quiet, out in ((True, FakeTerminal()), (False, io.StringIO())):
        with progress_line("solving", quiet=quiet, file=out) as progress:
            assert progress is None
        assert out.getvalue() == ""


def test_describe():
    assert describe("start", 1.0, 0.0) == "start, widths 100 % of the domains, 0.0 s"
    assert describe("start", float("inf"), 0.0) == "start, widths +oo of the domains, 0.0 s"
    assert describe("written", None, 1.26) == "written, 1.3 s"


@pytest.mark.parametrize("args", [["solve", EXAMPLES / "circle_fit.cal"],
                                  ["solve", EXAMPLES / "circle_fit.cal", "--quiet"],
                                  ["simulate", EXAMPLES / "planar_arm.cal", "--configs", "4",
                                   "-o", "{out}"]])
def test_no_progress_when_stderr_is_not_a_terminal(args, tmp_path):
    argv = [str(a).replace("{out}", str(tmp_path / "c.csv")) for a in args]
    res = CliRunner().invoke(cli.main, argv, catch_exceptions=False)
    assert res.exit_code == 0
    assert "calibc: solving" not in res.stderr and "calibc: simulating" not in res.stderr
    assert "widths" not in res.stderr and "\r" not in res.stderr


def test_the_meter_adds_fractions_of_the_domains_never_units():
    """Millimetres and radians are never added: each unknown counts as the fraction of its
    own search domain the box keeps; an unbounded domain counts 1 until the box bounds it,
    then relative to that first width; a point domain is left out."""
    import numpy as np

    from calib_dsl.progress import Meter

    seen = Recorder()
    lo, hi = np.array([0.0, 0.0, -np.inf, 1.0]), np.array([1000.0, 0.01, np.inf, 1.0])
    meter = Meter.over(seen, np.arange(4), lo, hi)
    meter("start", lo, hi)
    meter("half", np.array([0.0, 0.0, -1.0, 1.0]), np.array([500.0, 0.005, 1.0, 1.0]))
    meter("mm only", np.array([0.0, 0.0, -1.0, 1.0]), np.array([1.0, 0.01, 1.0, 1.0]))
    meter("bounded", np.array([0.0, 0.0, -0.5, 1.0]), np.array([1.0, 0.01, 0.5, 1.0]))
    assert [w for _, w, _ in seen.calls] == pytest.approx([1.0, 2 / 3, 2.001 / 3, 1.501 / 3])
