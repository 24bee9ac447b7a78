"""One data row, however it is spelled (elaborate/measured.py): a measured side that sums an
exact cell and a cell with an error bound is one reading, whichever side it is written on."""

from __future__ import annotations

import json
import random
from fractions import Fraction
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import given
from hypothesis import strategies as st

from calib_dsl import cli
from calib_dsl.compile.group import compile_model
from calib_dsl.compile.listing import render_listing
from calib_dsl.elaborate.elaborator import elaborate
from tests.simulated_ur5 import JOINTS, header, simulate_rows, write_table

F = f"ur5({JOINTS}) at (tx, ty, tz)"
T, D = "(m.tx_[k], m.ty_[k], m.tz_[k])", "(m.dx[k], m.dy[k], m.dz[k])"
SPELLINGS = {  # the same mathematics: measured = target + dif
    "sum": f"{F} == {T} + {D}",
    "difference": f"{F} - {T} == {D}",
    "mirrored": f"{T} + {D} == {F}",
    "dif first": f"{F} == {D} + {T}",
    "negated target": f"-{T} + {F} == {D}",
    "measured left": f"{D} == {F} - {T}",
}
TABLE = ('table m = "td.csv" {\n  q1, q2, q3, q4, q5, q6 : +- 0;\n  tx_, ty_, tz_ : +- 0;\n'
         "  dx, dy, dz : +- e;\n}\n")
COLUMNS = ["q1", "q2", "q3", "q4", "q5", "q6", "tx_", "ty_", "tz_", "dx", "dy", "dz"]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A UR5 campaign whose file holds the target (exact, to 1 um) and the difference."""
    tmp = tmp_path_factory.mktemp("ur5_target_dif")
    rows = simulate_rows(tmp, 40, seed=3, e=0.05)
    rng = random.Random(1)
    for r in rows:  # a target within 3 mm of the measurement, the rest in dif
        for a in "xyz":
            r[f"t{a}_"] = round(r[a] + rng.uniform(-3, 3), 3)
            r[f"d{a}"] = r[a] - r[f"t{a}_"]
    write_table(tmp / "td.csv", rows, COLUMNS, lambda r, c: r[c])
    return tmp


def _model(tmp: Path, name: str, constraint: str) -> Path:
    path = tmp / f"{name.replace(' ', '_')}.cal"
    path.write_text(header(0.05) + TABLE + f"for k in 1..rows(m) {{\n  {constraint};\n}}\n",
                    encoding="utf-8")
    return path


def _listing(path: Path, measured: int | None = None) -> str:
    prog = compile_model(elaborate(path))
    if measured is not None:  # each coordinate a measured side, not two readings
        assert len(prog.slots.measured_sides or {}) == measured
    return render_listing(prog).replace(path.name, "MODEL")


def test_every_spelling_compiles_to_the_same_program(campaign: Path) -> None:
    texts = {name: _listing(_model(campaign, name, c), measured=3 * 40)
             for name, c in SPELLINGS.items()}
    for name, text in texts.items():
        assert text == texts["sum"], name


@pytest.mark.slow
def test_both_spellings_give_the_same_intervals_and_certify_a_point(campaign: Path) -> None:
    out = {}
    for name in ("sum", "difference"):
        res = CliRunner().invoke(cli.main, ["solve", str(_model(campaign, name,
                                                                SPELLINGS[name])),
                                            "-q", "--json", "-"])
        assert res.exit_code == 0, res.output
        params = json.loads(res.output)["parameters"]
        assert all(p["inner"] for p in params.values())  # a point certified
        out[name] = {k: p["result"] for k, p in params.items()}
    assert out["sum"] == out["difference"]


@pytest.mark.parametrize("name", ["sum", pytest.param("difference", marks=pytest.mark.slow)])
def test_min_error_brackets_both_spellings(campaign: Path, name: str) -> None:
    path = _model(campaign, name, SPELLINGS[name])
    res = CliRunner().invoke(cli.main, ["solve", str(path), "-q", "--min-error", "e"])
    assert res.exit_code == 0, res.output
    assert "smallest consistent error bound for e: in [" in res.output
    lo, hi = (float(x) for x in res.output.split("in [")[1].split("]")[0].split(","))
    assert lo < hi <= 0.05 * 1.01  # the data were drawn within 0.05


@pytest.mark.slow
def test_a_reading_that_scales_with_the_bound_is_no_internal_error(campaign: Path) -> None:
    """Targets known to +- e/100 stay readings (two cells with an error bound: not folded),
    and --min-error's trials at smaller bounds keep them within their intervals."""
    path = campaign / "scaled.cal"
    path.write_text(header(0.05) + TABLE.replace("tx_, ty_, tz_ : +- 0", "tx_, ty_, tz_ : +- e/100")
                    + f"for k in 1..rows(m) {{\n  {SPELLINGS['difference']};\n}}\n",
                    encoding="utf-8")
    assert "m.tx_[k]" in _listing(path)  # the target is still a reading of its own
    res = CliRunner().invoke(cli.main, ["solve", str(path), "-q", "--min-error", "e"])
    assert res.exit_code == 0, res.output


