"""The held-out battery: campaigns nobody tuned to, run through every command a user runs.

`calibc simulate` draws campaigns (random, grid and repeated poses; with and without a
systematic error) of robots written here (tests/held_out_robots.py: other DH tables and
conventions, joint errors, units, a 6-DOF tracker) and, in the slow part, of the shipped UR10,
UR5 and RX90 models at other sizes. Every command must exit 0 (consistent), 1 (proven
inconsistent) or 2 (a user error), never 3; state its verdict; write strict JSON (no NaN or
Infinity tokens); and every result must hold the true values whenever the data are drawn
within their bounds."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from cli_run import run
from held_out_robots import GENERATORS, ROBOTS

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"


def strict(text: str) -> dict:
    """JSON as a strict parser reads it: NaN, Infinity and -Infinity are refused."""

    def refuse(token: str) -> None:
        raise AssertionError(f"non-standard JSON token {token}")

    return json.loads(text, parse_constant=refuse)


def calibc(*args: object, cwd: Path, codes: tuple[int, ...] = (0,)):
    res = run(*args, cwd=cwd)
    shown = f"calibc {' '.join(map(str, args))}: exit {res.exit_code}\n{res.output[-3000:]}"
    assert res.exit_code in codes, shown
    assert "Traceback" not in res.output and "internal error" not in res.output, shown
    return res


def truths_inside(result: dict) -> None:
    """Every unknown with a stated true value holds it in its result."""
    assert result["parameters"], "no parameter in the result"
    for name, p in result["parameters"].items():
        if p.get("true") is not None:
            lo, hi = p["result"]
            assert lo <= p["true"] <= hi, (name, p["true"], p["result"])


def campaign(tmp: Path, robot: str, *options: object) -> Path:
    """The robot's model and a campaign simulated for its table, in tmp."""
    source, table, generator = ROBOTS[robot]
    (tmp / robot).write_text(source)
    if generator != robot:
        (tmp / generator).write_text(GENERATORS[generator])
    calibc("simulate", generator, "-o", table, "-q", *options, cwd=tmp)
    return tmp / robot


def solve_json(tmp: Path, model: Path | str, *options: object, codes: tuple[int, ...] = (0,),
               name: str = "result.json") -> tuple[int, dict]:
    res = calibc("solve", model, "-q", "--json", name, *options, cwd=tmp, codes=codes)
    return res.exit_code, strict((tmp / name).read_text())


# -- small campaigns of the new robots ------------------------------------------------------
# the editing loop (unmarked) runs each robot and each kind of poses once
FAST_PAIRS = {("arm4_dh.cal", "random"), ("arm5_mdh.cal", "grid"), ("arm4_dh.cal", "repeated")}


@pytest.mark.parametrize(("robot", "poses"), [
    (robot, poses) if (robot, poses) in FAST_PAIRS else pytest.param(robot, poses,
                                                                     marks=pytest.mark.slow)
    for robot in ("arm4_dh.cal", "arm5_mdh.cal") for poses in ("random", "grid", "repeated")])
def test_a_new_robot_is_calibrated_with_its_truth_inside(tmp_path, robot, poses):
    model = campaign(tmp_path, robot, "--configs", 30, "--seed", 11, "--poses", poses)
    _, result = solve_json(tmp_path, model, "--no-identify")
    assert result["verdict"] == "consistent"
    truths_inside(result)


@pytest.mark.slow
def test_a_puma_measured_near_joint_6s_axis_keeps_its_truth(tmp_path):
    """Standard DH, 24 parameters, the tool point 0.5 mm from joint 6's axis: two angles the
    data barely see keep their whole domains (split.split_loose's case), every result still
    holds the truth."""
    model = campaign(tmp_path, "puma560.cal", "--configs", 40, "--seed", 5)
    _, result = solve_json(tmp_path, model, "--no-identify")
    assert result["verdict"] == "consistent"
    truths_inside(result)


def test_a_systematic_error_within_the_bound_keeps_the_truth(tmp_path):
    e = 0.05  # arm4_dh.cal's bound
    model = campaign(tmp_path, "arm4_dh.cal", "--configs", 30, "--seed", 3, "--no-noise",
                     "--systematic", 0.8 * e)
    _, result = solve_json(tmp_path, model, "--no-identify")
    assert result["verdict"] == "consistent"
    truths_inside(result)


