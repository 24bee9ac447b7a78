"""The tight strategy's history: the widths of the declared unknowns after each step and round,
recorded without changing the solve's result."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib_dsl.pipeline import load, solve
from calib_dsl.report.as_json import result_json
from calib_dsl.settings import DEFAULT
from calib_dsl.strategy.history import History
from calib_dsl.strategy.tight import Watch, tight_steps

ARM = Path(__file__).resolve().parents[2] / "models" / "examples" / "planar_arm.cal"


def test_history_from_domains_to_result():
    prog = load(ARM)
    sol = solve(prog)
    assert sol.history is not None
    steps = sol.history.steps
    declared = np.array(prog.slots.declared)
    assert steps[0].label == "start"
    np.testing.assert_array_equal(steps[0].widths, prog.slots.hi[declared]
                                  - prog.slots.lo[declared])
    np.testing.assert_array_equal(steps[-1].widths, sol.hi[declared] - sol.lo[declared])
    labels = [s.label for s in steps]
    assert "propagation" in labels and "rounds of LPs" in labels
    assert any(label.startswith("LP round 1 (") for label in labels)
    seconds = [s.seconds for s in steps]
    assert seconds == sorted(seconds) and seconds[-1] <= sol.seconds
    # contractors only narrow: every width is non-increasing along the history
    widths = np.array([s.widths for s in steps])
    assert np.all(np.diff(widths, axis=0) <= 0)
    assert widths[-1].max() < 1e-3 < widths[0].min()


def test_recording_changes_no_bound():
    """The same steps with and without a history give the same box, bit for bit."""
    prog = load(ARM)
    boxes = []
    for history in (None, History(np.array(prog.slots.declared))):
        steps = tight_steps(prog, 1e-5, 1000, DEFAULT, watch=Watch(history=history))
        out = steps.contract(prog.slots.lo.copy(), prog.slots.hi.copy())
        boxes.append((out.lo, out.hi))
    np.testing.assert_array_equal(boxes[0][0], boxes[1][0])
    np.testing.assert_array_equal(boxes[0][1], boxes[1][1])


def test_history_in_the_json_only_for_tight():
    prog = load(ARM)
    data = result_json(prog, solve(prog), "tight")["history"]
    assert data["parameters"] == ["l1", "l2"]
    assert data["steps"][0]["step"] == "start"
    assert all(len(s["widths"]) == 2 and s["seconds"] >= 0 for s in data["steps"])
    assert "history" not in result_json(prog, solve(prog, "hc4"), "hc4")
