"""The shipped planar arm (models/examples/planar_arm.cal) for tests: its forward kinematics
written out by hand, and a campaign simulated from its true lengths in a directory."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import numpy as np
from cli_run import run

EXAMPLES = Path(__file__).resolve().parents[1] / "models" / "examples"


def tip(l1, l2, q1, q2):
    return (l1 * np.cos(q1) + l2 * np.cos(q1 + q2), l1 * np.sin(q1) + l2 * np.sin(q1 + q2))


def simulated_arm(tmp: Path, configs: int, seed: int) -> list[dict[str, float]]:
    """The arm's model copied into tmp with `configs` simulated rows (planar_arm.csv): the
    rows read back."""
    for name in ("planar_arm.cal", "planar_arm_robot.cal"):
        shutil.copy(EXAMPLES / name, tmp)
    res = run("simulate", "planar_arm.cal", "--configs", configs, "--seed", seed, "-o",
              "planar_arm.csv", cwd=tmp)
    assert res.exit_code == 0, res.output
    with open(tmp / "planar_arm.csv") as f:
        return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
