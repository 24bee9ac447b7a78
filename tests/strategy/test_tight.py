"""strategy/: the tight strategy never loses a solution, and is never looser than propagation.

- The RX90 of the paper (Test A, 14 lengths) on simulated data for several seeds and 8..20
  configurations, both formulations: every true parameter value lies in its result, and every
  result lies in the plain propagation's result at the same tolerance.
- Random robots and random expression models (from test_linearize): the same two properties.
- Data inconsistent with the model: no crash, a valid status and a well-formed box.
- Defects found here and fixed since (interval constants shared between unknowns, the
  atan2 branch cut): regression tests.
"""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from relax.test_linearize import (  # the sibling test module: its model generators
    build_random_model,
    clean_version,
    robot_source,
    simulate_cal,
    truth_arrays,
)

from calib_dsl.compile.group import compile_model
from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.ir.dag import Dag
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program
from calib_dsl.propagate.fixpoint import propagate
from calib_dsl.relax.layout import independents
from calib_dsl.settings import DEFAULT
from calib_dsl.strategy.solution import Solution
from calib_dsl.strategy.tight import solve_tight
from calib_dsl.studies.simulate import simulate

ROOT = Path(__file__).resolve().parents[2]
RX90 = ROOT / "models" / "rx90_lengths.cal"


def true_values(prog: Program) -> tuple[np.ndarray, list[str]]:
    ind = independents(prog)
    names = [prog.slots.names[i] for i in ind]
    return np.array([prog.true_values[n] for n in names], dtype=float), names


def assert_sound_and_tighter(prog: Program, tight: Solution, hc4, truth: np.ndarray,
                             names: list[str], tol: float) -> None:
    """truth in tight's box, and tight's box in hc4's. Both stop when a sweep gains less than
    `tol` (relative), not at a fixed point, so tight's last propagation may stop a little
    earlier than hc4's did: each bound may exceed hc4's by tol * (hc4's width). Where both
    reached a fixed point (stop == "fixed point") the inclusion must be exact."""
    ind = independents(prog)
    assert tight.status == "contracted", (tight.status, tight.emptied)
    assert hc4.status == "contracted", (hc4.status, hc4.emptied)
    lo, hi = tight.lo[ind], tight.hi[ind]
    lost = np.flatnonzero(~((lo <= truth) & (truth <= hi)))
    assert len(lost) == 0, [(names[k], lo[k], truth[k], hi[k]) for k in lost]
    exact = tight.stop == hc4.stop == "fixed point"
    slack = 0.0 if exact else tol * (hc4.hi[ind] - hc4.lo[ind])
    wider = np.flatnonzero((lo < hc4.lo[ind] - slack) | (hi > hc4.hi[ind] + slack))
    assert len(wider) == 0, [(names[k], (lo[k], hi[k]), (hc4.lo[ind][k], hc4.hi[ind][k]))
                             for k in wider]
    # propagation's own result holds the truth too (else the comparison means nothing)
    assert np.all((hc4.lo[ind] <= truth) & (truth <= hc4.hi[ind]))


def rx90(tmp_path: Path, configs: int, seed: int, formulation: str) -> Program:
    data = tmp_path / f"rx90_{formulation}_{configs}_{seed}.csv"
    simulate(RX90, configs, seed, formulation=formulation, out_csv=data)
    return compile_model(elaborate(RX90, formulation=formulation, data=data))


@pytest.mark.slow
@pytest.mark.parametrize("formulation,configs,seed", [
    ("matrix", 8, 101), ("matrix", 11, 102), ("matrix", 14, 103), ("matrix", 17, 104),
    ("matrix", 20, 105), ("matrix", 20, 2004), ("rotation", 8, 106), ("rotation", 10, 107),
])
def test_rx90_tight_holds_the_truth_and_is_never_wider(tmp_path, formulation, configs, seed):
    prog = rx90(tmp_path, configs, seed, formulation)
    truth, names = true_values(prog)
    assert len(names) == 33
    tol = 1e-5
    tight = solve_tight(prog, tol=tol)
    hc4 = propagate(prog, tol=tol)
    assert tight.lp_rounds >= 1  # the LP did run
    assert_sound_and_tighter(prog, tight, hc4, truth, names, tol)


