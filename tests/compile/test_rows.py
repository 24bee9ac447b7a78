"""Rows as a batch dimension: a loop over a table's rows whose body reads its index only as
cells compiles once, and the program it gives is the unrolled one (same counts, same
domains, the same solutions enclosed, never wider); loops that read the index otherwise, or
exact cells, or other rows, are unrolled as written."""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.cli import main
from calib_dsl.compile.group import compile_model
from calib_dsl.compile.listing import render_listing
from calib_dsl.elaborate.elaborator import Inputs, elaborate
from calib_dsl.pipeline import solve
from calib_dsl.relax.layout import independents
from tests.compile.test_decompose import EXAMPLES
from tests.relax.test_linearize import clean_version, robot_source, simulate_cal

PLANAR = """param a in [0.5, 1.5];
param b in [0.2, 0.8];
table m = "d.csv" {{ q1, q2 : +- {tol}; x, y : +- 0.01; }}
for k in 1..rows(m) {{
  {body}
}}
"""
PLANAR_BODY = ("a * cos(m.q1[k]) + b * cos(m.q1[k] + m.q2[k]) == m.x[k];\n"
               "  a * sin(m.q1[k]) + b * sin(m.q1[k] + m.q2[k]) == m.y[k];")


def planar_csv(rows: int, seed: int = 0, a: float = 1.0, b: float = 0.5,
               exact: bool = False) -> str:
    rng = np.random.default_rng(seed)
    q = rng.uniform(-3, 3, (rows, 2))
    if exact:
        q = np.round(q * 4) / 4  # quarters: exact in binary
    x = a * np.cos(q[:, 0]) + b * np.cos(q.sum(1))
    y = a * np.sin(q[:, 0]) + b * np.sin(q.sum(1))
    lines = [",".join(repr(float(v)) for v in row) for row in np.column_stack([q, x, y])]
    return "q1,q2,x,y\n" + "\n".join(lines) + "\n"


def both(path, formulation: str = "matrix"):
    batched = compile_model(elaborate(path, formulation=formulation))
    unrolled = compile_model(elaborate(path, formulation=formulation,
                                       inputs=Inputs(unroll=True)))
    return batched, unrolled


def same_program(batched, unrolled) -> None:
    """The same program up to slot numbering: counts, and every initial domain."""
    assert batched.counts() == unrolled.counts()
    for side in ("lo", "hi"):
        a, b = getattr(batched.slots, side), getattr(unrolled.slots, side)
        assert np.array_equal(np.sort(a), np.sort(b))
    assert len(batched.primitives) == len(unrolled.primitives)
    assert sorted(map(len, (g.prim for g in batched.groups))) == \
        sorted(map(len, (g.prim for g in unrolled.groups)))


def declared_box(prog, sol) -> dict[str, tuple[float, float]]:
    return {prog.slots.names[i]: (float(sol.lo[i]), float(sol.hi[i]))
            for i in independents(prog)}


@pytest.mark.slow
# 12 examples in bench/checks/test_soundness_full.py
@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), joints=st.integers(1, 3), rows=st.integers(3, 9),
       formulation=st.sampled_from(["matrix", "rotation"]))
def test_a_loop_compiled_once_is_the_unrolled_program(tmp_path_factory, seed, joints, rows,
                                                      formulation):
    """Random robots, simulated data (known truth): the batched program is the unrolled one,
    and both strategies' boxes hold the truth, the batched no wider than 1.0001x."""
    rng = np.random.default_rng(seed)
    source = robot_source(rng, joints, 1e-6, 1e-4, spatial=bool(seed % 2))
    tmp = tmp_path_factory.mktemp("rows")
    sim = simulate_cal(tmp, source, clean_version(source), rows, seed, formulation)
    batched = sim.prog
    unrolled = compile_model(elaborate(tmp / "model.cal", formulation=formulation,
                                       data=tmp / "data.csv", inputs=Inputs(unroll=True)))
    # unrolled only where the rows share a measured side (z of a planar arm: bz == m.z[k])
    assert (batched.rows is not None) != bool(batched.slots.capped_by_rows)
    assert unrolled.rows is None
    same_program(batched, unrolled)
    names = [batched.slots.names[i] for i in independents(batched)]
    assert names == [unrolled.slots.names[i] for i in independents(unrolled)]
    for strategy in ("hc4", "tight"):
        bb = declared_box(batched, solve(batched, strategy))
        ub = declared_box(unrolled, solve(unrolled, strategy))
        for name, truth in zip(names, sim.p_true, strict=True):
            for box in (bb, ub):
                assert box[name][0] <= truth <= box[name][1], (strategy, name)
            wb, wu = bb[name][1] - bb[name][0], ub[name][1] - ub[name][0]
            assert wb <= 1.0001 * wu + 1e-15, (strategy, name, wb, wu)


