"""simulate.py: the paper's protocol on a hand-built RX90 model, then end to end."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from calib_dsl.elaborate.chains import Frame, forward_point
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.ir.dag import Dag
from calib_dsl.ir.model import Column, Model, Table
from calib_dsl.studies.kinematics import RX90_PARAMS, RX90_TOOL, rx90_forward
from calib_dsl.studies.simulate import cell_name, simulate, simulate_model, write_csv

ROOT = Path(__file__).resolve().parents[2]
TOL_Q, TOL_X = 1e-5, 1e-4
Q_COLS = [f"q{j}" for j in range(1, 7)]
X_COLS = [f"{c}{k}" for k in range(1, 4) for c in "xyz"]


def rx90_sim_model(rows: int, formulation: str = "matrix", tol_q: float = TOL_Q,
                   tol_x: float = TOL_X) -> Model:
    """What the elaborator hands over in simulation mode, built by hand: 33 parameters at
    their true values, a table `m` whose cells are `data` variables, `x == chain(q)`."""
    dag = Dag()
    loc = Loc("rx90.cal", 1, 1)
    tool = {f"b{k}{c}": RX90_TOOL[k - 1][i] for k in range(1, 4) for i, c in enumerate("xyz")}
    p = {}
    for name, true in {**RX90_PARAMS, **tool}.items():
        p[name] = dag.var(name, true - 0.1, true + 0.1, loc, true=true)
    zero = dag.const(0.0)
    for row in range(1, rows + 1):
        cell = {c: dag.var(cell_name("m", c, row), -10.0, 10.0, kind="data")
                for c in Q_COLS + X_COLS}
        frames = [Frame(zero, zero, p["theta0"], p["r0"])]
        frames += [Frame(p[f"alpha{j}"], p[f"d{j}"], dag.op("add", p[f"theta{j}"], cell[f"q{j}"]),
                         p[f"r{j}"]) for j in range(1, 6)]
        frames.append(Frame(p["alpha6"], p["d6"], cell["q6"], zero))
        for k in range(1, 4):
            x = forward_point(dag, frames, (p[f"b{k}x"], p[f"b{k}y"], p[f"b{k}z"]), formulation)
            for c, node in zip("xyz", x, strict=True):
                # Both orientations of a defining constraint are accepted.
                if k == 2:
                    dag.constrain(node, "==", cell[f"{c}{k}"], loc)
                else:
                    dag.constrain(cell[f"{c}{k}"], "==", node, loc)
    columns = ([Column(c, tol_q, (-math.pi, math.pi)) for c in Q_COLS]
               + [Column(c, tol_x) for c in X_COLS])
    return Model("rx90.cal", dag, [Table("m", "m.csv", columns, rows, loc)], formulation,
                 simulation=True)


def test_shape_and_reproducibility():
    model = rx90_sim_model(20)
    a, b, c = (simulate_model(model, s)["m"] for s in (7, 7, 8))
    assert a.shape == (20, 15)
    np.testing.assert_array_equal(a, b)
    assert np.all(a != c)
    q = a[:, :6]
    assert np.all(np.abs(q) <= math.pi + TOL_Q) and q.std() > 1.0  # spread over [-pi, pi]


@pytest.mark.parametrize("formulation", ["matrix", "rotation"])
def test_clean_values_match_kinematics_and_noise_is_bounded(formulation):
    # Same seed: the inputs are drawn before the noise, so a tol-0 run is the clean data.
    clean = simulate_model(rx90_sim_model(50, formulation, 0.0, 0.0), 11)["m"]
    noisy = simulate_model(rx90_sim_model(50, formulation), 11)["m"]
    x = rx90_forward(clean[:, :6]).reshape(50, 9)
    np.testing.assert_allclose(clean[:, 6:], x, atol=1e-13)
    noise = noisy - clean
    assert np.all(np.abs(noise[:, :6]) <= TOL_Q) and np.all(np.abs(noise[:, 6:]) <= TOL_X)
    # Every cell is noisy, and the noise uses its whole range.
    assert np.all(noise != 0)
    assert np.abs(noise[:, 6:]).max() > 0.8 * TOL_X


def test_formulations_simulate_the_same_data():
    m = simulate_model(rx90_sim_model(10, "matrix"), 3)["m"]
    r = simulate_model(rx90_sim_model(10, "rotation"), 3)["m"]
    np.testing.assert_allclose(m, r, rtol=0, atol=1e-14)


def test_csv_round_trips_exactly(tmp_path):
    model = rx90_sim_model(5)
    data = simulate_model(model, 1)["m"]
    path = tmp_path / "m.csv"
    write_csv(path, model.tables[0], data)
    with path.open() as f:
        rows = list(csv.reader(f))
    assert rows[0] == Q_COLS + X_COLS
    assert len(rows) == 6
    np.testing.assert_array_equal(np.array(rows[1:], dtype=float), data)


def test_parameter_without_true_value():
    model = rx90_sim_model(2)
    model.dag.variables["d3"].true = None
    with pytest.raises(CalError, match="'d3' has no true value") as err:
        simulate_model(model, 0)
    assert err.value.loc == Loc("rx90.cal", 1, 1)


def test_output_column_without_definition():
    model = rx90_sim_model(2)
    model.tables[0].columns.append(Column("w", 0.1))
    model.dag.var(cell_name("m", "w", 1), 0, 1, kind="data")
    with pytest.raises(CalError, match="'m.w' has no defining constraint"):
        simulate_model(model, 0)


def test_output_defined_through_another_output():
    # y == 2 * x, x == q + 1: solved in two passes.
    dag = Dag()
    q, x, y = (dag.var(cell_name("t", c, 1), -9, 9, kind="data") for c in "qxy")
    dag.constrain(y, "==", dag.op("mul", dag.const(2.0), x))
    dag.constrain(x, "==", dag.op("add", q, dag.const(1.0)))
    cols = [Column("q", 0.0, (0.0, 1.0)), Column("x", 0.0), Column("y", 0.0)]
    model = Model("t.cal", dag, [Table("t", "t.csv", cols, 1)], simulation=True)
    (qv, xv, yv), = simulate_model(model, 5)["t"]
    assert 0.0 <= qv <= 1.0 and xv == qv + 1.0 and yv == 2.0 * xv


def test_constraint_violated_at_true_values():
    # The distance between two tool points stated wrong: the data would be inconsistent.
    model = rx90_sim_model(2)
    dag = model.dag
    v = dag.variables
    bad = Loc("rx90.cal", 9, 5)
    dx = dag.op("sub", v["b1x"].node, v["b3x"].node)  # true: 0.1 - 0.2 = -0.1
    dag.constrain(dag.op("sqr", dx), "==", dag.const(0.02), bad)
    with pytest.raises(CalError, match="does not hold at the true values") as err:
        simulate_model(model, 0)
    assert err.value.loc == bad


def test_constraint_met_inside_a_constant_interval():
    model = rx90_sim_model(2)
    dag, v = model.dag, model.dag.variables
    dx = dag.op("sub", v["b1x"].node, v["b3x"].node)
    dag.constrain(dag.op("sqr", dx), "==", dag.const(0.0099, 0.0101))
    dag.constrain(v["r0"].node, "<=", dag.const(0.6))
    simulate_model(model, 0)


# -- end to end: the elaborated RX90 model ---------------------------------------------------
RX90_MODEL = ROOT / "models" / "rx90_lengths.cal"
needs_elaborator = pytest.mark.skipif(not RX90_MODEL.exists(),
                                      reason="models/rx90_lengths.cal is missing")


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open() as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


@needs_elaborator
@pytest.mark.parametrize("formulation", ["matrix", "rotation"])
def test_rx90_model_end_to_end(tmp_path, formulation):
    from calib_dsl.elaborate.elaborator import elaborate

    model = elaborate(str(RX90_MODEL), formulation=formulation, simulate_rows=30)
    (table,) = model.tables
    inputs = [c for c in table.columns if c.sim is not None]
    outputs = [c for c in table.columns if c.sim is None]
    assert len(inputs) == 6 and len(outputs) == 9

    paths = [tmp_path / f"{s}.csv" for s in ("a", "b", "c")]
    for path, seed in zip(paths, (4, 4, 5), strict=True):
        simulate(RX90_MODEL, 30, seed, formulation=formulation, out_csv=path)
    header, a = read_csv(paths[0])
    assert header == [c.name for c in table.columns]
    assert a.shape == (30, 15)
    assert paths[0].read_text() == paths[1].read_text()
    assert np.all(a != read_csv(paths[2])[1])

    # Recorded x vs the kinematics at the recorded q: the x noise, plus the q noise moved
    # through the arm (reach < 1.5 m per radian on each of the 6 joints).
    col = {c.name: i for i, c in enumerate(table.columns)}
    q = a[:, [col[c.name] for c in inputs]]
    x = a[:, [col[c.name] for c in outputs]]
    tol_q = max(c.tol for c in inputs)
    bound = np.array([c.tol for c in outputs]) + 6 * 1.5 * tol_q
    assert np.all(np.abs(x - rx90_forward(q).reshape(30, 9)) <= bound)


# -- evaluate.py: the float evaluator the simulation runs on ----------------------------------
def test_evaluate_every_op_against_math():
    from calib_dsl.ir.dag import ARITY
    from calib_dsl.studies.evaluate import evaluate

    dag = Dag()
    x, y, z = (dag.var(n, -9.0, 9.0) for n in "xyz")
    vx, vy, vz = 0.7, -1.3, 2.1
    expect = {
        "neg": -vx, "sqr": vx * vx, "sqrt": math.sqrt(vx), "exp": math.exp(vx),
        "log": math.log(vx), "sin": math.sin(vx), "cos": math.cos(vx), "tan": math.tan(vx),
        "abs": abs(vx), "add": vx + vy, "sub": vx - vy, "mul": vx * vy, "div": vx / vy,
        "atan2": math.atan2(vx, vy),
        "rotu": vy * math.cos(vx) - vz * math.sin(vx),
        "rotv": vy * math.sin(vx) + vz * math.cos(vx),
    }
    nodes = {op: dag.op(op, *(x, y, z)[:ARITY[op]]) for op in expect}
    cube = dag.op("pow", y, data=3)
    half = dag.op("mul", dag.const(0.25, 0.75), z)  # a constant counts as its midpoint
    assert set(expect) == set(ARITY) - {"pow"}
    val = evaluate(dag, {x: vx, y: vy, z: vz})
    for op, node in nodes.items():
        assert val[node] == pytest.approx(expect[op], rel=1e-15), op
    assert val[cube] == pytest.approx(vy ** 3) and val[half] == pytest.approx(0.5 * vz)


def test_evaluate_batches_and_missing_values():
    from calib_dsl.studies.evaluate import evaluate, values_by_name

    dag = Dag()
    a, b = dag.var("a", 0, 1), dag.var("b", 0, 1)
    s = dag.op("add", dag.op("sin", a), b)
    val = evaluate(dag, values_by_name(dag, {"a": np.array([0.0, 1.0, 2.0]), "b": 1.0}))
    np.testing.assert_allclose(val[s], np.sin([0.0, 1.0, 2.0]) + 1.0)
    with pytest.raises(KeyError, match="'b'"):
        evaluate(dag, {a: 0.5})
    assert math.isnan(evaluate(dag, {a: 0.5}, default=math.nan)[s])


def test_unwritable_output_is_a_user_error(tmp_path):
    model = rx90_sim_model(1)
    with pytest.raises(CalError, match="cannot write"):
        write_csv(tmp_path / "no" / "such" / "dir.csv", model.tables[0],
                  simulate_model(model, 0)["m"])