def _calibc() -> list[str]:
    """The `calibc` command through the interpreter running the tests (no PATH needed)."""
    return [sys.executable, "-c", "import sys; from calib_dsl.cli import main; "
            "sys.argv[0] = 'calibc'; main()"]


@pytest.mark.slow
def test_rx90_cli_simulate_and_solve(tmp_path):
    """The documented commands end to end: `calibc simulate`, then `calibc solve --json`."""
    calibc = _calibc()
    data = tmp_path / "d.csv"
    subprocess.run([*calibc, "simulate", str(RX90), "--configs", "9", "--seed", "77",
                    "-o", str(data)], check=True, capture_output=True)
    out = subprocess.run([*calibc, "solve", str(RX90), "--data", str(data), "--json", "-"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    res = json.loads(out.stdout)
    assert res["status"] == "contracted" and res["strategy"] == "tight"
    truth = compile_model(elaborate(RX90)).true_values  # stated, or the domains' centres
    for name, p in res["parameters"].items():
        lo, hi = p["result"]
        assert lo <= truth[name] <= hi, name


@pytest.mark.slow
@pytest.mark.parametrize("formulation", ["matrix", "rotation"])
def test_rx90_inconsistent_data_gives_a_valid_status(tmp_path, formulation):
    """One measured coordinate moved by 0.01 (100 times its tolerance): no parameter value
    fits, so any answer is sound; the run must end with a valid status and a sane box."""
    data = tmp_path / "d.csv"
    simulate(RX90, 10, 31, formulation=formulation, out_csv=data)
    rows = list(csv.reader(data.open()))
    col = rows[0].index("a1x")
    rows[3][col] = repr(float(rows[3][col]) + 0.01)
    with data.open("w", newline="") as f:
        csv.writer(f).writerows(rows)
    prog = compile_model(elaborate(RX90, formulation=formulation, data=data))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = solve_tight(prog)
    assert res.status in ("infeasible", "contracted")
    if res.status == "infeasible":
        assert res.emptied is not None and res.emptied.variable
    else:
        ind = independents(prog)
        assert np.all(res.lo[ind] <= res.hi[ind])
        assert not np.any(np.isnan(res.lo)) and not np.any(np.isnan(res.hi))


# -- random models -------------------------------------------------------------------------

@pytest.mark.slow
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1), joints=st.integers(1, 3), rows=st.integers(2, 8),
       spatial=st.booleans(), formulation=st.sampled_from(["matrix", "rotation"]),
       tol_q=st.sampled_from([1e-6, 1e-4]), tol_x=st.sampled_from([1e-5, 1e-3]))
def test_random_robots_tight_holds_the_truth(tmp_path_factory, seed, joints, rows, spatial,
                                             formulation, tol_q, tol_x):
    rng = np.random.default_rng(seed)
    source = robot_source(rng, joints, tol_q, tol_x, spatial)
    sim = simulate_cal(tmp_path_factory.mktemp("tight"), source, clean_version(source), rows,
                       seed, formulation)
    prog = sim.prog
    truth, names = true_values(prog)
    tol = 0.0 if seed % 2 else 1e-5  # tol 0: to the fixed point, where tight is inside hc4
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        tight = solve_tight(prog, tol=tol, max_sweeps=500)
        hc4 = propagate(prog, tol=tol, max_sweeps=500)
    assert_sound_and_tighter(prog, tight, hc4, truth, names, tol)


@pytest.mark.slow
@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(seed=st.integers(0, 2**32 - 1), n_p=st.integers(1, 4), n_cfg=st.integers(0, 3),
       n_con=st.integers(1, 5), depth=st.integers(1, 3), models=st.integers(1, 4))