def test_a_systematic_error_far_beyond_the_bound_is_proven_inconsistent(tmp_path):
    model = campaign(tmp_path, "arm4_dh.cal", "--configs", 30, "--seed", 3,
                     "--systematic", 40 * 0.05)
    code, result = solve_json(tmp_path, model, "--no-identify", codes=(1,))
    assert result["verdict"] == "inconsistent"
    out = run("solve", model.name, "-q", "--no-identify", cwd=tmp_path).output
    assert "verdict: inconsistent" in out


@pytest.mark.slow
def test_every_command_on_a_new_robot(tmp_path):
    """solve (default, --json, --inner, --outliers 1, --min-error, --report), identify,
    validate, predict, plot, export (each format), plan and report on one campaign."""
    model = campaign(tmp_path, "arm4_dh.cal", "--configs", 30, "--seed", 5).name
    calibc("simulate", model, "--configs", 20, "--seed", 6, "-o", "held.csv", "-q",
           cwd=tmp_path)
    _, result = solve_json(tmp_path, model, "--report", "solve.html")
    truths_inside(result)
    assert "verdict: consistent" in calibc("solve", model, "-q", cwd=tmp_path).output
    calibc("solve", model, "-q", "--inner", cwd=tmp_path)
    _, outliers = solve_json(tmp_path, model, "--outliers", 1, "--no-identify",
                             name="outliers.json")
    truths_inside(outliers)
    calibc("solve", model, "-q", "--min-error", "e", "--json", "min.json", cwd=tmp_path)
    strict((tmp_path / "min.json").read_text())
    ident = strict(calibc("identify", model, "--json", cwd=tmp_path).stdout)
    (tmp_path / "identify.json").write_text(json.dumps(ident))
    calibc("validate", model, "--at", "held.csv", "-q", "--json", "v.json", cwd=tmp_path)
    assert strict((tmp_path / "v.json").read_text())["coverage"] == 1.0
    calibc("predict", model, "--at", "held.csv", "-q", "--json", "p.json", "--csv", "p.csv",
           cwd=tmp_path)
    assert len(strict((tmp_path / "p.json").read_text())["rows"]) == 20
    calibc("plot", "result.json", "-o", "r.png", "--kind", "all", cwd=tmp_path)
    calibc("plot", "v.json", "-o", "v.svg", cwd=tmp_path)
    for fmt in ("dh-table", "urdf", "cell", "json", "cal"):
        calibc("export", "result.json", "--format", fmt, "-o", f"x.{fmt}", cwd=tmp_path)
        assert (tmp_path / f"x.{fmt}").stat().st_size > 0
    strict((tmp_path / "x.json").read_text())
    res = calibc("export", "result.json", "--format", "ur-kinematics", cwd=tmp_path, codes=(2,))
    assert res.output.count("error:") == 1 and "six revolute joints" in res.output
    calibc("export", "result.json", "--format", "dh-table", "--convention", "dh",
           "--point", "centre", cwd=tmp_path)
    calibc("plan", model, "--candidates", "held.csv", "--n", 8, "-o", "plan.csv", "--json",
           "plan.json", cwd=tmp_path)
    strict((tmp_path / "plan.json").read_text())
    calibc("report", "result.json", "-o", "report.html", "--validation", "v.json",
           "--identify", "identify.json", "--min-error", "min.json", cwd=tmp_path)
    assert (tmp_path / "report.html").read_text().count("<html") == 1


def test_a_six_dof_tracker_is_proven_consistent(tmp_path):
    """Its arm's rotation has an entry the model computes as a constant (a twist of pi/2):
    that entry's row is implied by the measured angles like the other eight."""
    model = campaign(tmp_path, "arm3_6dof.cal", "--configs", 40, "--seed", 2)
    _, result = solve_json(tmp_path, model, "--no-identify", codes=(0, 4))
    truths_inside(result)
    assert result["verdict"] == "consistent"


def test_min_error_of_a_six_dof_trackers_positions_closes(tmp_path):
    model = campaign(tmp_path, "arm3_6dof.cal", "--configs", 10, "--seed", 2)
    calibc("solve", model.name, "-q", "--min-error", "e", "--json", "min.json", cwd=tmp_path)
    lo, hi = strict((tmp_path / "min.json").read_text())["min_error"]["bracket"]
    assert lo is not None and hi / lo <= 1.02 and hi <= 0.05  # simulated within e = 0.05


