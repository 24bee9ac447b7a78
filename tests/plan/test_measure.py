"""`calibc simulate --at`: measurements at given configurations, in the table's dialect."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.plan.configs import read_configurations, table_of
from calib_dsl.plan.measure import simulate_at
from calib_dsl.studies.campaign import Campaign
from tests.cli_run import run

ROOT = Path(__file__).resolve().parents[2]
UR10 = ROOT / "models" / "ur10_simulated.cal"
Q = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
     "wrist_2_joint", "wrist_3_joint"]
X = ["measurement_x", "measurement_y", "measurement_z"]


def read(path: Path) -> dict[str, np.ndarray]:
    """A file in the UR10 cell's dialect (';', decimal commas) as columns."""
    lines = path.read_text(encoding="utf-8").splitlines()
    header = lines[0].split(";")
    rows = [[float(c.replace(",", ".")) for c in ln.split(";")] for ln in lines[1:]]
    return {h: np.array([r[j] for r in rows]) for j, h in enumerate(header)}


def configs_file(tmp_path: Path, rows: int = 6, seed: int = 1) -> Path:
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, size=(rows, 6))
    path = tmp_path / "configs.csv"
    path.write_text(";".join(Q) + "\n" + "\n".join(
        ";".join(repr(float(x)).replace(".", ",") for x in row) for row in q) + "\n",
        encoding="utf-8")
    return path


def test_measures_at_the_given_poses_in_the_tables_dialect(tmp_path):
    at = configs_file(tmp_path)
    out = tmp_path / "m.csv"
    result = run("simulate", UR10, "--at", f"m={at}", "-o", out, "--seed", 3, "-D", "e=0.5")
    assert result.exit_code == 0, result.output
    given, got = read(at), read(out)
    assert list(got) == Q + X  # the table's header names, its separator and decimal comma
    for name in Q:  # the poses given, with the encoders' noise (q_err) only
        assert np.all(np.abs(got[name] - given[name]) <= 1e-5 * (1 + 1e-9))


def test_two_campaigns_at_the_same_poses_agree_within_their_bounds(tmp_path):
    """The same truth measured twice at the same poses: the positions differ by at most the
    two noises (2 e) plus what the encoders' noise moves the point (|q| <= 1e-5 rad at
    about 1.5 m reach); at different poses they would differ by metres."""
    at = configs_file(tmp_path, rows=8)
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    for seed, out in ((1, a), (2, b)):
        assert simulate_at(UR10, at, seed, out, consts={"e": "0.5"}) == (8, [])
    ra, rb = read(a), read(b)
    gap = max(float(np.max(np.abs(ra[c] - rb[c]))) for c in X)
    assert 0 < gap <= 2 * 0.5 + 6 * 2e-5 * 1500
    assert not np.allclose(ra[X[0]], rb[X[0]])  # fresh noise per seed


def test_without_noise_the_inputs_keep_only_the_encoders_noise_and_outputs_repeat(tmp_path):
    at = configs_file(tmp_path, rows=4)
    outs = []
    for seed in (5, 6):
        out = tmp_path / f"n{seed}.csv"
        simulate_at(UR10, at, seed, out, campaign=Campaign(noise=False), consts={"e": "0.5"})
        outs.append(read(out))
    gap = max(float(np.max(np.abs(outs[0][c] - outs[1][c]))) for c in X)
    assert gap < 0.5  # only the inputs' noise (1e-5 rad) moved them


def test_reads_the_inputs_converted_to_the_models_units(tmp_path):
    at = configs_file(tmp_path, rows=3)
    t = table_of(elaborate(str(UR10), simulate_rows=1))
    configs = read_configurations(t, at)
    assert configs.columns == ("q1", "q2", "q3", "q4", "q5", "q6")
    assert np.allclose(configs.q[:, 0], read(at)[Q[0]])
    sub = configs.subset([2, 0])
    assert sub.line == (configs.line[2], configs.line[0])


def test_user_errors_are_one_line_and_exit_2(tmp_path):
    at = configs_file(tmp_path, rows=2)
    bad = tmp_path / "bad.csv"
    bad.write_text("shoulder_pan_joint;elbow_joint\n1;2\n", encoding="utf-8")
    cases = [("--at", at, "--configs", 3), (), ("--at", bad), ("--at", f"zz={at}"),
             ("--at", tmp_path / "none.csv")]
    for extra in cases:
        result = run("simulate", UR10, "-o", tmp_path / "o.csv", *extra)
        assert result.exit_code == 2, (extra, result.output)
        lines = result.output.strip().splitlines()
        assert "error:" in lines[0] and "Traceback" not in result.output


def test_configurations_beyond_the_joint_limits_are_named(tmp_path):
    """(a joint column in degrees, read as radians, was simulated at poses the robot cannot
    take, without a word)"""
    at = configs_file(tmp_path, rows=4)
    lines = at.read_text(encoding="utf-8").splitlines()
    cells = lines[2].split(";")
    cells[2] = "100,5"  # rad: beyond the UR10's +- 2 pi
    lines[2] = ";".join(cells)
    at.write_text("\n".join(lines) + "\n", encoding="utf-8")
    res = run("simulate", UR10, "--at", at, "-o", tmp_path / "m.csv", "-q")
    assert res.exit_code == 0, res.output
    warned = [ln for ln in res.output.splitlines() if ln.startswith("calibc: warning: ")]
    assert len(warned) == 1 and "1 reading of m.q3 lies outside the joint's limits" \
        in warned[0] and f"{at}:3 100.5" in warned[0], res.output
    res = run("simulate", UR10, "--at", configs_file(tmp_path), "-o", tmp_path / "m.csv", "-q")
    assert "warning" not in res.output, res.output
