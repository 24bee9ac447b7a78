"""The priors at fault (outliers/prior_faults.py): data inconsistent only because a domain
misses the truth name that domain, never rows; a gross row with right priors names the row."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from calib_dsl import cli
from calib_dsl.pipeline import conflict
from tests.simulated_ur5 import JOINTS, PARAMS, header, simulate_rows, write_table

COLUMNS = ["q1", "q2", "q3", "q4", "q5", "q6", "x", "y", "z"]
TABLE = ('table m = "data.csv" {\n  q1, q2, q3, q4, q5, q6 : +- 0;\n  x, y, z : +- e;\n}\n'
         f"for k in 1..rows(m) {{\n  ur5({JOINTS}) at (tx, ty, tz) == (m.x[k], m.y[k], m.z[k]);"
         "\n}\n")


def _campaign(tmp: Path, true: dict[str, float], moved: float = 0.0) -> Path:
    """40 configurations of the robot with these true values (the rest PARAMS'), row 7's x
    moved by `moved` mm; the model's domains PARAMS' (true values not stated)."""
    rows = simulate_rows(tmp, 40, seed=11, e=0.05, true=true)
    rows[6]["x"] += moved
    write_table(tmp / "data.csv", rows, COLUMNS, lambda r, c: r[c])
    path = tmp / "robot.cal"
    path.write_text(header(0.05, with_true=False) + TABLE, encoding="utf-8")
    return path


@pytest.mark.parametrize(("name", "value"), [("alpha3", 0.0162),
                                           pytest.param("d4", -385.9, marks=pytest.mark.slow)])
def test_a_wrong_prior_is_named_and_no_row_is_blamed(tmp_path: Path, name: str,
                                                      value: float) -> None:
    centre, w, _ = PARAMS[name]
    path = _campaign(tmp_path, {name: value})
    res = CliRunner().invoke(cli.main, ["solve", str(path), "-q", "--json", "-"])
    assert res.exit_code == 1, res.output
    found = json.loads(res.output)["conflict"]
    assert found["rows"] == []
    assert [f["name"] for f in found["priors"]] == [name]
    f = found["priors"][0]
    assert f["end"] == (f["domain"][1] if value > f["domain"][1] else f["domain"][0])
    assert abs(f["wanted"] - value) <= 0.2 * w  # near the truth, beyond the domain
    text = CliRunner().invoke(cli.main, ["solve", str(path), "-q"]).output
    assert f"{name}: the data want" in text and "worst rows" not in text


def test_a_gross_row_is_blamed_when_the_priors_hold(tmp_path: Path) -> None:
    found = conflict(_campaign(tmp_path, {}, moved=5.0))
    assert found is not None and not found.priors
    assert [r.row for r in found.rows] == [7] and found.consistent and not found.units


def _units_case(tmp: Path, table: str, extra: list[str]) -> dict:
    rows = simulate_rows(tmp, 40, seed=11, e=0.05)
    write_table(tmp / "data.csv", rows, COLUMNS, lambda r, c: r[c])
    path = tmp / "robot.cal"
    path.write_text(header(0.05, with_true=False) + table, encoding="utf-8")
    res = CliRunner().invoke(cli.main, ["solve", str(path), "-q", "--json", "-", *extra])
    assert res.exit_code == 1, res.output
    found = json.loads(res.output)["conflict"]
    assert found["rows"] == [] and not found["priors"]  # no row blamed
    return found


def test_positions_declared_in_metres_name_their_columns(tmp_path: Path) -> None:
    found = _units_case(tmp_path, TABLE.replace("x, y, z : +- e", "x in m, y in m, z in m : +- e"),
                        [])
    assert len(found["units"]) == 1 and found["units"][0].startswith("columns x, y, z:")
    assert "1000 (mm and m)" in found["units"][0]


@pytest.mark.slow
def test_joints_declared_in_degrees_name_their_columns(tmp_path: Path) -> None:
    deg = ", ".join(f"q{i} in deg" for i in range(1, 7))
    found = _units_case(tmp_path, TABLE.replace("q1, q2, q3, q4, q5, q6 : +- 0",
                                                f"{deg} : +- 0"), [])
    assert any(u.startswith("columns q1, q2, q3, q4, q5, q6: declared `in deg`")
               for u in found["units"])


@pytest.mark.slow
def test_a_bound_in_metres_is_named(tmp_path: Path) -> None:
    found = _units_case(tmp_path, TABLE, ["-D", "e=0.00005"])
    assert any("the error bound, about 1000 (mm and m)" in u for u in found["units"])