def test_random_expression_models_tight_holds_the_truth(seed, n_p, n_cfg, n_con, depth, models):
    built = build_random_model(seed, n_p, n_cfg, 2, n_con, depth, models=models)
    assume(built is not None)
    prog, m = built
    p_true, _ = truth_arrays(prog, m)
    names = [prog.slots.names[i] for i in independents(prog)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        tight = solve_tight(prog, tol=1e-5, max_sweeps=200)
        hc4 = propagate(prog, tol=1e-5, max_sweeps=200)
    ind = independents(prog)
    assert hc4.status == "contracted", ("propagation lost the solution", hc4.emptied)
    assert tight.status == "contracted", ("tight lost the solution", tight.emptied)
    lost = np.flatnonzero(~((tight.lo[ind] <= p_true) & (p_true <= tight.hi[ind])))
    assert len(lost) == 0, [(names[k], tight.lo[ind][k], p_true[k], tight.hi[ind][k])
                            for k in lost]
    assert np.all((hc4.lo[ind] <= p_true) & (p_true <= hc4.hi[ind]))


# -- regressions: defects these tests found (fixed) -----------------------------------------

def test_tight_atan2_branch_cut_keeps_both_branches():
    dag = Dag()
    a = dag.var("a", -4.0, 4.0)
    y = dag.var("y", -0.5, 0.5)
    dag.constrain(a, "==", dag.op("atan2", y, dag.const(-1.0)))
    prog = compile_model(Model(path="atan2.cal", dag=dag))
    res = solve_tight(prog)
    ind = independents(prog)
    got = {prog.slots.names[i]: (res.lo[i], res.hi[i]) for i in ind}
    assert res.status == "contracted"
    for name, v in (("a", math.atan2(-0.1, -1.0)), ("y", -0.1),
                    ("a", math.atan2(0.1, -1.0)), ("y", 0.1)):
        assert got[name][0] <= v <= got[name][1], (name, v, got[name])


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("strategy", ["tight", "hc4"])
def test_equal_readings_in_two_configurations(tmp_path, strategy):
    _write(tmp_path, "d.csv", "q,x\n0.5,0.55\n0.5,0.45\n")
    model = _write(tmp_path, "m.cal", (
        "param p in [-1, 1] true 0;\n"
        'table m = "d.csv" { q : +- 0.1; x : +- 1e-9; }\n'
        "for k in 1..rows(m) { m.x[k] == p + m.q[k]; }\n"))
    prog = compile_model(elaborate(model))
    res = solve_tight(prog) if strategy == "tight" else propagate(prog)
    assert res.status == "contracted", res.emptied
    (i,) = independents(prog)
    for v in (-0.05, 0.0, 0.05):  # (p, q1, q2) = (v, 0.55 - v, 0.45 - v) is a solution
        assert res.lo[i] <= v <= res.hi[i]


def test_two_unknowns_equal_to_the_same_interval_stay_independent(tmp_path):
    model = _write(tmp_path, "k.cal", (
        "var x in [0, 2];\nvar y in [0, 2];\n"
        "x == 1 +- 0.1;\ny == 1 +- 0.1;\nx * y == 1;\n"))
    prog = compile_model(elaborate(model))
    res = solve_tight(prog)
    assert res.status == "contracted"
    got = {prog.slots.names[i]: (res.lo[i], res.hi[i]) for i in independents(prog)}
    assert set(got) == {"x", "y"}, got  # two unknowns, not one
    assert got["x"][0] <= 0.95 and got["y"][1] >= 1 / 0.95


def _plane_model(tmp_path: Path, curve: str) -> Program:
    """y_k = a u_k + b v_k + c (or a nonlinear surface), u, v known, y measured to 1e-3: each
    row mixes all three unknowns, so propagation alone gains little and the LP does the work."""
    rng = np.random.default_rng(7)
    u, v = rng.uniform(-1, 1, 40), rng.uniform(-1, 1, 40)
    f = {"plane": lambda a, b, c: a * u + b * v + c,
         "waves": lambda a, b, c: np.sin(a * u) + np.sin(b * v) + c}[curve]
    ys = f(0.3, -0.2, 0.1) + rng.uniform(-1e-3, 1e-3, len(u))
    rows = "".join(f"{float(x)!r},{float(y)!r},{float(z)!r}\n"
                   for x, y, z in zip(u, v, ys, strict=True))
    _write(tmp_path, "d.csv", "u,v,y\n" + rows)
    expr = {"plane": "a * m.u[i] + b * m.v[i] + c",
            "waves": "sin(a * m.u[i]) + sin(b * m.v[i]) + c"}[curve]
    model = _write(tmp_path, "m.cal", (
        "param a in [-1, 1] true 0.3;\nparam b in [-1, 1] true -0.2;\n"
        "param c in [-1, 1] true 0.1;\n"
        'table m = "d.csv" { u, v : +- 0; y : +- 1e-3; }\n'
        f"for i in 1..rows(m) {{ m.y[i] == {expr}; }}\n"))
    return compile_model(elaborate(model))


def test_a_linear_model_stops_after_one_cell_round_at_the_hull(tmp_path):
    from calib_dsl.relax.linearize import relax
    from calib_dsl.studies.reference import linearized_hull

    prog = _plane_model(tmp_path, "plane")
    rel = relax(prog, prog.slots.lo, prog.slots.hi, cell_variables=False)
    assert rel is not None and rel.remainder_share < 1e-6  # linear: only rounding is left
    res = solve_tight(prog)
    # one folded round, then one cell round, which is final: the model is linear
    assert res.status == "contracted" and res.lp_rounds == 2
    hull = linearized_hull(prog)
    for i in independents(prog):
        name = prog.slots.names[i]
        lo, hi = hull[name]
        assert res.lo[i] <= prog.true_values[name] <= res.hi[i]
        assert res.hi[i] - res.lo[i] <= (hi - lo) * 1.001 + 1e-12, (name, res.lo[i], res.hi[i])


def test_a_nonlinear_model_on_a_wide_box_is_not_settled(tmp_path):
    from calib_dsl.relax.linearize import relax

    prog = _plane_model(tmp_path, "waves")
    rel = relax(prog, prog.slots.lo, prog.slots.hi, cell_variables=False)
    assert rel is not None and rel.remainder_share > 0.5
    res = solve_tight(prog)
    assert res.status == "contracted"
    assert relax(prog, res.lo, res.hi, cell_variables=False).remainder_share < 0.5  # shrank
    for name, true in (("a", 0.3), ("b", -0.2), ("c", 0.1)):
        i = prog.slots.names.index(name)
        assert res.lo[i] <= true <= res.hi[i] and res.hi[i] - res.lo[i] < 1e-2


def test_without_cell_columns_a_settled_folded_round_is_the_last(tmp_path):
    prog = _plane_model(tmp_path, "plane")
    res = solve_tight(prog, settings=DEFAULT.tuned(max_cell_columns=0))  # as with 1000 rows
    assert res.status == "contracted" and res.lp_rounds == 1  # a second round: the same LP
    for name, true in (("a", 0.3), ("b", -0.2), ("c", 0.1)):
        i = prog.slots.names.index(name)
        assert res.lo[i] <= true <= res.hi[i] and res.hi[i] - res.lo[i] < 1e-2


# -- second-order rounds on wide boxes ----------------------------------------------------------

WIDE_ARM = """
param t1 in 0 +- 0.3 true {t1};
param t2 in 0 +- 0.3 true {t2};
param t3 in 0 +- 0.3 true {t3};
param a2 in pi/2 +- 0.3 true {a2};
param l1 in 0.5 +- 0.1 true {l1};
param l2 in 0.4 +- 0.1 true {l2};
param bz in 0 +- 0.05 true {bz};

robot arm(q1, q2, q3) {{
  joint theta = t1 + q1;
  joint alpha = a2, theta = t2 + q2;
  joint d = l1, theta = t3 + q3;
}}

table m = "data.csv" {{
  q1, q2, q3 : +- 1e-6 simulate in [-pi, pi];
  x, y, z : +- 1e-4;
}}

for k in 1..rows(m) {{
  arm(m.q1[k], m.q2[k], m.q3[k]) at (l2, 0, bz) == (m.x[k], m.y[k], m.z[k]);
}}
"""


def _wide_arm(tmp: Path, seed: int):
    """The wide arm with a truth drawn inside the middle half of each domain, simulated: the
    program and the true unknowns."""
    rng = np.random.default_rng(seed)
    truth = {"t1": rng.uniform(-0.15, 0.15), "t2": rng.uniform(-0.15, 0.15),
             "t3": rng.uniform(-0.15, 0.15), "a2": math.pi / 2 + rng.uniform(-0.15, 0.15),
             "l1": 0.5 + rng.uniform(-0.05, 0.05), "l2": 0.4 + rng.uniform(-0.05, 0.05),
             "bz": rng.uniform(-0.025, 0.025)}
    source = WIDE_ARM.format(**{k: repr(float(v)) for k, v in truth.items()})
    sim = simulate_cal(tmp, source, clean_version(source), 12, seed, "matrix")
    return sim.prog, sim.p_true


@pytest.mark.slow
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1))
def test_second_order_rounds_contract_where_first_order_cannot(tmp_path_factory, seed):
    """A 3-joint arm with joint offsets of +-0.3 rad: first-order rounds stall on the search
    domains (curvature far above WIDE); second-order rounds bring every parameter below 1 %
    of its domain, the truth inside. The truth is drawn inside the middle half of each domain."""
    prog, p_true = _wide_arm(tmp_path_factory.mktemp("arm"), seed)
    ind = independents(prog)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        first = solve_tight(prog, second_order=False)
        second = solve_tight(prog)
    for res in (first, second):
        assert res.status == "contracted"
        assert np.all(res.lo[ind] <= p_true) and np.all(p_true <= res.hi[ind])
    domain = prog.slots.hi[ind] - prog.slots.lo[ind]
    ratio = (second.hi[ind] - second.lo[ind]) / domain
    assert np.all(ratio < 0.01), ratio
    assert np.all(second.hi[ind] - second.lo[ind] <= first.hi[ind] - first.lo[ind])


