"""The command line under bad inputs: whatever the subcommand, the model, the data and the
options, calibc exits 0, 1, 2 or 4 (a verdict: consistent, inconsistent, undecided; or a user
error) and never prints a traceback (exit 3 is an internal error: a bug). The inputs of
issue 40 are among the examples; hypothesis draws the rest from the same parts (a bounded
number of cases: the test runs in seconds)."""

from __future__ import annotations

import hashlib
import math
import os
from pathlib import Path

import pytest
from batch_project import FILES
from click.testing import CliRunner
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from calib_dsl import cli

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "models" / "examples"
FIXED = """const k = 1e-3;
param a in 1 +- k;
param b in [0, 2] true 1;
table m = "line.csv" { x : +- 0; y : +- 0.01; }
for i in 1..rows(m) { m.y[i] == a * m.x[i] + b; }
"""
HUGE_ROWS = "\n".join(f"{1e154 * (1 + 3 * math.cos(1.1 * k))!r},"
                      f"{1e154 * (2 + 3 * math.sin(1.1 * k))!r}" for k in range(6))
WORKSPACE: dict[str, bytes] = {
    "line.cal": FILES["line.cal"].encode(), "a.csv": FILES["a.csv"].encode(),
    "fixed.cal": FIXED.encode(), "line.csv": b"x,y\n0,1\n1,2\n2,3.005\n",
    "F.csv": b"x,y\n100,0\n1,5\n",
    "digits.csv": b"x,y\n0." + b"0" * 5000 + b"1,2\n1,5\n-2,3\n",
    "e308.csv": b"x,y\n1e308,1e308\n1,5\n-2,3\n",
    "huge.csv": b"x,y\n" + HUGE_ROWS.encode() + b"\n",
    "latin1.csv": b"x,y\n1,2\n3,4\n5,\xe96\n",
    "nul.csv": b"x,y\n1,2\n3,4\x00\n",
    "latin1.cal": b"param a in [0, 1];\n# caf\xe9\n",
    "nul.cal": b"param a in [0, 1];\nparam b\x00 in [0, 1];\n",
    "include_dir.cal": b'include "sub";\nparam a in [0, 1];\n',
    "unbounded.cal": b"param a in [-oo, oo];\nparam b in [0, 1];\na >= b;\n",
    "huge.cal": (EXAMPLES / "circle_fit.cal").read_bytes()
    .replace(b"[-10, 10]", b"[-1e155, 1e155]").replace(b"[0, 10]", b"[0, 1e155]"),
    "not_json.json": b"{ nope",
}
MODELS = [str(EXAMPLES / "circle_fit.cal"), str(EXAMPLES / "paper_propagation.cal"),
          str(EXAMPLES / "paper_cse.cal"), "line.cal", "fixed.cal", "latin1.cal", "nul.cal",
          "include_dir.cal", "unbounded.cal", "huge.cal", "missing.cal", "sub"]
DATA = ["a.csv", "line.csv", "F.csv", "digits.csv", "e308.csv", "huge.csv", "latin1.csv",
        "nul.csv", "missing.csv", "sub"]
DEFINES = ["e=0", "k=0", "e=1e308", "e=-1", "k=nan", "x=1", "e=1e-400", "e="]
SEEDS = [  # the repros of issue 40, as arguments
    ["validate", str(EXAMPLES / "circle_fit.cal"), "--at", "F.csv", "-q"],
    ["predict", "line.cal", "--at", "a.csv", "--at-rows", "1..2", "--csv", "p.csv", "-q"],
    ["solve", str(EXAMPLES / "paper_propagation.cal"), "--json", "-", "-q"],
    ["predict", str(EXAMPLES / "circle_fit.cal"), "--at", "F.csv", "--json", "-", "-q"],
    ["solve", "fixed.cal", "-D", "k=0", "--lsq", "-q"],
    ["identify", "fixed.cal", "-D", "k=0"],
    ["solve", str(EXAMPLES / "circle_fit.cal"), "--data", "digits.csv", "-q"],
    ["identify", "huge.cal", "--data", "huge.csv"],
    ["solve", "huge.cal", "--data", "huge.csv", "-q", "--lsq"],
    ["compile", "include_dir.cal"],
    ["compile", "latin1.cal"],
    ["solve", str(EXAMPLES / "circle_fit.cal"), "--data", "latin1.csv", "-q"],
    ["compile", "nul.cal"],
    ["simulate", str(EXAMPLES / "planar_arm.cal"), "--configs", "3", "-o", "-", "-q"],
    ["solve", str(EXAMPLES / "circle_fit.cal"), "--data", "e308.csv", "-q", "--lsq"],
    ["export", "not_json.json", "--format", "json"],
    ["solve", "line.cal", "--min-error", "e", "-q"],
    ["solve", "line.cal", "--residuals", "-q"],
    ["export", "out.json", "--format", "json"],
    ["identify", "unbounded.cal"],
]