def test_the_rx90_model_compiles_once_through_its_macro(tmp_path):
    """rx90_lengths.cal's loop passes k to a macro (`arm(k, b1)`) that reads cells with it."""
    batched, unrolled = both(EXAMPLES.parent / "rx90_lengths.cal")
    assert batched.rows is not None and len(batched.rows.rows) == 50
    same_program(batched, unrolled)
    assert declared_box(batched, solve(batched, "hc4")) == \
        declared_box(unrolled, solve(unrolled, "hc4"))


def test_the_listing_shows_the_body_once(write_model):
    path = write_model(PLANAR.format(tol=1e-5, body=PLANAR_BODY),
                       files={"d.csv": planar_csv(40)})
    batched, unrolled = both(path)
    text = render_listing(batched)
    assert "for k in 1..40 (40 rows of m, compiled once):" in text
    body = text.split("compiled once):", 1)[1]
    assert "m.q1[k]" in body and "m.x[k]" not in body  # x is the measured side's domain
    # the counts of the header are the whole program's, as unrolled
    assert text.splitlines()[1:3] == render_listing(unrolled).splitlines()[1:3]
    assert len(text.splitlines()) < len(render_listing(unrolled).splitlines()) / 10


@pytest.mark.parametrize("body, why", [
    ("a * m.q1[k] + b == m.x[k] * k;", "arithmetic on k"),
    ("a * cos(m.q1[k]) + b * cos(m.q1[1]) == m.x[k];", "another row's cell"),
    ("a * cos(m.q1[k]) == m.x[k];\n  a * cos(m.q1[k + 1]) + b == m.y[k + 1];",
     "the next row"),
])
def test_loops_that_read_other_rows_are_unrolled(write_model, body, why):
    rows = 12
    src = PLANAR.format(tol=1e-5, body=body).replace("1..rows(m)", f"1..{rows - 1}")
    path = write_model(src, files={"d.csv": planar_csv(rows)})
    batched, unrolled = both(path)
    assert batched.rows is None, why
    assert batched.counts() == unrolled.counts()


def test_exact_cells_are_unrolled(write_model):
    """Cells without an error bound fold and simplify by value: each row's program differs."""
    path = write_model(PLANAR.format(tol=0, body=PLANAR_BODY),
                       files={"d.csv": planar_csv(10, exact=True)})
    batched, unrolled = both(path)
    assert batched.rows is None and batched.counts() == unrolled.counts()


def test_two_rows_are_unrolled(write_model):
    path = write_model(PLANAR.format(tol=1e-5, body=PLANAR_BODY),
                       files={"d.csv": planar_csv(2)})
    assert compile_model(elaborate(path)).rows is None


def test_compiling_rows_once_keeps_no_python_object_per_row(write_model):
    """Memory as a design goal: elaborate + compile of 4000 rows allocate well under
    0.1 MB per row (the unrolled program takes about 0.2 MB per row of this model)."""
    rows = 4000
    path = write_model(PLANAR.format(tol=1e-5, body=PLANAR_BODY),
                       files={"d.csv": planar_csv(rows)})
    tracemalloc.start()
    try:
        prog = compile_model(elaborate(path))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert prog.rows is not None and len(prog.rows.rows) == rows
    assert peak < 0.02e6 * rows, peak / rows


def test_unroll_option_gives_the_same_results(write_model, untimed):
    path = write_model(PLANAR.format(tol=1e-5, body=PLANAR_BODY),
                       files={"d.csv": planar_csv(30, seed=3)})
    out = {}
    for flag in ((), ("--unroll",)):
        result = path.parent / f"r{len(flag)}.json"
        run = CliRunner().invoke(main, ["solve", str(path), "--strategy", "hc4", "--json",
                                        str(result), "-q", *flag])
        assert run.exit_code == 0, run.output
        doc = untimed(json.loads(result.read_text()))
        out[flag] = {name: p["result"] for name, p in doc["parameters"].items()}
    assert out[()] == out[("--unroll",)]
    listing = CliRunner().invoke(main, ["compile", str(path), "--unroll"])
    assert listing.exit_code == 0 and "compiled once" not in listing.stdout