@pytest.mark.slow
@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1))
def test_reused_multipliers_save_lp_rounds_and_keep_the_truth(tmp_path_factory, seed):
    """On the wide arm, rounds that reuse the last LPs' multipliers replace LP rounds: fewer
    LP rounds, the truth inside, every parameter below 1 % of its domain as without them."""
    prog, p_true = _wide_arm(tmp_path_factory.mktemp("arm"), seed)
    ind = independents(prog)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        reusing = solve_tight(prog)
        plain = solve_tight(prog, settings=DEFAULT.tuned(reuse_rounds=0))  # LPs every round
    assert reusing.reused_rounds > 0 and plain.reused_rounds == 0
    assert reusing.lp_rounds < plain.lp_rounds
    domain = prog.slots.hi[ind] - prog.slots.lo[ind]
    for res in (reusing, plain):
        assert res.status == "contracted"
        assert np.all(res.lo[ind] <= p_true) and np.all(p_true <= res.hi[ind])
        assert np.all((res.hi[ind] - res.lo[ind]) / domain < 0.01)


# -- parameters that are not identifiable alone: split into pieces ------------------------------
# (what the solve does where it cannot take their identifiable combination as an unknown,
# reparametrize.py: here, with combinations=False)

PARALLEL_ARM = """
param t1 in 0 +- 0.02 true {t1};
param a2 in pi/2 +- 0.02 true {a2};
param t2 in 0 +- 0.02 true {t2};
param r2 in 0 +- {rr} true {r2};
param a3 in 0 +- 0.02 true {a3};
param d3 in 0.4 +- 0.01 true {d3};
param t3 in 0 +- 0.02 true {t3};
param r3 in 0 +- {rr} true {r3};
param l in 0.3 +- 0.01 true {l};

robot arm(q1, q2, q3) {{
  joint theta = t1 + q1;
  joint alpha = a2, theta = t2 + q2, r = r2;
  joint alpha = a3, d = d3, theta = t3 + q3, r = r3;
}}

table m = "data.csv" {{
  q1, q2, q3 : +- 1e-5 simulate in [-pi, pi];
  x, y, z : +- 1e-4;
}}

for k in 1..rows(m) {{
  arm(m.q1[k], m.q2[k], m.q3[k]) at (l, 0, 0.1) == (m.x[k], m.y[k], m.z[k]);
}}
"""


