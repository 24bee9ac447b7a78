"""calibc plan: the stages, the plan as a subset of the candidates, predictions, sweeps,
planning after measured rows, and the truth inside every simulated solve."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.plan.classical import d_optimal, information, log_widths, marginal_exchange
from calib_dsl.plan.configs import draw_configurations, read_configurations, table_of
from calib_dsl.plan.planner import Problem, given_rows, linear, plan, sweep
from calib_dsl.plan.refine import hull_of, refine, rows_of, score
from calib_dsl.settings import DEFAULT
from calib_dsl.studies.simulate import simulate
from tests.cli_run import run

ROOT = Path(__file__).resolve().parents[2]
ARM = ROOT / "models" / "examples" / "planar_arm.cal"
BOUND = {"e": "0.01"}


def candidates(tmp_path: Path, rows: int = 120, seed: int = 3) -> Path:
    path = tmp_path / f"cand{seed}.csv"
    simulate(ARM, rows, seed, out_csv=path, consts=BOUND)
    return path


def pool(path: Path):
    return read_configurations(table_of(elaborate(str(ARM), simulate_rows=1)), path)


def test_the_plan_is_a_subset_of_the_candidates_own_lines(tmp_path):
    cand = candidates(tmp_path)
    out = tmp_path / "plan.csv"
    result = run("plan", ARM, "--candidates", cand, "--n", 5, "-o", out, "-D", "e=0.01")
    assert result.exit_code == 0, result.output
    lines = cand.read_text().splitlines()
    planned = out.read_text().splitlines()
    assert planned[0] == lines[0] and len(planned) == 6
    assert set(planned[1:]) <= set(lines[1:]) and len(set(planned[1:])) == 5
    assert "median predicted width / domain" in result.output


def test_planned_beats_random_sets_in_its_criterion_and_the_truth_is_inside(tmp_path):
    configs = pool(candidates(tmp_path))
    problem = Problem(ARM, DEFAULT, consts=BOUND, seed=1)
    p = plan(problem, configs, 5)
    lin, _ = linear(problem, configs, None)
    planned = score(hull_of(rows_of(lin.blocks, p.rows, None), lin.box), lin.box)
    rng = np.random.default_rng(0)
    randoms = [score(hull_of(rows_of(lin.blocks, rng.choice(len(configs), 5, replace=False),
                                     None), lin.box), lin.box) for _ in range(10)]
    assert planned < np.mean(randoms)
    assert all(s is not None and s.truth_inside for s in p.solved.values())
    assert p.chosen in {s.name for s in p.stages} and len(p.rows) == 5


def test_the_same_inputs_and_seed_give_the_same_plan(tmp_path):
    configs = pool(candidates(tmp_path))
    a, b = (plan(Problem(ARM, DEFAULT, consts=BOUND, seed=5), configs, 6) for _ in range(2))
    assert a.rows.tolist() == b.rows.tolist() and a.chosen == b.chosen


def test_the_exchanges_never_undo_what_the_start_had():
    rng = np.random.default_rng(4)
    blocks = rng.normal(size=(80, 2, 5))
    greedy = d_optimal(blocks, 6, 0.1, 0, 80)
    exchanged = d_optimal(blocks, 6, 0.1, 10, 80)
    logdet = [np.linalg.slogdet(information(blocks, c, 0.1))[1] for c in (greedy, exchanged)]
    assert logdet[1] >= logdet[0] - 1e-9 and len(set(exchanged.tolist())) == 6
    after = marginal_exchange(blocks, exchanged, 0.1, 10, 80)

    def variances(c):
        return np.sum(np.log(np.diag(np.linalg.inv(information(blocks, c, 0.1)))))
    assert variances(after) <= variances(exchanged) + 1e-9
    # log_widths is the criterion of the information with each candidate added
    m = information(blocks, exchanged, 0.1)
    one = int(np.setdiff1d(np.arange(80), exchanged)[0])
    direct = np.sum(np.log(np.diag(np.linalg.inv(m + blocks[one].T @ blocks[one]))))
    assert log_widths(blocks, m)[one] == pytest.approx(direct)


def test_the_lp_exchange_only_keeps_swaps_that_narrow():
    rng = np.random.default_rng(5)
    blocks = rng.normal(size=(60, 2, 4))
    box = (np.full(4, -1.0), np.full(4, 1.0))
    start = np.arange(6)
    got = refine(blocks, start, box, 3, 30)
    assert got.score <= got.start
    assert got.score == pytest.approx(score(hull_of(rows_of(blocks, got.chosen, None), box),
                                            box))


@given(st.integers(0, 10_000), st.integers(4, 12))
@settings(max_examples=25, deadline=None)
def test_noise_only_narrows_the_linearized_set(seed, rows):
    """(P_e - P_e) / 2 lies in P_0: no noise draw widens the noise-free hull, the
    criterion's worst case."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(rows, 3))
    box = (np.full(3, -1.0), np.full(3, 1.0))
    free = hull_of(a, box)
    noisy = hull_of(a, box, rng.uniform(-1, 1, rows))
    assert np.all(noisy.hi - noisy.lo <= free.hi - free.lo + 1e-9)