def test_a_six_dof_tracker_keeps_its_truth(tmp_path):
    model = campaign(tmp_path, "arm3_6dof.cal", "--configs", 40, "--seed", 2)
    _, result = solve_json(tmp_path, model, "--no-identify", codes=(0, 4))
    truths_inside(result)


# -- the slow part: the shipped robots at other sizes, poses and errors ---------------------
# (model, simulate's options, the exit code expected): a hundred rows or so each; the same
# robots on campaigns of 300-3000 rows run in bench/checks/test_held_out_campaigns.py
SHIPPED = [
    ("rx90_lengths.cal", ("--configs", 50, "--seed", 1), 0),
    ("rx90_full.cal", ("--configs", 60, "--seed", 3), 0),
    ("ur5_simulated.cal", ("--configs", 100, "--seed", 1), 0),
    ("ur10_simulated.cal", ("--configs", 100, "--seed", 4, "--poses", "grid"), 0),
    ("ur10_simulated.cal", ("--configs", 100, "--seed", 6, "--systematic", 1), 1),
]


def held_out_campaign(tmp_path: Path, model: str, options: tuple, code: int) -> None:
    """`calibc simulate` a campaign of a shipped robot, then solve it: the verdict the exit
    code expects, and for a consistent one every true value inside."""
    calibc("simulate", MODELS / model, "-o", "c.csv", "-q", *options, cwd=tmp_path)
    _, result = solve_json(tmp_path, MODELS / model, "--data", "m=c.csv", "--no-identify",
                           codes=(code,))
    assert result["verdict"] == ("consistent" if code == 0 else "inconsistent")
    if code == 0:
        truths_inside(result)


def test_plan_for_a_six_dof_tracker_says_why_it_cannot(tmp_path):
    """Its orientation rows' bounds vanish at the planning point (the candidates' angles
    are not measured yet): a user error naming them, not a singular matrix (exit 3)."""
    model = campaign(tmp_path, "arm3_6dof.cal", "--configs", 10, "--seed", 2)
    calibc("simulate", model.name, "--configs", 30, "--seed", 3, "-o", "cand.csv", "-q",
           cwd=tmp_path)  # a small file: the default draws thousands
    res = calibc("plan", model.name, "--candidates", "cand.csv", "--n", 5, "-o", "plan.csv",
                 cwd=tmp_path, codes=(2,))
    assert res.output.startswith("error: ") and "no error bound" in res.output, res.output


def test_min_error_of_a_six_dof_trackers_angles_closes(tmp_path):
    """Least squares leaves a position row beyond its own bound (the angles' rows weigh
    more), which no raise of e_rot mends: the fit starts again from the point with the least
    largest residual in bounds over every row."""
    model = campaign(tmp_path, "arm3_6dof.cal", "--configs", 10, "--seed", 2)
    calibc("solve", model.name, "-q", "--min-error", "e_rot", "--json", "min.json",
           cwd=tmp_path)
    lo, hi = strict((tmp_path / "min.json").read_text())["min_error"]["bracket"]
    assert lo is not None and hi / lo <= 1.02


@pytest.mark.parametrize("poses", ["grid", "repeated"])
def test_plan_chooses_among_grid_or_repeated_candidates(tmp_path, poses):
    """Candidates that share joint values (a grid, with readings of 0) or whole poses
    (repeated ones), read exactly: each candidate still has rows of its own to choose."""
    model = campaign(tmp_path, "arm4_dh.cal", "--configs", 10, "--seed", 2).name
    calibc("simulate", model, "--configs", 30, "--poses", poses, "--seed", 3, "-o", "cand.csv",
           "-q", cwd=tmp_path)
    calibc("plan", model, "--candidates", "cand.csv", "--n", 5, "-o", "plan.csv", cwd=tmp_path)
    cand = (tmp_path / "cand.csv").read_text().splitlines()
    plan = (tmp_path / "plan.csv").read_text().splitlines()
    assert plan[0] == cand[0] and len(plan) == 6
    assert set(plan[1:]) <= set(cand[1:])