def _parallel_arm(tmp: Path, seed: int, rr: float):
    """An arm whose joints 2 and 3 have parallel axes (alpha3 = 0 at the nominal values): only
    r2 + r3 is identifiable, as on the RX90. The truth is drawn inside the domains, r2 and r3
    within 60 % of theirs, alpha3 exactly 0 (as on the RX90) or anywhere within 1e-3 of it
    (then r2 and r3 are identifiable in theory, not in practice)."""
    rng = np.random.default_rng(seed)
    truth = {"t1": rng.uniform(-0.01, 0.01), "a2": math.pi / 2 + rng.uniform(-0.01, 0.01),
             "t2": rng.uniform(-0.01, 0.01), "r2": rng.uniform(-0.6, 0.6) * rr,
             "a3": rng.uniform(-1e-3, 1e-3) if rng.uniform() < 0.5 else 0.0,
             "d3": 0.4 + rng.uniform(-0.005, 0.005),
             "t3": rng.uniform(-0.01, 0.01), "r3": rng.uniform(-0.6, 0.6) * rr,
             "l": 0.3 + rng.uniform(-0.005, 0.005)}
    source = PARALLEL_ARM.format(rr=rr, **{k: repr(float(v)) for k, v in truth.items()})
    return simulate_cal(tmp, source, clean_version(source), 12, seed, "matrix")


