"""Tables given as values (the Python API's arrays and lists) where a file would be: the same
columns, row selection and units as a file, each float its own exact value, and the same kind
of located user errors."""

from __future__ import annotations

import csv
import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from calib_dsl.elaborate.elaborator import Inputs, elaborate
from calib_dsl.elaborate.rows import Selection, parse_ranges
from calib_dsl.elaborate.values import Values
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.pipeline import load, solve

EXAMPLES = Path(__file__).resolve().parents[2] / "models" / "examples"
CIRCLE = EXAMPLES / "circle_fit.cal"


def circle_columns() -> dict[str, list[float]]:
    with open(EXAMPLES / "circle.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    return {c: [float(r[c]) for r in rows] for c in ("x", "y")}


@pytest.mark.parametrize("shape", ["mapping", "array", "lists"])
def test_values_solve_as_the_file_does_and_hold_the_truth(shape):
    columns = circle_columns()
    given = {"mapping": {**columns, "note": ["ignored"] * 6},
             "array": np.column_stack([columns["x"], columns["y"]]),
             "lists": [list(r) for r in zip(columns["x"], columns["y"], strict=True)]}[shape]
    from_file = solve(load(CIRCLE))
    prog = load(CIRCLE, inputs=Inputs(data={"m": Values(given)}))
    from_values = solve(prog)
    for name, true in (("cx", 1.0), ("cy", 2.0), ("radius", 3.0)):
        i = prog.slots.names.index(name)
        assert from_values.lo[i] <= true <= from_values.hi[i]
        # the floats are exact: never wider than the file's decimals, and as good
        assert from_file.lo[i] <= from_values.lo[i] <= from_values.hi[i] <= from_file.hi[i]
        assert math.isclose(from_values.hi[i] - from_values.lo[i],
                            from_file.hi[i] - from_file.lo[i], rel_tol=1e-6)


def test_each_float_is_its_own_enclosure_and_rows_are_selected(tmp_path):
    model_path = tmp_path / "m.cal"
    model_path.write_text('table m = "absent.csv" (rows = 2..3) { a : +- 0; b : +- 0.5; }\n'
                          "var x;\nfor k in 1..rows(m) { x == m.a[k] + m.b[k]; }\n")
    a = [0.1, 0.2, 0.3, 0.4]
    model = elaborate(model_path, inputs=Inputs(data={"": Values({"a": a, "b": [1, 2, 3, 4]},
                                                                 "<my arrays>")}))
    (table,) = model.tables
    assert (table.rows, table.numbers, table.path) == (2, [2, 3], "<my arrays>")
    consts = {model.dag.nodes[n].data[:2] for n in range(len(model.dag.nodes))
              if model.dag.nodes[n].op == "const"}
    assert (0.2, 0.2) in consts and (0.3, 0.3) in consts  # the floats themselves, exact
    assert (1.5, 2.5) in consts and (2.5, 3.5) in consts  # b +- 0.5
    assert (0.1, 0.1) not in consts  # row 1 was not selected
    # --rows from the command line's side replaces the table's selection, as for a file
    model = elaborate(model_path, inputs=Inputs(data={"m": Values({"a": a, "b": a})},
                                                rows={"m": Selection(parse_ranges("4"))}))
    assert model.tables[0].numbers == [4]


def test_units_convert_values_as_they_do_a_file(tmp_path):
    path = tmp_path / "m.cal"
    path.write_text('table m = "absent.csv" { q = "q_deg" in deg : +- 0; }\nvar x;\n'
                    "x == m.q[1];\n")
    model = elaborate(path, inputs=Inputs(data={"": Values({"q": [90.0]})}))
    (c,) = model.dag.constraints
    lo, hi = model.dag.nodes[c.rhs].data[:2]
    assert Fraction(lo) <= Fraction(math.pi / 2) <= Fraction(hi) and hi - lo < 1e-15


X, Y = [1.0, 2.0], [3.0, 4.0]


@pytest.mark.parametrize(("given", "message"), [
    ({"x": X}, "table 'm' (<values>) has no column 'y' (its columns: x)"),
    ({"x": X, "y": Y[:1]}, "its columns differ in length (x: 2, y: 1)"),
    ([[1.0, 2.0, 3.0]], "has 3 columns; the table declares 2 (x, y), in this order"),
    ({"x": "1,2", "y": Y}, "column 'x': a string is not numbers"),
    ({"x": X, "y": [3.0, math.nan]}, "row 2, column 'y': nan is not a finite number"),
    ({"x": X, "y": [3.0, math.inf]}, "row 2, column 'y': inf is not a finite number"),
    ({"x": [], "y": []}, "table 'm' (<values>) has no rows"),
    ({"x": [[1.0]], "y": [2.0]}, "column 'x': expected a sequence of numbers, got 2"),
    ({"x": ["a", "b"], "y": Y}, "column 'x': not numbers"),
])
def test_bad_values_are_located_user_errors(given, message):
    with pytest.raises(CalError) as err:
        load(CIRCLE, inputs=Inputs(data={"": Values(given)}))
    assert message in err.value.message
    assert err.value.loc == Loc(str(CIRCLE), 8, 1)  # the table's declaration
