"""A result JSON damaged after the solve wrote it (an end NaN, ends in the wrong order, an
end that is not a number, a field emptied): every export, the figures and the report refuse
it as one user error, exit 2, rather than write or draw a box no solve proved or fail with an
internal error."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import pytest
from cli_run import run

ROOT = Path(__file__).resolve().parents[1]
ARM = ROOT / "models" / "examples" / "planar_arm.cal"
FORMATS = ("cal", "dh-table", "json", "urdf", "cell")


@pytest.fixture(scope="module")
def solved(tmp_path_factory) -> tuple[Path, dict]:
    tmp = tmp_path_factory.mktemp("damaged")
    res = run("solve", ARM, "-D", "e=0.01", "--json", tmp / "ok.json", "-q")
    assert res.exit_code == 0, res.output
    return tmp, json.loads((tmp / "ok.json").read_text())


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("ends", [[math.nan, 1.0], [2.0, 1.0], ["abc", 1.0], [1.0]])
def test_a_damaged_result_is_refused_by_every_export(solved, fmt, ends):
    tmp, doc = solved
    name = next(iter(doc["parameters"]))
    doc["parameters"][name]["result"] = ends
    path = tmp / "damaged.json"
    path.write_text(json.dumps(doc))
    res = run("export", "--format", fmt, path)
    assert res.exit_code == 2
    assert res.output.startswith("error: ") and "damaged.json' is malformed: the result of " \
        in res.output, res.output


READERS = {"plot": ("plot", "-o", "f.png"), "report": ("report", "-o", "r.html")}


@pytest.mark.parametrize("reader", READERS)
@pytest.mark.parametrize("ends", [[math.nan, 1.0], [2.0, 1.0], ["abc", 1.0], [1.0]])
def test_a_damaged_interval_is_refused_by_the_figures_and_the_report(solved, reader, ends):
    """(plot drew, and report wrote, ends in the wrong order as a guaranteed result)"""
    tmp, doc = solved[0], copy.deepcopy(solved[1])
    name = next(iter(doc["parameters"]))
    doc["parameters"][name]["result"] = ends
    (tmp / "damaged.json").write_text(json.dumps(doc))
    command, *options = READERS[reader]
    res = run(command, "damaged.json", *options, cwd=tmp)
    assert res.exit_code == 2, res.output
    errors = [ln for ln in res.output.splitlines() if "error:" in ln]
    assert len(errors) == 1 and "Traceback" not in res.output, res.output
    assert ("damaged.json' is malformed" in errors[0] and "is not an interval" in errors[0]
            or "not strict JSON: NaN" in errors[0]), res.output  # (the report reads strictly)


def test_fields_of_another_type_are_one_error_in_the_figures(solved):
    """(nulls where the figures read objects and numbers were an internal error, exit 3)"""
    tmp, doc = solved
    nulled = {key: (value if key == "parameters" else None) for key, value in doc.items()}
    (tmp / "nulled.json").write_text(json.dumps(nulled))
    res = run("plot", "nulled.json", "-o", "f.png", cwd=tmp)
    assert res.exit_code == 2, res.output
    assert res.output.startswith("error: 'nulled.json' is malformed"), res.output