def arm_solved_twice(tmp: Path, seed: int, first: dict, second: dict) -> tuple:
    """The arm with parallel axes (r2, r3 of +-0.05 m) solved with two sets of options:
    (program, true unknowns, their slots, their names, first result, second result)."""
    sim = _parallel_arm(tmp, seed, 0.05)
    prog = sim.prog
    ind = independents(prog)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        a, b = solve_tight(prog, **first), solve_tight(prog, **second)
    return prog, sim.p_true, ind, [prog.slots.names[i] for i in ind], a, b


@pytest.mark.slow
@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1))
def test_split_of_a_non_identifiable_parameter(tmp_path_factory, seed):
    """r2 and r3 of +-0.05 m on parallel axes: the solve cuts one of them into pieces, and the
    hull of the pieces holds the truth, lies inside the unsplit result, and is narrower than it
    (the slack of the wide r2, r3 in every row is gone); the enclosure of r2 + r3 holds it."""
    from calib_dsl.analysis.identify import analyse, combination_enclosures

    # (without the fine rounds that keep the readings as LP columns: they take most of the
    # same slack out of the unsplit result, and this is about the split)
    alone = DEFAULT.tuned(remainder_readings=1.0)
    prog, p_true, ind, names, whole, cut = arm_solved_twice(
        tmp_path_factory.mktemp("par"), seed,
        {"split": False, "combinations": False, "settings": alone},
        {"combinations": False, "settings": alone})
    assert whole.status == cut.status == "contracted"
    assert cut.split and cut.split[0] in ("r2", "r3") and 1 <= len(cut.pieces) <= 4
    for res in (whole, cut):
        assert np.all(res.lo[ind] <= p_true) and np.all(p_true <= res.hi[ind])
    for plo, phi in cut.pieces:  # every piece inside the hull returned
        assert np.all(cut.lo <= plo) and np.all(phi <= cut.hi)
    assert np.all(cut.lo[ind] >= whole.lo[ind]) and np.all(cut.hi[ind] <= whole.hi[ind])
    ratio = (cut.hi[ind] - cut.lo[ind]) / (whole.hi[ind] - whole.lo[ind])
    others = [k for k, n in enumerate(names) if n not in ("r2", "r3")]
    # The box of the other seven shrinks: geometric mean 0.66-0.91 over 40 seeds (one of them
    # may barely move, so not each one); no shrink at all would be 1.
    assert np.exp(np.mean(np.log(ratio[others]))) < 0.95, dict(zip(names, ratio, strict=True))
    info = analyse(prog)  # at the true values: r2 + r3 only if alpha3 is 0
    cut_sums = combination_enclosures(prog, info, cut.lo, cut.hi, True, cut.pieces)
    whole_sums = combination_enclosures(prog, info, whole.lo, whole.hi, True)
    k = [t for t, _, _ in cut_sums].index("r2 + r3") if any(
        t == "r2 + r3" for t, _, _ in cut_sums) else None
    if k is None:
        return
    (text, a, b), (_, a0, b0) = cut_sums[k], whole_sums[k]
    s = p_true[names.index("r2")] + p_true[names.index("r3")]
    assert a <= s <= b and a0 <= s <= b0, text
    assert b - a <= 1.01 * (b0 - a0)  # not wider (narrower unless r2 + r3 is near its edge)


