"""Every JSON document calibc writes parses with a strict parser (no NaN, no Infinity: what
JavaScript, Go and jq reject), whatever the subcommand; the strict writer's convention
(docs/json.md) holds for any value."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest
from batch_project import FILES
from click.testing import CliRunner
from hypothesis import given
from hypothesis import strategies as st

from calib_dsl import cli
from calib_dsl.report.strict_json import dumps, plain, strict_loads

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "models" / "examples"
CIRCLE = EXAMPLES / "circle_fit.cal"
UNBOUNDED = "param a in [-oo, oo];\nparam b in [0, 1];\na >= b;\n"


def run(*args: object):
    return CliRunner().invoke(cli.main, [str(a) for a in args], catch_exceptions=False)


def strict(text: str) -> object:
    return strict_loads(text)


def test_strict_parser_refuses_what_python_writes():
    for bad in ('{"a": NaN}', '[Infinity]', '[-Infinity]'):
        with pytest.raises(ValueError):
            strict(bad)


numbers = st.floats(allow_nan=True, allow_infinity=True)
values = st.recursive(
    st.none() | st.booleans() | st.integers() | numbers | st.text(max_size=5)
    | numbers.map(np.float64) | st.integers(-2**40, 2**40).map(np.int64),
    lambda inner: st.lists(inner, max_size=4) | st.tuples(inner, inner)
    | st.dictionaries(st.text(max_size=4), inner, max_size=4), max_leaves=20)


@given(values)
def test_any_value_is_written_as_strict_json(value):
    back = strict(dumps(value, indent=2))
    assert back == plain(value)  # the convention, and nothing else, changed it


@pytest.mark.parametrize("x, written", [(math.inf, "+oo"), (-math.inf, "-oo"), (math.nan, None),
                                        (np.float64("nan"), None), (np.float64(1.5), 1.5),
                                        (np.int64(3), 3)])
def test_the_convention(x, written):
    assert strict(dumps({"x": x})) == {"x": written}


def write_line(tmp: Path) -> Path:
    for name in ("line.cal", "a.csv"):
        (tmp / name).write_text(FILES[name], encoding="utf-8")
    return tmp / "line.cal"


def outputs_of_every_subcommand(tmp: Path) -> dict[str, str]:
    """The JSON text each subcommand writes, by a label naming the command."""
    (tmp / "unb.cal").write_text(UNBOUNDED, encoding="utf-8")
    (tmp / "F.csv").write_text("x,y\n100,0\n1,5\n", encoding="utf-8")
    out: dict[str, str] = {}
    out["compile --json"] = run("compile", EXAMPLES / "paper_cse.cal", "--json").stdout
    for name in ("paper_propagation.cal", "circle_fit.cal"):
        out[f"solve {name}"] = run("solve", EXAMPLES / name, "--json", "-", "-q").stdout
    out["solve unbounded"] = run("solve", tmp / "unb.cal", "--json", "-", "-q").stdout
    line = write_line(tmp)
    out["solve --min-error"] = run("solve", line, "--min-error", "e", "--json", "-",
                                   "-q").stdout
    out["validate --json"] = run("validate", line, "--at", tmp / "a.csv", "--json", "-",
                                 "-q").stdout
    run("solve", tmp / "unb.cal", "--json", tmp / "unb.json", "-q")
    out["export unbounded"] = run("export", tmp / "unb.json", "--format", "json").stdout
    run("solve", CIRCLE, "--json", tmp / "c.json", "-q")
    out["export circle"] = run("export", tmp / "c.json", "--format", "json").stdout
    out["identify --json"] = run("identify", CIRCLE, "--json").stdout
    out["predict --json"] = run("predict", CIRCLE, "--at", tmp / "F.csv", "--json", "-",
                                "-q").stdout
    return out


@pytest.mark.slow
def test_every_subcommands_json_is_strict(tmp_path):
    for label, text in outputs_of_every_subcommand(tmp_path).items():
        try:
            strict(text)
        except ValueError as err:
            pytest.fail(f"{label} wrote JSON a strict parser rejects: {err}\n{text[:400]}")


def test_the_issues_documents_use_the_convention(tmp_path):
    """paper_propagation's outer/inner ratios are infinite, an unbounded parameter's export
    has no midpoint: written as "+oo" and null, not Infinity and NaN."""
    found = outputs_of_every_subcommand(tmp_path)
    solved = strict(found["solve paper_propagation.cal"])
    assert solved["tightness"]["median_ratio"] == "+oo"
    exported = strict(found["export unbounded"])
    assert exported["parameters"]["a"] == {"value": None, "half_width": "+oo", "nominal": False}
    predicted = json.loads(found["predict --json"])
    assert all(isinstance(v, float | type(None)) for v in predicted["width"].values())


@pytest.mark.skipif(importlib.util.find_spec("distributed") is None,
                    reason="calibc batch runs on Dask: pip install -e .[dev]")
def test_batch_lines_are_strict(tmp_path):
    jobs = tmp_path / "jobs.toml"
    jobs.write_text(f'[[job]]\nid = "p"\nmodel = "{EXAMPLES / "paper_propagation.cal"}"\n',
                    encoding="utf-8")
    res = run("batch", jobs, "-o", tmp_path / "out.jsonl", "--workers", "1", "--quiet")
    assert res.exit_code == 0, res.output
    lines = (tmp_path / "out.jsonl").read_text(encoding="utf-8").splitlines()
    assert [strict(x)["result"]["tightness"]["median_ratio"] for x in lines] == ["+oo"]


def test_the_python_api_document_is_strict_too():
    """`calib_dsl.solve(...).as_json()` is the --json document: any writer writes it strictly."""
    import calib_dsl

    doc = calib_dsl.solve(calib_dsl.load(EXAMPLES / "paper_propagation.cal")).as_json()
    assert doc["tightness"]["median_ratio"] == "+oo"
    strict(json.dumps(doc, allow_nan=False))