@given(st.integers(0, 10_000), st.integers(4, 40))
@settings(max_examples=25, deadline=None)
def test_no_design_brings_the_noise_free_hull_below_its_floor(seed, rows):
    """The floor of docs/planning.md: the point moved along unknown k by 1 / max |a_ik|
    satisfies every row, so the noise-free width is at least 2 / max |a_ik| (within the
    box), whatever the rows; noise is what a set can gain below it."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(rows, 4)) * rng.uniform(0.1, 3.0, 4)
    box = (np.full(4, -1.0), np.full(4, 1.0))
    free = hull_of(a, box)
    floor = np.minimum(2.0 / np.abs(a).max(axis=0), 2.0)
    assert np.all(free.hi - free.lo >= floor - 1e-7)
    noisy = hull_of(a, box, rng.uniform(-1, 1, rows))
    assert np.all(noisy.hi - noisy.lo <= free.hi - free.lo + 1e-9)


def test_drawn_candidates_stay_within_the_joint_limits():
    t = table_of(elaborate(str(ARM), simulate_rows=1))
    drawn = draw_configurations(t, 500, np.random.default_rng(1), {"q1": (-0.5, 0.25)})
    assert drawn.q.shape == (500, 2)
    assert drawn.q[:, 0].min() >= -0.5 and drawn.q[:, 0].max() <= 0.25
    assert drawn.q[:, 1].min() >= -np.pi and drawn.q[:, 1].max() <= np.pi


def test_without_candidates_the_plan_is_drawn_and_written_in_the_dialect(tmp_path):
    out = tmp_path / "plan.csv"
    result = run("plan", ARM, "--n", 4, "-o", out, "-D", "e=0.01")
    assert result.exit_code == 0, result.output
    lines = out.read_text().splitlines()
    assert lines[0] == "q1,q2" and len(lines) == 5


def test_a_sweep_names_the_smallest_count_meeting_the_targets(tmp_path):
    configs = pool(candidates(tmp_path))
    problem = Problem(ARM, DEFAULT, consts=BOUND)
    free = sweep(problem, configs, [3, 6, 12], {})
    goal = {"l1": float(free.widths[1][0]) * 1.0001}
    swept = sweep(problem, configs, [3, 6, 12], goal)
    meets = [n for n, w in zip(swept.counts, swept.widths, strict=True)
             if w[0] <= goal["l1"]]
    assert swept.enough == meets[0]
    assert np.all(swept.widths[-1] < swept.widths[0])  # 12 rows narrow more than 3
    result = run("plan", ARM, "--candidates", tmp_path / "cand3.csv", "--n", "3..12:3",
                 "--target", "l1=1e-9", "-o", tmp_path / "p.csv", "-D", "e=0.01")
    assert result.exit_code == 0, result.output
    assert "smallest N meeting every target (l1 <= 1e-09): none up to 12" in result.output


def test_planning_after_measured_rows_starts_from_their_solve(tmp_path):
    done = tmp_path / "done.csv"
    simulate(ARM, 4, 9, out_csv=done, consts=BOUND)
    configs = pool(candidates(tmp_path))
    problem = Problem(ARM, DEFAULT, consts=BOUND, seed=2)
    measured = given_rows(problem, done)
    first = {n: hi - lo for n, (lo, hi) in measured.domains.items()}
    p = plan(problem, configs, 4, measured)
    assert p.domain.tolist() == pytest.approx([first[n] for n in p.names])
    assert np.all(p.predicted <= p.domain)  # the next rows only narrow what the first gave
    assert all(s is not None and s.truth_inside for s in p.solved.values())


@pytest.mark.parametrize("args, says", [
    (("--n", "0"), "--n 0"), (("--n", "5..2"), "--n 5..2"), (("--n", "x"), "--n x"),
    (("--n", "500"), "a count from 1 to the 120 candidates"),
    (("--n", "3..6", "--target", "zz=1"), "no unknown 'zz'"),
    (("--n", "3..6", "--target", "l1=-1"), "--target l1=-1"),
    (("--n", "3..6", "--plot", "f.txt"), "cannot plot to 'f.txt'"),
    (("--n", "3", "--target", "l1=1"), "for a range of counts"),
])
def test_user_errors_are_one_line_and_exit_2(tmp_path, args, says):
    cand = candidates(tmp_path)
    result = run("plan", ARM, "--candidates", cand, "-o", tmp_path / "p.csv", "-D",
                 "e=0.01", *args)
    assert result.exit_code == 2, result.output
    assert says in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1


@pytest.mark.slow
@given(st.integers(0, 10_000), st.integers(3, 8))
@settings(max_examples=2, deadline=None,  # 8 in bench/checks/test_soundness_full.py
          suppress_health_check=list(HealthCheck))
def test_the_truth_lies_inside_every_simulated_solve(tmp_path_factory, seed, count):
    tmp = tmp_path_factory.mktemp("truth")
    configs = pool(candidates(tmp, rows=40, seed=seed))
    p = plan(Problem(ARM, DEFAULT, consts={"e": "0.001"}, seed=seed), configs, count)
    assert p.solved and all(s is not None and s.truth_inside for s in p.solved.values())
