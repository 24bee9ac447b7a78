"""Each shipped robot on a held-out campaign through the command, and every command a UR user
adds on a UR5 campaign of 120 rows: too heavy for `make test`, where
tests/test_held_out_battery.py keeps every command on a new robot and a systematic error far
beyond its bound proven inconsistent."""

from __future__ import annotations

import pytest

from tests.test_held_out_battery import (
    MODELS,
    SHIPPED,
    calibc,
    held_out_campaign,
    solve_json,
    strict,
    truths_inside,
)


@pytest.mark.parametrize("model, options, code", SHIPPED,
                         ids=[f"{m}-{'-'.join(map(str, o))}" for m, o, _ in SHIPPED])
def test_a_shipped_robot_on_a_held_out_campaign(tmp_path, model, options, code):
    held_out_campaign(tmp_path, model, options, code)


def test_every_command_on_a_ur5_campaign(tmp_path):
    """The commands a UR user adds: the export for the controller, validation on held-out
    rows, identification and the handover report."""
    model = MODELS / "ur5_simulated.cal"
    calibc("simulate", model, "-o", "c.csv", "-q", "--configs", 120, "--seed", 21, cwd=tmp_path)
    calibc("simulate", model, "-o", "h.csv", "-q", "--configs", 40, "--seed", 22, cwd=tmp_path)
    _, result = solve_json(tmp_path, model, "--data", "m=c.csv")
    truths_inside(result)
    for fmt in ("ur-kinematics", "dh-table", "urdf", "cell", "json", "cal"):
        calibc("export", "result.json", "--format", fmt, "-o", f"x.{fmt}", cwd=tmp_path)
    calibc("validate", model, "--data", "m=c.csv", "--at", "h.csv", "-q", "--json", "v.json",
           cwd=tmp_path)
    assert strict((tmp_path / "v.json").read_text())["coverage"] == 1.0
    calibc("report", "result.json", "-o", "r.html", "--validation", "v.json", cwd=tmp_path)