@pytest.mark.slow
def test_split_pieces_go_to_a_cluster_when_there_is_one(tmp_path, monkeypatch):
    """Where a batch job runs on a cluster (strategy/cluster.py), the split hands its pieces to
    it instead of child processes; the result is the same, bit for bit."""
    from calib_dsl.strategy import split

    sim = _parallel_arm(tmp_path, 7, 0.05)
    handed = []

    class Cluster:  # the cluster's map, run here
        def map(self, fn, calls):
            handed.append(len(calls))
            return [fn(*args) for args in calls]

        def close(self):
            pass

    results = []
    for pieces in (None, Cluster()):
        monkeypatch.setattr(split, "cluster_pieces", lambda p=pieces: p)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            results.append(solve_tight(sim.prog, combinations=False))
    here, there = results
    assert handed and handed[0] == len(there.pieces) >= 1
    assert np.array_equal(here.lo, there.lo) and np.array_equal(here.hi, there.hi)


@pytest.mark.slow
def test_split_pieces_refined_in_children_as_here(tmp_path, monkeypatch):
    """The pieces go to two child processes (workers.py); the result is the one the solving
    process gives when it refines them itself, bit for bit."""
    from calib_dsl.strategy import split

    sim = _parallel_arm(tmp_path, 7, 0.05)
    ran = []
    children_map = split.Children.map

    def recorded(self, *args):
        out = children_map(self, *args)
        ran.append(out is not None)
        return out

    monkeypatch.setattr(split.Children, "map", recorded)
    results = []
    for processes in (2, 1):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            results.append(solve_tight(sim.prog, combinations=False,
                                       settings=replace(DEFAULT, piece_processes=processes)))
    assert ran == [True]  # the children ran (once: one process refines them itself)
    two, one = results
    assert two.split and two.split == one.split and len(two.pieces) == len(one.pieces)
    assert np.array_equal(two.lo, one.lo) and np.array_equal(two.hi, one.hi)
    for (a, b), (c, d) in zip(two.pieces, one.pieces, strict=True):
        assert np.array_equal(a, c) and np.array_equal(b, d)


def test_no_split_where_it_does_not_pay(tmp_path):
    """The same arm with r2 and r3 known to +-2 mm: their slack is already small, a piece's
    relaxation is hardly narrower, and nothing is split (no rounds spent for nothing)."""
    sim = _parallel_arm(tmp_path, 3, 0.002)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = solve_tight(sim.prog, combinations=False)
    assert res.status == "contracted" and res.split == () and res.pieces == ()


@pytest.mark.slow
def test_split_is_reported(tmp_path):
    from calib_dsl import sections
    from calib_dsl.report.as_json import result_json
    from calib_dsl.report.extras import Extras
    from calib_dsl.report.text import render_summary

    sim = _parallel_arm(tmp_path, 4, 0.05)  # alpha3 = 0: only r2 + r3 is identifiable
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = solve_tight(sim.prog, combinations=False)
    extra = Extras()
    sections.identify(extra, sim.prog, res, use_lp=True)
    text = render_summary(sim.prog, res, "tight", extra)
    assert f"split: {res.split[0]} (not identifiable alone)" in text
    assert "guaranteed: r2 + r3 in [" in text
    data = result_json(sim.prog, res, "tight", extra)
    assert data["split"] == {"parameters": list(res.split), "pieces": len(res.pieces)}


@settings(max_examples=300, deadline=None)
@given(data=st.data(), per=st.integers(1, 6))
def test_pieces_cover_the_box(data, per):
    """The pieces of a split tile the box: along the cut slot they chain from its lower end to
    its upper end (shared float endpoints), and every other slot keeps its interval."""
    from calib_dsl.strategy.split import pieces

    n = 4
    bound = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
    lo = np.array(data.draw(st.lists(bound, min_size=n, max_size=n)))
    width = np.array(data.draw(st.lists(st.floats(0, 1e6), min_size=n, max_size=n)))
    hi = lo + width
    s = data.draw(st.integers(0, n - 1))
    boxes = pieces(lo, hi, s, per)
    assert len(boxes) == per
    rest = [i for i in range(n) if i != s]
    for plo, phi in boxes:
        assert np.all(plo <= phi) and np.all(lo <= plo) and np.all(phi <= hi)
        assert np.array_equal(plo[rest], lo[rest]) and np.array_equal(phi[rest], hi[rest])
    assert boxes[0][0][s] == lo[s] and boxes[-1][1][s] == hi[s]
    assert all(boxes[k][1][s] == boxes[k + 1][0][s] for k in range(per - 1))
