"""The Python API (calib_dsl/api.py): what `load` makes of its inputs, that a result says what
`calibc solve --json` says, inconsistent data, the lazy re-export from `calib_dsl`. Its guide
(docs/api.md) runs as doctests in test_api_doc.py."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import pytest
from click.testing import CliRunner

import calib_dsl as cal
from calib_dsl import api, cli
from calib_dsl.elaborate.rows import RowRange
from calib_dsl.elaborate.values import Values

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "models" / "examples"
ARM = EXAMPLES / "planar_arm.cal"
INFEASIBLE = "var x in [0, 1];\nvar y in [0, 1];\nvar z in [3, 4];\nz == x + y;\n"


def test_load_turns_python_values_into_the_command_lines_inputs():
    three = {"q1": [0.1, 0.2, 0.3], "q2": [0.2] * 3, "x": [1.3] * 3, "y": [0.3] * 3}
    p = cal.load(ARM, data=three, defines={"e": 0.1}, rows="1..3", exclude=[2])
    assert isinstance(p.inputs.data[""], Values)
    assert p.inputs.consts == {"e": "0.1"} and p.consts["e"] == Fraction(1, 10)
    assert p.inputs.rows[""].ranges == (RowRange(1, 3),) and p.inputs.rows[""].excluded == (2,)
    assert p.model.tables[0].numbers == [1, 3]
    assert cal.load(ARM, defines={"e": Fraction(1, 3)}).consts["e"] == Fraction(1, 3)
    assert cal.load(ARM, defines={"e": "2e-4"}).consts["e"] == Fraction(1, 5000)
    by_name = cal.load(ARM, tables={"m": str(EXAMPLES / "planar_arm.csv")}, rows=[2, 4])
    assert by_name.model.tables[0].numbers == [2, 4]


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"rows": "1..x"}, "rows '1..x': '1..x' is not a row range"),
    ({"exclude": "a"}, "exclude 'a'"),
    ({"defines": {"nope": 1}}, "the model has no const 'nope'"),
    ({"tables": {"n": [[1.0, 2.0, 3.0, 4.0]]}}, "given for table 'n', but the model has "
                                                 "tables m"),
    ({"data": EXAMPLES / "missing.csv"}, "not found"),
])
def test_bad_inputs_raise_a_cal_error(kwargs, message):
    with pytest.raises(cal.CalError) as err:
        cal.load(ARM, **kwargs)
    assert message in err.value.render()


def test_the_result_is_what_the_command_prints(untimed):
    got = cal.solve(cal.load(ARM))
    res = CliRunner().invoke(cli.main, ["solve", str(ARM), "--json", "-"],
                             catch_exceptions=False)
    assert res.exit_code == 0
    printed = json.loads(res.stdout)
    mine = got.as_json()
    del printed["provenance"]  # (the command line's: what ran, where, when)
    assert untimed(mine) == untimed({**printed, "model": str(ARM)})
    for p in got.parameters:
        row = printed["parameters"][p.name]
        assert list(p.result) == row["result"] and list(p.domain) == row["domain"]
        assert p.true == row["true"] and p.identifiable == row["identifiable"]
        assert p.width == p.result[1] - p.result[0]
        assert p.contraction == pytest.approx(p.width / (p.domain[1] - p.domain[0]))
    assert list(got.narrowed) == printed["narrowed"] == ["l1", "l2"]
    text = CliRunner().invoke(cli.main, ["solve", str(ARM)], catch_exceptions=False).stdout
    strip = [ln for ln in text.splitlines() if not ln.startswith("time: ")]
    assert [ln for ln in got.text().splitlines() if not ln.startswith("time: ")] == strip


def test_options_reach_the_solver():
    p = cal.load(ARM)
    hc4 = cal.solve(p, "hc4", identify=False, lsq=True)
    assert hc4.strategy == "hc4" and hc4.lp_rounds == 0
    assert hc4["l1"].identifiable is None and hc4["l1"].least_squares == pytest.approx(1.0)
    assert cal.solve(p, "hc4", max_sweeps=1).sweeps == 1
    with pytest.raises(KeyError, match="no declared unknown 'l3'"):
        hc4["l3"]


def test_inconsistent_data(tmp_path):
    model = tmp_path / "bad.cal"
    model.write_text(INFEASIBLE)
    res = cal.solve(cal.load(model))
    assert res.status == "infeasible" and res.conflict is None  # no table: no rows to name
    assert all(p.result is None and p.width is None for p in res.parameters)
    q1, q2 = [0.1, 0.7, 1.3], [0.5, -0.4, 1.1]
    x = [math.cos(a) + 0.5 * math.cos(a + b) for a, b in zip(q1, q2, strict=True)]
    y = [math.sin(a) + 0.5 * math.sin(a + b) for a, b in zip(q1, q2, strict=True)]
    y[1] += 0.01  # 1 cm off: no arm meets this row within 1e-4
    arm = cal.load(ARM, data={"q1": q1, "q2": q2, "x": x, "y": y})
    res = cal.solve(arm)
    assert res.status == "infeasible"
    assert res.conflict is not None and [r.row for r in res.conflict.rows] == [2]
    assert "inconsistent" in res.text() and res.as_json()["conflict"]["rows"]
    with pytest.raises(cal.Inconsistent):
        cal.predict(arm, EXAMPLES / "planar_arm.csv")


def test_the_package_imports_the_api_on_first_use():
    code = ("import sys, calib_dsl; assert 'calib_dsl.api' not in sys.modules; "
            "calib_dsl.load; assert 'calib_dsl.api' in sys.modules; "
            "assert calib_dsl.listing is calib_dsl.api.listing")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)
    assert set(cal.__all__) == set(api.__all__)
    with pytest.raises(AttributeError):
        cal.no_such_name  # noqa: B018


def test_results_compare_by_their_numbers():
    p = cal.load(ARM)
    a, b = cal.solve(p, "hc4", identify=False), cal.solve(p, "hc4", identify=False)
    assert a.parameters == b.parameters and a != cal.solve(p, "tight", identify=False)


def test_solve_with_outliers_names_the_moved_row(tmp_path):
    (tmp_path / "d.csv").write_text("x,v\n0,0.1\n1,0.6\n2,1.1\n3,3.0\n4,2.1\n5,2.6\n")
    (tmp_path / "line.cal").write_text(
        "param p in [0, 1]; param q in [-1, 1];\n"
        'table m = "d.csv" { x : +- 1e-9; v : +- 0.01; }\n'
        "for k in 1..rows(m) { m.v[k] == p * m.x[k] + q; }\n")
    got = cal.solve(cal.load(tmp_path / "line.cal"), outliers=1)
    assert got.status == "contracted" and [r.row for r in got.outliers.certain] == [4]
    assert got.as_json()["outliers"]["certain"] == [4]
    assert "outliers (at most 1 row): certain" in got.text()
    lo, hi = got["p"].result
    assert lo <= 0.5 <= hi and hi - lo < 0.02
