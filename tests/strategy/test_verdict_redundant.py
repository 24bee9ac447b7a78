"""Proofs of inconsistency where the data cannot separate some parameters (strategy/refute.py
in the solve's own unknowns, along the identifiable combinations), and the `--min-error`
bracket they close (analysis/min_error.py): a UR5 with all 33 chain, base and target
parameters free, as models/ur10_all.cal is for the UR10, on campaigns simulated here (no
shipped model or table), and models/ur10_all.cal itself. Their `--min-error` brackets within
2 % (minutes each) run in bench/checks/test_brackets_redundant.py."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.pipeline import solve
from calib_dsl.problem import Problem
from calib_dsl.settings import Settings
from calib_dsl.strategy.refute import Refuter
from calib_dsl.strategy.reparametrize import along_combinations
from tests.simulated_ur5 import JOINTS, PARAMS, ROBOT, simulate_rows, write_table
from tests.test_held_out_battery import campaign

E = 0.1  # mm, per axis
COLUMNS = ["q1", "q2", "q3", "q4", "q5", "q6", "x", "y", "z"]
MODELS = Path(__file__).resolve().parents[2] / "models"
# the parameters tests/simulated_ur5.py holds at their nominal values, freed here
NOMINAL = {"alpha1": 0.01, "d1": 5, "theta1": 0.01, "r1": 5, "r3": 5, "r4": 5,
           "alpha6": 0.01, "d6": 5, "theta6": 0.01, "r6": 5}


def every_parameter_free(tmp: Path, rows: int, seed: int) -> Path:
    """A UR5 model with all its parameters free (10 more than the data can separate), its
    true values stated, and a table simulated within +- E of them."""
    tmp.mkdir(parents=True, exist_ok=True)
    data = simulate_rows(tmp, rows, seed, E)
    write_table(tmp / "data.csv", data, COLUMNS, lambda r, c: r[c])
    lines = ["units mm, rad;", f'include "{ROBOT}";', f"const e = {E!r};"]
    lines += [f"param {n} in {c} +- {w!r} true {t!r};" for n, (c, w, t) in PARAMS.items()]
    lines += [f"param {n} in ur5_{n} +- {w!r} true ur5_{n};" for n, w in NOMINAL.items()]
    lines += ['table m = "data.csv" {', "  q1, q2, q3, q4, q5, q6 : +- 0;", "  x, y, z : +- e;",
              "}", "for k in 1..rows(m) {",
              f"  ur5({JOINTS}) at (tx, ty, tz) == (m.x[k], m.y[k], m.z[k]);", "}"]
    model = tmp / "ur5_all.cal"
    model.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return model


def test_the_refuter_moves_to_the_solves_unknowns(tmp_path):
    """The rounds and the split see the program along the combinations, on the solve's box
    (its first slots) and the combinations' certified bounds; the members left free are
    not cut. A proof found there holds for the program as written: the change is exact."""
    problem = Problem.load(every_parameter_free(tmp_path, 12, 3))
    prog = problem.program
    s = Settings()
    res = solve(prog, settings=s)
    assert res.combinations, "the data separate every parameter: nothing to test"
    rep = along_combinations(prog, s)
    assert rep is not None
    r = Refuter(prog, res, None, None, s, 1e-5, 1000, 0.0, 0.0)
    r.in_solve_unknowns()
    assert r.prog is not prog and len(r.prog.slots.names) == len(rep.prog.slots.names)
    n = rep.old_slots
    assert np.array_equal(r.res.lo[:n], res.lo) and np.array_equal(r.res.hi[:n], res.hi)
    for (_, a, b), (_, slot, _, _) in zip(res.combinations, rep.combinations, strict=True):
        assert a <= r.res.lo[slot] <= r.res.hi[slot] <= b
    assert r.uncut is not None and set(r.uncut.tolist()) == set(rep.free)
    assert r._widest(r.res.lo, r.res.hi) not in set(rep.free)


@pytest.mark.slow
def test_the_truth_is_never_refuted_in_the_solves_unknowns(tmp_path, seed=8):
    """At the bound the table was simulated within, the effort (fine rounds and a split in
    the solve's unknowns, a budget of five solves) never proves the data inconsistent."""
    model = every_parameter_free(tmp_path, 12, seed)
    prog = Problem.load(model).program
    s = Settings()
    res = solve(prog, settings=s)
    assert res.status != "infeasible" and res.combinations
    refuter = Refuter(prog, res, None, None, s, 1e-5, 1000, 5 * res.seconds,
                      time.perf_counter())
    found = refuter.run([])
    assert found.proof is None, found.tried
    assert refuter.prog is not prog and found.tried  # (it ran, in the solve's unknowns)


@pytest.mark.slow
@settings(max_examples=3, deadline=None,  # 12 in bench/checks/test_soundness_full.py
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(robot=st.sampled_from(["arm4_dh.cal", "arm5_mdh.cal"]),
       poses=st.sampled_from(["random", "grid", "repeated"]),
       rows=st.integers(8, 24), seed=st.integers(0, 10**6))
def test_consistent_campaigns_of_other_robots_are_never_refuted(tmp_path_factory, robot, poses,
                                                                rows, seed):
    """Robots written for the held-out battery (standard DH with exact joints, with a base
    height the data see only through bz + d1; modified DH with joint errors, degrees and
    metres), campaigns drawn within their bounds: the effort (in the solve's unknowns where
    the data see a combination, as on the first; as written on the second) never proves
    them inconsistent, and the truth stays in the solve's box."""
    tmp = tmp_path_factory.mktemp("redundant")
    model = campaign(tmp, robot, "--configs", rows, "--seed", seed, "--poses", poses)
    prog = Problem.load(model).program
    s = Settings()
    res = solve(prog, settings=s)
    assert res.status != "infeasible"
    for k, name in enumerate(prog.slots.names[:len(res.lo)]):
        true = prog.true_values.get(name)
        if true is not None:
            assert res.lo[k] <= true <= res.hi[k], (name, true, res.lo[k], res.hi[k])
    refuter = Refuter(prog, res, None, None, s, 1e-5, 1000, 3 * res.seconds,
                      time.perf_counter())
    found = refuter.run([])
    assert found.proof is None, found.tried


def test_a_failed_change_of_unknowns_leaves_the_effort_as_written(tmp_path, monkeypatch):
    """A failure while building the combinations' program (memory, say) proves nothing: the
    effort stays in the unknowns as written, and tries the change once."""
    import calib_dsl.strategy.refute as refute

    problem = Problem.load(every_parameter_free(tmp_path, 12, 3))
    prog = problem.program
    s = Settings()
    res = solve(prog, settings=s)
    assert res.combinations

    def fails(*_args, **_kw):
        raise MemoryError

    monkeypatch.setattr(refute, "along_combinations", fails)
    r = Refuter(prog, res, None, None, s, 1e-5, 1000, 0.0, 0.0)
    r.in_solve_unknowns()
    assert r.prog is prog and r.uncut is not None and len(r.uncut) == 0
    r.in_solve_unknowns()  # (once: no second attempt)