SMALL = """param p in [-100, 100];
table m = "d.csv" { t : +- 0; d : +- 0.25; }
for k in 1..rows(m) { p == m.t[k] SIGN m.d[k]; }
"""

decimals = st.decimals(min_value=-50, max_value=50, places=7, allow_nan=False)


@given(st.lists(st.tuples(decimals.filter(bool), decimals), min_size=1, max_size=5),
       st.sampled_from(["+", "-"]))
def test_the_derived_reading_holds_the_exact_sum(tmp_path_factory, rows, sign) -> None:
    """Each row's reading encloses t + d (or t - d) +- 0.25, the decimals' exact values (t is
    never 0: p == 0 + d is p == d, no sum to fold)."""
    tmp = tmp_path_factory.mktemp("sum")
    (tmp / "d.csv").write_text("t,d\n" + "".join(f"{t},{d}\n" for t, d in rows))
    (tmp / "m.cal").write_text(SMALL.replace("SIGN", sign))
    model = elaborate(tmp / "m.cal")
    table = model.tables[0]
    name = "t+d" if sign == "+" else "t-d"
    assert table.columns[-1].name == name and table.columns[-1].derived == ("t", "d")
    lo, hi = table.bounds[name]
    for k, (t, d) in enumerate(rows):
        exact = Fraction(t) + (Fraction(d) if sign == "+" else -Fraction(d))
        assert Fraction(lo[k]) <= exact - Fraction(1, 4)
        assert exact + Fraction(1, 4) <= Fraction(hi[k])
        assert hi[k] - lo[k] <= 0.5 + 1e-9 * (1 + abs(float(exact)))


def test_two_cells_with_errors_stay_two_readings(compile_src) -> None:
    prog = compile_src("param p in [-100, 100];\n"
                       'table m = "d.csv" { t : +- 0.1; d : +- 0.25; }\n'
                       "for k in 1..rows(m) { p == m.t[k] + m.d[k]; }\n",
                       files={"d.csv": "t,d\n1.5,0.25\n"})
    assert [k for k in prog.slots.kinds if k == "const"]  # t and d: cells of their own
    assert not prog.slots.measured_sides


def test_an_exact_value_two_rows_share_is_still_folded(write_model) -> None:
    """Equal exact numbers are one DAG node (0.5 in rows 1 and 2): each row takes its own."""
    model = elaborate(write_model(SMALL.replace("SIGN", "+"),
                                  files={"d.csv": "t,d\n0.5,0.125\n0.5,0.375\n0.75,0.25\n"}))
    dag = model.dag
    tags = [dag.cells.get(c.rhs) for c in dag.constraints]
    assert tags == [{("m", "t+d", k)} for k in (1, 2, 3)]
