"""The `calibc` command line: compile, solve, simulate; exit codes 0 / 1 (infeasible) / 2 (user
error) / 3 (internal error); user errors as `file:line:col: error:` with the line and a caret."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
from pathlib import Path

import pytest
from click.testing import CliRunner
from scipy.optimize import brentq

from calib_dsl import cli
from calib_dsl.pipeline import load

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "models" / "examples"

PAPER_CSE = EXAMPLES / "paper_cse.cal"
PAPER_PROP = EXAMPLES / "paper_propagation.cal"
TOP_KEYS = {"model", "status", "stop", "sweeps", "lp_rounds", "reused_rounds", "seconds",
            "primitives", "formulation", "strategy", "parameters", "narrowed", "split",
            "warnings", "verdict", "decision", "provenance"}
OPTIONAL_TOP = {"emptied", "identifiability", "least_squares", "tightness", "history",
                "residuals"}
PARAM_KEYS = {"kind", "domain", "result", "true", "unit"}
OPTIONAL_PARAM = {"identifiable", "least_squares", "inner", "certified"}
X2_STAR = brentq(lambda x: x**3 - math.sin(x), 0.5, 1.5, xtol=1e-15)  # x1 = sin(x2) = x2^3
X1_STAR = X2_STAR**3
SLACK = 1e-9  # the table prints 10 significant digits
INFEASIBLE = "var x in [0, 1];\nvar y in [0, 1];\nvar z in [3, 4];\n\nz == x + y;\n"


def run(*args: str, cwd: Path | None = None):
    runner = CliRunner()
    if cwd is None:
        return runner.invoke(cli.main, [str(a) for a in args], catch_exceptions=False)
    old = Path.cwd()
    os.chdir(cwd)
    try:
        return runner.invoke(cli.main, [str(a) for a in args], catch_exceptions=False)
    finally:
        os.chdir(old)


def table_row(stdout: str, name: str) -> tuple[str, tuple[float, float] | None]:
    """(search domain text, result) of one row of the solve table."""
    m = re.search(rf"^{re.escape(name)}\s+(\[[^\]]*\])\s+(\[[^\]]*\]|\(empty\))", stdout, re.M)
    assert m, stdout
    if m.group(2) == "(empty)":
        return m.group(1), None
    lo, hi = (float(x.replace("oo", "inf")) for x in m.group(2)[1:-1].split(","))
    return m.group(1), (lo, hi)


# -- compile -----------------------------------------------------------------------------------

def test_compile_json_paper_cse_six_primitives():
    res = run("compile", PAPER_CSE, "--json")
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["primitives"] == 6
    assert data["ops"] == {"add": 2, "cos": 1, "mul": 1, "sin": 1, "sqr": 1}


def test_installed_command_compile_json(calibc, tmp_path):
    # from another directory, as a user would
    proc = subprocess.run([*calibc, "compile", str(PAPER_CSE), "--json"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["primitives"] == 6
    assert proc.stderr == ""


def test_compile_prints_the_listing():
    res = run("compile", PAPER_CSE)
    assert res.exit_code == 0
    assert res.stdout.startswith("# calibc listing of ")
    assert "6 primitives" in res.stdout
    assert re.search(r"^  y2 = i3 \* t\d+\s+# paper_cse\.cal:9$", res.stdout, re.M)


def test_compile_output_file(tmp_path):
    out = tmp_path / "listing.txt"
    res = run("compile", PAPER_CSE, "-o", out)
    assert res.exit_code == 0 and res.stdout == ""
    assert out.read_text(encoding="utf-8") == run("compile", PAPER_CSE).stdout


def test_compile_json_output_file_holds_the_json(tmp_path):
    """-o writes what was asked: with --json, the JSON (and nothing on standard output)."""
    out = tmp_path / "counts.json"
    res = run("compile", PAPER_CSE, "-o", out, "--json")
    assert res.exit_code == 0 and res.stdout == ""
    text = out.read_text(encoding="utf-8")
    assert json.loads(text)["primitives"] == 6
    assert text == run("compile", PAPER_CSE, "--json").stdout


def test_every_option_has_a_help_text():
    import click

    commands = cli.main.commands
    assert {"compile", "solve", "simulate"} <= set(commands)
    for name, command in commands.items():
        options = [p for p in command.params if isinstance(p, click.Option)]
        assert options, name
        for option in options:
            assert (option.help or "").strip(), f"calibc {name} {'/'.join(option.opts)}"


def test_compile_formulation_rotation():
    rot = run("compile", EXAMPLES / "planar_arm.cal", "--formulation", "rotation")
    mat = run("compile", EXAMPLES / "planar_arm.cal")
    assert rot.exit_code == mat.exit_code == 0
    assert "(formulation: rotation)" in rot.stdout and "(formulation: matrix)" in mat.stdout
    # two rotations per row: the loop's body once (5 rows), or each row's with --unroll
    assert len(re.findall(r"^    \(.+\) = rot\(.+, \(\S+, \S+\)\)  ", rot.stdout, re.M)) == 2
    unrolled = run("compile", EXAMPLES / "planar_arm.cal", "--formulation", "rotation",
                   "--unroll")
    assert len(re.findall(r"^  \(.+\) = rot\(.+, \(\S+, \S+\)\)  ", unrolled.stdout,
                          re.M)) == 10
    assert "rot(" not in mat.stdout
    bad = run("compile", PAPER_CSE, "--formulation", "angles")
    assert bad.exit_code == 2  # click's own usage error


# -- solve ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("strategy", ["hc4", "tight"])
def test_solve_paper_propagation(strategy):
    res = run("solve", PAPER_PROP, "--strategy", strategy)
    assert res.exit_code == 0, res.output
    for name, star in (("x1", X1_STAR), ("x2", X2_STAR)):
        dom, (lo, hi) = table_row(res.stdout, name)
        assert dom == "[-oo, +oo]"
        assert lo <= -star + SLACK and star - SLACK <= hi
        assert abs(hi - star) < 1e-3 and abs(lo + star) < 1e-3
    assert "status: contracted" in res.stdout
    assert f"strategy: {strategy}" in res.stdout


def test_solve_default_strategy_is_tight():
    res = run("solve", PAPER_PROP)
    assert "strategy: tight" in res.stdout and "LP rounds:" in res.stdout


@pytest.mark.parametrize("opts, stop", [
    (["--tol", "0"], "fixed point"), (["--tol", "0.5"], "tolerance"),
    (["--max-sweeps", "1"], "max sweeps"), (["--tol", "0", "--max-sweeps", "3"], "max sweeps")])
def test_solve_stop_options(opts, stop):
    res = run("solve", PAPER_PROP, "--strategy", "hc4", *opts)
    assert res.exit_code == 0
    assert f"stopped: {stop}\n" in res.stdout
    if opts[-2:] == ["--max-sweeps", "3"]:
        assert "sweeps: 3\n" in res.stdout


@pytest.mark.parametrize("opts", [["--tol", "-1"], ["--max-sweeps", "0"],
                                  ["--strategy", "simplex"]])
def test_solve_rejects_bad_options(opts):
    res = run("solve", PAPER_PROP, *opts)
    assert res.exit_code == 2
    assert "Traceback" not in res.output


def test_solve_json_file(tmp_path):
    out = tmp_path / "r.json"
    res = run("solve", PAPER_PROP, "--strategy", "hc4", "--json", out)
    assert res.exit_code == 0
    assert "status: contracted" in res.stdout  # the table is still printed
    data = json.loads(out.read_text(encoding="utf-8"))
    assert TOP_KEYS <= set(data) <= TOP_KEYS | OPTIONAL_TOP
    assert "emptied" not in data
    assert data["status"] == "contracted"
    assert data["strategy"] == "hc4" and data["formulation"] == "matrix"
    assert isinstance(data["sweeps"], int) and data["sweeps"] >= 1
    assert isinstance(data["seconds"], float) and data["seconds"] >= 0
    assert data["primitives"] == 2
    assert list(data["parameters"]) == ["x1", "x2"]
    for name, star in (("x1", X1_STAR), ("x2", X2_STAR)):
        p = data["parameters"][name]
        assert PARAM_KEYS <= set(p) <= PARAM_KEYS | OPTIONAL_PARAM
        assert p["domain"] == ["-oo", "+oo"]
        lo, hi = p["result"]
        assert lo <= -star and star <= hi and hi - star < 1e-3
        assert p["true"] is None and p["kind"] == "var"


def test_solve_says_when_no_parameter_was_narrowed(write_model, tmp_path):
    # y = x^2 over x in [-1, 1], y in [0, 1]: every x and every y has a partner
    # (an equation between unknowns holds at no floating-point point that is not exact: no
    # point is certified, and the verdict says so, with exit 4)
    model = write_model("param x in [-1, 1];\nvar y in [0, 1];\ny == x * x;\n")
    out = tmp_path / "r.json"
    res = run("solve", model, "--strategy", "hc4", "--json", out)
    assert res.exit_code == 4
    assert res.stdout.startswith("VERDICT: UNDECIDED")
    assert "calibc: UNDECIDED" in res.stderr
    assert "note: no parameter was narrowed" in res.stdout
    data = json.loads(out.read_text(encoding="utf-8"))
    assert data["narrowed"] == [] and data["verdict"] == "undecided"


@pytest.mark.parametrize("strategy", ["hc4", "tight"])
def test_solve_lists_the_narrowed_parameters(write_model, tmp_path, strategy):
    model = write_model("param x in [-1, 1];\nparam u in [0, 1];\nvar y in [0.5, 2];\n"
                        "y == sin(x);\n")
    out = tmp_path / "r.json"
    res = run("solve", model, "--strategy", strategy, "--json", out)
    assert res.exit_code == 0
    assert "no parameter was narrowed" not in res.stdout
    assert json.loads(out.read_text(encoding="utf-8"))["narrowed"] == ["x", "y"]


def test_solve_json_stdout_is_only_json():
    res = run("solve", PAPER_PROP, "--strategy", "hc4", "--json", "-")
    assert res.exit_code == 0
    data = json.loads(res.stdout)
    assert data["status"] == "contracted"


def test_solve_json_half_infinite_result(write_model, tmp_path):
    model = write_model("var x in [0, 1];\nvar w in [-oo, 5];\nw >= x;\n")
    out = tmp_path / "r.json"
    assert run("solve", model, "--strategy", "hc4", "--json", out).exit_code == 0
    w = json.loads(out.read_text(encoding="utf-8"))["parameters"]["w"]
    assert w["domain"] == ["-oo", 5.0]
    assert w["result"] == [0.0, 5.0]


@pytest.mark.parametrize("strategy", ["hc4", "tight"])
def test_solve_infeasible_exit_1(write_model, tmp_path, strategy):
    model = write_model(INFEASIBLE)
    out = tmp_path / "r.json"
    res = run("solve", model, "--strategy", strategy, "--json", out)
    assert res.exit_code == 1
    assert "status: infeasible" in res.stdout
    assert table_row(res.stdout, "x") == ("[0, 1]", None)
    line = res.stdout.strip().splitlines()[-1]
    assert line.startswith(f"{model}:5:1: ")
    assert "the domain of z became empty" in line and "z = x + y" in line
    data = json.loads(out.read_text(encoding="utf-8"))
    assert data["status"] == "infeasible" and data["stop"] == "empty"
    assert all(p["result"] is None for p in data["parameters"].values())
    assert data["parameters"]["z"]["domain"] == [3.0, 4.0]
    assert data["emptied"] == {"variable": "z", "location": f"{model}:5:1",
                               "primitive": "z = x + y"}
    assert TOP_KEYS | {"emptied"} <= set(data) <= TOP_KEYS | OPTIONAL_TOP


def test_solve_infeasible_constant_sum(write_model):
    model = write_model("var x in [0, 1];\nvar y in [0, 1];\nx + y == 3;\n")
    res = run("solve", model, "--strategy", "hc4")
    assert res.exit_code == 1
    assert re.search(rf"^{re.escape(str(model))}:3:1: the data and the model are inconsistent",
                     res.stdout, re.M)


def test_solve_empty_before_any_sweep(write_model, tmp_path):
    # x in [0, 1] and x == 3: empty at compile time; the table shows the declared domain
    model = write_model("var x in [0, 1];\nvar y in [0, 1];\n\nx == 3;\n")
    out = tmp_path / "r.json"
    res = run("solve", model, "--strategy", "hc4", "--json", out)
    assert res.exit_code == 1
    assert table_row(res.stdout, "x") == ("[0, 1]", None)
    assert "sweeps: 0\n" in res.stdout
    assert "the domain of x became empty" in res.stdout
    data = json.loads(out.read_text(encoding="utf-8"))
    assert data["parameters"]["x"]["domain"] == [0.0, 1.0]
    assert data["emptied"]["variable"] == "x" and data["sweeps"] == 0


def test_solve_true_values_marked():
    res = run("solve", EXAMPLES / "planar_arm.cal", "--strategy", "hc4")
    assert res.exit_code == 0
    for name in ("l1", "l2"):
        assert re.search(rf"^{name}\s.*true inside", res.stdout, re.M)
    assert "TRUE VALUE OUTSIDE" not in res.stdout


# -- --data ------------------------------------------------------------------------------------

DATA_MODEL = ("param p in [0, 1];\ntable m = \"a.csv\" { v : +- 0.01; }\n"
              "for k in 1..rows(m) { p == m.v[k]; }\n")


def test_data_option_replaces_the_models_csv(write_model, tmp_path):
    model = write_model(DATA_MODEL, files={"a.csv": "v\n0.5\n0.505\n"})
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "b.csv").write_text("w,v\n9,0.25\n", encoding="utf-8")
    own = run("solve", model, "--strategy", "hc4")
    _, (lo, hi) = table_row(own.stdout, "p")
    assert lo <= 0.5 and 0.505 <= hi and hi - lo < 0.02
    # --data is relative to the current directory, not to the model
    other = run("solve", model, "--strategy", "hc4", "--data", "other/b.csv", cwd=tmp_path)
    assert other.exit_code == 0, other.output
    _, (lo, hi) = table_row(other.stdout, "p")
    assert lo <= 0.25 <= hi and hi - lo < 0.03
    listing = run("compile", model, "--data", "other/b.csv", cwd=tmp_path)
    assert listing.exit_code == 0 and "p  in [0.24" in listing.stdout


def test_data_option_missing_file(write_model, tmp_path):
    model = write_model(DATA_MODEL, files={"a.csv": "v\n0.5\n"})
    res = run("solve", model, "--data", tmp_path / "missing.csv")
    assert res.exit_code == 2
    assert "missing.csv" in res.stderr and "not found" in res.stderr
    assert "Traceback" not in res.output


# -- user errors ---------------------------------------------------------------------------------

ERRORS = [  # (model source, extra files, file the error is in, line, col, message part)
    ("var x in [0, 1];\nx == (1 + ;\n", {}, "m.cal", 2, 11, "unexpected ';'"),
    ("var x;\nx == yy + 1;\n", {}, "m.cal", 2, 6, "unknown name 'yy'"),
    ("var x in [2, 1];\n", {}, "m.cal", 1, 10, "empty interval"),
    ("param p in [0, 1];\ntable m = \"nope.csv\" { a : +- 0; }\n"
     "for k in 1..rows(m) { p == m.a[k]; }\n", {}, "m.cal", 2, 11, "nope.csv' not found"),
    ("param p in [0, 1];\ntable m = \"d.csv\" { a : +- 0.1; }\n"
     "for k in 1..rows(m) { p == m.a[k]; }\n", {"d.csv": "a\n0.5\nnan\n"}, "d.csv", 3, 1,
     "'nan' is not a finite number"),
]


@pytest.mark.parametrize("command", ["compile", "solve"])
@pytest.mark.parametrize("src, files, where, line, col, message", ERRORS,
                         ids=["syntax", "unknown-name", "empty-interval", "missing-csv", "nan"])
def test_user_errors(write_model, tmp_path, command, src, files, where, line, col, message):
    model = write_model(src, files=files)
    res = run(command, model)
    assert res.exit_code == 2
    assert res.stdout == ""
    assert "Traceback" not in res.stderr
    lines = res.stderr.splitlines()
    m = re.match(r"(\S+):(\d+):(\d+): error: (.*)", lines[0])
    assert m, res.stderr
    assert Path(m.group(1)) == tmp_path / where
    assert (int(m.group(2)), int(m.group(3))) == (line, col)
    assert message in m.group(4)
    source = (tmp_path / where).read_text(encoding="utf-8").splitlines()[line - 1]
    assert lines[1] == "    " + source
    assert lines[2] == "    " + " " * (col - 1) + "^"


def test_user_error_through_the_installed_command(calibc, write_model):
    model = write_model("var x;\nx == yy + 1;\n")
    proc = subprocess.run([*calibc, "solve", str(model)], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.startswith(f"{model}:2:6: error: unknown name 'yy'")
    assert "Traceback" not in proc.stderr and proc.stdout == ""


def test_missing_model_file(tmp_path):
    res = run("compile", tmp_path / "absent.cal")
    assert res.exit_code == 2
    assert "Traceback" not in res.output


@pytest.mark.parametrize("args", [["compile", str(PAPER_CSE), "-o"],
                                  ["solve", str(PAPER_PROP), "--strategy", "hc4", "--json"]])
def test_unwritable_output_is_a_user_error(tmp_path, args):
    res = run(*args, tmp_path / "no" / "such" / "dir" / "out.txt")
    assert "internal error" not in res.stderr
    assert res.exit_code == 2


def test_internal_error_exit_3(monkeypatch):
    import calib_dsl.problem

    def boom(model):
        raise RuntimeError("boom")

    monkeypatch.setattr(calib_dsl.problem, "compile_model", boom)
    monkeypatch.delenv("CALIBC_DEBUG", raising=False)
    res = run("compile", PAPER_CSE)
    assert res.exit_code == 3
    assert "calibc: internal error: RuntimeError: boom" in res.stderr
    assert "Traceback" not in res.stderr
    monkeypatch.setenv("CALIBC_DEBUG", "1")
    res = run("compile", PAPER_CSE)
    assert res.exit_code == 3 and "Traceback" in res.stderr


# -- broken pipe -------------------------------------------------------------------------------

@pytest.mark.parametrize("args", [
    pytest.param(["solve", str(PAPER_PROP), "--strategy", "hc4"], marks=pytest.mark.slow),
    pytest.param(["solve", str(PAPER_PROP), "--json", "-"], marks=pytest.mark.slow),
    ["compile", str(EXAMPLES / "planar_arm.cal")]])
def test_reader_gone_before_output(calibc, args):
    proc = subprocess.Popen([*calibc, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader leaves before anything is written
    err = proc.stderr.read().decode()
    code = proc.wait(timeout=60)
    assert "internal error" not in err and "Traceback" not in err and "Exception" not in err
    assert code == 0


def test_head_one_on_a_long_listing(calibc):
    # like `calibc compile models/rx90_lengths.cal | head -1`: the listing is far longer than
    # a pipe buffer, the reader leaves after one line
    proc = subprocess.Popen([*calibc, "compile", str(ROOT / "models" / "rx90_lengths.cal")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    first = proc.stdout.readline().decode()
    proc.stdout.close()
    err = proc.stderr.read().decode()
    code = proc.wait(timeout=120)
    assert first.startswith("# calibc listing of ")
    assert "internal error" not in err and "Traceback" not in err and "Exception" not in err
    assert code == 0


# -- simulate, then solve against the simulated data ---------------------------------------------

def test_simulate_then_solve(tmp_path):
    out = tmp_path / "sim.csv"
    res = run("simulate", EXAMPLES / "planar_arm.cal", "--configs", "4", "--seed", "3",
              "-o", out)
    assert res.exit_code == 0, res.output
    assert "wrote 4 configurations" in res.stdout
    header, *rows = out.read_text(encoding="utf-8").strip().splitlines()
    assert {"q1", "q2", "x", "y"} <= set(header.split(",")) and len(rows) == 4
    solved = run("solve", EXAMPLES / "planar_arm.cal", "--strategy", "hc4", "--data", out)
    assert solved.exit_code == 0, solved.output
    for name, true in (("l1", 1.0), ("l2", 0.5)):
        _, (lo, hi) = table_row(solved.stdout, name)
        assert lo <= true <= hi and hi - lo < 0.01


def test_version():
    res = run("--version")
    assert res.exit_code == 0 and "0.1.0" in res.stdout


@pytest.mark.slow
@pytest.mark.parametrize("cap", [1, 4])
def test_max_sweeps_caps_the_tight_strategy(cap, tmp_path):
    """--max-sweeps caps the sweeps of the whole tight solve (its propagations and rounds
    together), and a capped solve still holds the truth. Caps 9 and 1000 (nearer a whole
    solve) run in bench/checks/test_max_sweeps.py."""
    capped_solve_holds_the_truth(cap, tmp_path)


def capped_solve_holds_the_truth(cap, tmp_path):
    out = run("solve", ROOT / "models" / "rx90_lengths.cal", "--max-sweeps", cap, "--json",
              tmp_path / "r.json", "-q", "--no-inner")
    assert out.exit_code == 0, out.output
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["sweeps"] <= cap
    if data["stop"] == "max sweeps":
        assert data["sweeps"] == cap
    truth = load(ROOT / "models" / "rx90_lengths.cal").true_values  # the data's
    for name, p in data["parameters"].items():
        lo, hi = p["result"]
        assert lo <= truth[name] <= hi, (cap, name)


def test_known_parameters_are_named_not_listed_unless_all(tmp_path):
    """A curvature known to +-1e-5 that the data (+-0.05) cannot improve is named on one line
    (--all lists it); the line's two narrowed parameters stay listed. Test A's 19 known
    parameters run in bench/checks/test_known_parameters.py."""
    (tmp_path / "d.csv").write_text("x,v\n" + "".join(
        f"{x},{0.2 * x + 0.1 + 0.1 * x * x:.4f}\n" for x in range(6)))
    (tmp_path / "m.cal").write_text(
        "param a in [-2, 2]; param b in [-2, 2]; param c in [0.09999, 0.10001];\n"
        'table m = "d.csv" { x : +- 1e-12; v : +- 0.05; }\n'
        "for i in 1..rows(m) { a * m.x[i] + b + c * m.x[i] * m.x[i] == m.v[i]; }\n")
    short = run("solve", tmp_path / "m.cal", "--no-inner")
    every = run("solve", tmp_path / "m.cal", "--no-inner", "--all")
    assert short.exit_code == every.exit_code == 0, short.output
    assert table_row(every.stdout, "c")[0] == "[0.09999, 0.10001]"
    assert not re.search(r"^c\s", short.stdout, re.M)
    assert re.search(r"^\(1 more kept their whole search domain, not shown: c; --all lists them\)$",
                     short.stdout, re.M)
    assert "more kept" not in every.stdout
    for name in ("a", "b"):
        table_row(short.stdout, name)
    assert short.stdout.startswith("verdict: consistent: ")