@pytest.fixture(scope="module")
def workspace(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("fuzz")
    for name, data in WORKSPACE.items():
        (root / name).write_bytes(data)
    (root / "sub").mkdir()
    _run(root, ["solve", "unbounded.cal", "--json", "out.json", "-q"])  # a result to export
    return root


def _options(command: str) -> st.SearchStrategy[list[str]]:
    data = st.sampled_from(DATA)
    common = [st.tuples(st.just("--data"), data),
              st.tuples(st.just("-D"), st.sampled_from(DEFINES)),
              st.tuples(st.just("--rows"), st.sampled_from(["1..2", "0", "5..1", "x", "1..:0"])),
              st.tuples(st.just("--exclude"), st.sampled_from(["1", "99", "-1", ""]))]
    extra = {
        "solve": [st.tuples(st.just("--json"), st.sampled_from(["-", "out.json"])),
                  st.tuples(st.just("--strategy"), st.just("hc4")),
                  st.tuples(st.just("--lsq")), st.tuples(st.just("--no-identify")),
                  st.tuples(st.just("--residuals")),
                  st.tuples(st.just("--tol"), st.sampled_from(["nan", "-1", "1e308"]))],
        "predict": [st.tuples(st.just("--at"), data), st.tuples(st.just("--json"), st.just("-")),
                    st.tuples(st.just("--csv"), st.just("p.csv"))],
        "validate": [st.tuples(st.just("--at"), data), st.tuples(st.just("--json"), st.just("-"))],
        "identify": [st.tuples(st.just("--json"))],
        "compile": [st.tuples(st.just("--json"))],
    }.get(command, [])
    parts = st.lists(st.one_of(*common, *extra), max_size=3)
    return parts.map(lambda ps: [x for p in ps for x in p])


@st.composite
def command_lines(draw) -> list[str]:
    command = draw(st.sampled_from(["compile", "solve", "identify", "predict", "validate",
                                    "export", "simulate"]))
    if command == "export":
        return ["export", draw(st.sampled_from(["out.json", "not_json.json", "a.csv", "sub",
                                                "missing.json"])),
                "--format", draw(st.sampled_from(["json", "cal", "dh-table", "urdf"]))]
    if command == "simulate":
        return ["simulate", draw(st.sampled_from(MODELS)), "--configs",
                draw(st.sampled_from(["1", "3", "0"])), "-o",
                draw(st.sampled_from(["-", "s.csv", "sub"])), "-q"]
    model = draw(st.sampled_from(MODELS) | st.binary(max_size=40).map(_fuzzed_model))
    quiet = ["-q"] if command in ("solve", "predict", "validate") else []
    args = [command, model, *draw(_options(command)), *quiet]
    if command in ("predict", "validate") and "--at" not in args:
        args += ["--at", draw(st.sampled_from(DATA))]
    return args


def _fuzzed_model(tail: bytes) -> str:
    """A model whose last line is arbitrary bytes, as a file of the workspace."""
    name = f"fz_{hashlib.sha1(tail).hexdigest()[:12]}.cal"
    FUZZED[name] = b"param a in [0, 1];\n" + tail
    return name


FUZZED: dict[str, bytes] = {}


def _run(workspace: Path, args: list[str]):
    for name, data in FUZZED.items():
        path = workspace / name
        if not path.exists():
            path.write_bytes(data)
    old = Path.cwd()
    os.chdir(workspace)
    try:
        return CliRunner().invoke(cli.main, args)
    finally:
        os.chdir(old)


def _check(res, args: list[str]) -> None:
    shown = f"calibc {' '.join(args)!r}: exit {res.exit_code}\n{res.output[-2000:]}"
    assert res.exit_code in (0, 1, 2, 4), shown
    assert res.exception is None or isinstance(res.exception, SystemExit), shown
    assert "Traceback" not in res.output, shown
    assert "internal error" not in res.output, shown


@pytest.mark.parametrize("args", SEEDS, ids=[" ".join(Path(a).name for a in s[:2])
                                             for s in SEEDS])
def test_the_issues_inputs(workspace, args):
    _check(_run(workspace, args), args)


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(command_lines())
@example(["solve", str(EXAMPLES / "paper_propagation.cal"), "--json", "-", "-q"])
@example(["validate", str(EXAMPLES / "circle_fit.cal"), "--at", "F.csv", "-q"])
def test_any_command_line(workspace, args):
    _check(_run(workspace, args), args)
