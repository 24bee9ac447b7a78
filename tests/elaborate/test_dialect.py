"""Tables as they come: separators, decimal commas, the file's own header names, units
converted with outward rounding, row selection; and what the command line adds (--data
TABLE=, --rows, --exclude, -D). Bad data and bad options give one clear message, exit 2."""

from __future__ import annotations

import json
import re
import subprocess
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.elaborate.elaborator import Inputs, elaborate
from calib_dsl.elaborate.rows import Selection, parse_ranges
from calib_dsl.elaborate.units import PI_60
from calib_dsl.frontend.diagnostics import CalError

UR10 = Path(__file__).resolve().parents[3] / "shared" / "data" / "ur10"
UR10_TABLE = UR10 / "measurements_joint_configurations.csv"
needs_ur10 = pytest.mark.skipif(
    not UR10_TABLE.exists(),
    reason=f"the public UR10 data set is not at {UR10} (see docs/real-data.md to get it)")

TABLE = """units mm, rad;
const e = 1.0;
param a in [-1e4, 1e4];
table m = "{path}" (separator = ";", decimal = ",", {options}) {{
  q1 = "shoulder_pan_joint" in rad, q2 = "shoulder_lift_joint" in rad : +- 1e-5;
  x = "measurement_x" in mm : +- e;
  rx = "measurement_rx" in deg : +- 1e-3;
}}
for k in 1..rows(m) {{ a >= m.x[k] - 1e4; }}
"""


def exact_cells(path: Path, header: str, decimal_comma: bool = True) -> list[Fraction]:
    lines = path.read_text(encoding="utf-8").splitlines()
    names = lines[0].split(";")
    j = names.index(header)
    out = []
    for line in lines[1:]:
        if line.strip():
            cell = line.split(";")[j]
            out.append(Fraction(cell.replace(",", ".") if decimal_comma else cell))
    return out


def cell_interval(model, table: str, column: str, row: int) -> tuple[float, float]:
    """The interval of a cell: [lo, hi] (the data's error bound included)."""
    (t,) = [t for t in model.tables if t.name == table]
    lo, hi = t.bounds[column]
    return float(lo[row - 1]), float(hi[row - 1])


@needs_ur10
def test_the_ur10_table_reads_as_it_comes(tmp_path):
    """Every 15th row of the public file: 100 rows, each cell's interval holds the exact
    decimal of the file converted to the model's units (mm, rad) and widened by its bound."""
    model_file = tmp_path / "m.cal"
    model_file.write_text(TABLE.format(path=UR10_TABLE, options="rows = 1..1495:15"))
    model = elaborate(model_file)
    (table,) = model.tables
    assert table.rows == 100 and table.numbers[:3] == [1, 16, 31]
    assert table.lines[:2] == [2, 17]  # the header is line 1
    xs = exact_cells(UR10_TABLE, "measurement_x")
    rxs = exact_cells(UR10_TABLE, "measurement_rx")
    q1 = exact_cells(UR10_TABLE, "shoulder_pan_joint")
    for k, number in enumerate(table.numbers, start=1):
        lo, hi = cell_interval(model, "m", "x", k)
        truth = xs[number - 1]
        assert Fraction(lo) <= truth - 1 and truth + 1 <= Fraction(hi)  # +- e = 1 mm
        assert hi - lo < 2 + 1e-9
        lo, hi = cell_interval(model, "m", "rx", k)
        pi_lo, pi_hi = PI_60 - Fraction(1, 10**59), PI_60 + Fraction(1, 10**59)
        deg = rxs[number - 1]
        rad = sorted([deg * pi_lo / 180, deg * pi_hi / 180])
        bound = Fraction(1, 1000)
        assert Fraction(lo) <= rad[0] - bound and rad[1] + bound <= Fraction(hi)
        lo, hi = cell_interval(model, "m", "q1", k)
        assert Fraction(lo) <= q1[number - 1] - Fraction(1, 10**5)
        assert q1[number - 1] + Fraction(1, 10**5) <= Fraction(hi)


@needs_ur10
def test_the_ur10_table_with_every_row_and_exclusions(tmp_path):
    model_file = tmp_path / "m.cal"
    model_file.write_text(TABLE.format(path=UR10_TABLE, options="exclude = (533, 856)"))
    (table,) = elaborate(model_file).tables
    assert table.rows == 1493 and 533 not in table.numbers and 856 not in table.numbers
    cli = Inputs(rows={"m": Selection(parse_ranges("1..10"))})
    (table,) = elaborate(model_file, inputs=cli).tables  # --rows replaces the ranges
    assert table.numbers == list(range(1, 11))


def small_file(tmp_path: Path, text: str, name: str = "d.csv") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


MODEL = """units {units};
param a in [-100, 100];
table m = "d.csv" ({options}) {{
  {columns} : +- 0;
}}
for k in 1..rows(m) {{ a >= m.v[k] - 100; }}
"""


