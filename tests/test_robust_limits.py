"""A joint reading outside the robot's joint limits is a fault of the file that the solve
cannot always see (a whole number of turns more, or a huge value whose sine is all of
[-1, 1]): the solve names the row in a warning; a clean file gets none."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import pytest
from cli_run import run

EXAMPLES = Path(__file__).resolve().parents[1] / "models" / "examples"


@pytest.fixture
def arm(tmp_path: Path) -> Path:
    shutil.copy(EXAMPLES / "planar_arm.csv", tmp_path / "planar_arm.csv")
    model = (EXAMPLES / "planar_arm.cal").read_text()
    direct = model.replace("tip(m.q1[k], m.q2[k])", "arm2(m.q1[k], m.q2[k]) at (l2, 0, 0)")
    assert direct != model  # (the cells reach the joints directly: they take its limits)
    (tmp_path / "planar_arm.cal").write_text(direct)
    robot = (EXAMPLES / "planar_arm_robot.cal").read_text()
    limited = robot.replace("robot arm2(q1, q2)", "robot arm2(q1 in [-pi, pi], q2 in [-pi, pi])")
    assert limited != robot
    (tmp_path / "planar_arm_robot.cal").write_text(limited)
    return tmp_path


def _turned(arm: Path, row: int, turns: int) -> None:
    """Data row `row`'s q1 moved by whole turns: the same pose, beyond the limits."""
    lines = (arm / "planar_arm.csv").read_text().splitlines()
    cells = lines[row].split(",")
    cells[0] = repr(float(cells[0]) + turns * 2 * math.pi)
    lines[row] = ",".join(cells)
    (arm / "planar_arm.csv").write_text("\n".join(lines) + "\n")


def _warnings(arm: Path) -> tuple[int, list[str], str]:
    res = run("solve", "planar_arm.cal", "--json", "r.json", "-q", cwd=arm)
    return res.exit_code, json.loads((arm / "r.json").read_text())["warnings"], res.output


def test_a_clean_file_gets_no_limit_warning(arm):
    code, warnings, _ = _warnings(arm)
    assert code == 0
    assert not [w for w in warnings if "joint's limits" in w]


@pytest.mark.parametrize("turns", [3, -5])
def test_a_reading_beyond_its_joints_limits_is_named(arm, turns):
    _turned(arm, 3, turns)
    code, warnings, output = _warnings(arm)
    assert code == 0  # the same pose: the data stay consistent, the verdict is right
    found = [w for w in warnings if "joint's limits" in w]
    assert len(found) == 1
    assert "m.q1" in found[0] and "planar_arm.csv:4 (data row 3)" in found[0]
    assert "calibc: warning: 1 reading of m.q1 lies outside" in output