def model_with(tmp_path, data: str, columns: str = 'v = "value" in deg',
               options: str = 'separator = ";", decimal = ","', units: str = "m, rad"):
    small_file(tmp_path, data)
    path = tmp_path / "m.cal"
    path.write_text(MODEL.format(units=units, options=options, columns=columns))
    return path


@settings(max_examples=60, deadline=None)
@given(st.decimals(min_value=-1000, max_value=1000, places=6, allow_nan=False),
       st.sampled_from(["deg", "mrad", "rad"]))
def test_converted_cells_hold_the_exact_value(tmp_path_factory, value, unit):
    tmp = tmp_path_factory.mktemp("u")
    text = f"{value}".replace(".", ",")
    model = elaborate(model_with(tmp, f"other;value\n1;{text}\n", f'v = "value" in {unit}'))
    lo, hi = cell_interval(model, "m", "v", 1)
    exact = Fraction(str(value))
    if unit == "deg":
        ends = [exact * (PI_60 + s * Fraction(1, 10**59)) / 180 for s in (-1, 1)]
    else:
        ends = [exact / (1000 if unit == "mrad" else 1)] * 2
    assert Fraction(lo) <= min(ends) and max(ends) <= Fraction(hi)
    assert hi - lo <= 8 * np.spacing(max(abs(lo), abs(hi), 1e-300))  # a few ulps at most


@pytest.mark.parametrize("data,options,message", [
    ("value\n1.5\n", 'separator = ";", decimal = ","', "has a decimal point, but the table says"),
    ("value\nnan\n", 'separator = ";", decimal = ","', "is not a finite number"),
    ("value\n1,2,3\n", 'separator = ";", decimal = ","', "is not a number"),
    ("other;valu\n1;2\n", 'separator = ";", decimal = ","', "has no column 'value'"),
    ("value;x\n1;2\n", 'separator = ","', 'the file looks ";"-separated'),
    ("value\n1\n", 'separator = ",", decimal = ","', "must differ"),
    ("value\n1\n", 'separator = "x"', "separator 'x'"),
    ("value\n1\n", 'delimiter = ";"', "unknown table option 'delimiter'"),
    ("value\n1\n2\n", 'rows = 1..3', "reach past the end of the table (2 rows)"),
    ("value\n1\n2\n", 'exclude = 5', "row 5 is excluded but the table has rows 1..2"),
    ("value\n1\n2\n", 'rows = 2..1', "is empty"),
])
def test_bad_data_and_options_name_the_place(tmp_path, data, options, message):
    with pytest.raises(CalError, match=re.escape(message)):
        elaborate(model_with(tmp_path, data, 'v = "value" in rad', options))


def test_a_bad_cell_is_located_in_the_data_file(tmp_path):
    path = model_with(tmp_path, "a;value\n1;2,5\n3;x\n")
    with pytest.raises(CalError) as err:
        elaborate(path)
    assert str(err.value.loc).endswith("d.csv:3:2")
    assert "row 2, column 'v' (\"value\")" in err.value.message
    assert "    3;x\n      ^" in err.value.render()  # the caret under the field


def test_units_are_checked(tmp_path):
    with pytest.raises(CalError, match="unknown unit 'furlong'"):
        elaborate(model_with(tmp_path, "value\n1\n", units="furlong, rad"))
    with pytest.raises(CalError, match="two length units"):
        elaborate(model_with(tmp_path, "value\n1\n", units="m, mm"))


def run(calibc, *args):
    return subprocess.run([*calibc, *map(str, args)], capture_output=True, text=True,
                          timeout=60)


@pytest.mark.slow
def test_command_line_options(tmp_path, calibc):
    model = model_with(tmp_path, "value\n1\n2\n3\n", 'v = "value" in rad')
    other = small_file(tmp_path, "value\n7\n", "other.csv")
    ok = run(calibc, "compile", model, "--json", "--data", f"m={other}")
    assert ok.returncode == 0, ok.stderr
    assert '"constants": 1' in ok.stdout or '"declared": 1' in ok.stdout
    for args, message in [
        (["--data", f"n={other}"], "given for table 'n', but the model has tables m"),
        (["--rows", "1..9"], "reach past the end"),
        (["--rows", "x"], "is not a row range"),
        (["--exclude", "0"], "excluded but the table has rows 1..3"),
        (["-D", "nothere=1"], "the model has no const 'nothere'"),
        (["-D", "oops"], "write NAME=VALUE"),
    ]:
        res = run(calibc, "compile", model, *args)
        assert res.returncode == 2 and message in res.stderr, (args, res.stderr)
        assert "Traceback" not in res.stderr


def test_define_sets_a_const(tmp_path, calibc):
    source = ('const lo = 5;\nparam a in [0, 10];\na >= lo;\n')
    path = tmp_path / "c.cal"
    path.write_text(source)
    res = run(calibc, "solve", path, "--strategy", "hc4", "--no-identify", "-D", "lo=7.5",
              "--json", "-")
    assert res.returncode == 0, res.stderr
    lo, hi = json.loads(res.stdout)["parameters"]["a"]["result"]
    assert 7.5 - 1e-12 < lo <= 7.5 and hi == 10
