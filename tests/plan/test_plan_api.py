"""calib_dsl.plan from Python: the same plans and sweeps as the command line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from calib_dsl import plan
from calib_dsl.frontend.diagnostics import CalError

ROOT = Path(__file__).resolve().parents[2]
ARM = ROOT / "models" / "examples" / "planar_arm.cal"


def test_plan_sweep_and_simulate_at(tmp_path):
    cand = tmp_path / "c.csv"
    from calib_dsl.studies.simulate import simulate

    simulate(ARM, 80, 4, out_csv=cand)
    p = plan.plan(plan.PlanRequest(ARM, cand, defines={"e": 0.01}, seed=3), 4)
    assert len(p.rows) == 4 and p.names == ["l1", "l2"]
    assert np.all(p.predicted < p.domain)
    out = tmp_path / "plan.csv"
    from calib_dsl.plan.command import write_plan

    write_plan(plan.problem_of(ARM, {"e": 0.01}, 3, "matrix", None), p.configs, out)
    assert plan.simulate_at(ARM, out, tmp_path / "m.csv", defines={"e": 0.01}) == 4
    s = plan.sweep(plan.PlanRequest(ARM, cand, defines={"e": 0.01}), [2, 8], {"l2": 1.0})
    assert s.enough == 2 and s.widths.shape == (2, 2)
    drawn = plan.plan(plan.PlanRequest(ARM, None, defines={"e": 0.01}), 3)
    assert drawn.configs.q.shape == (3, 2)


def test_mistakes_raise_calerror(tmp_path):
    with pytest.raises(CalError, match="no unknown 'nope'"):
        plan.sweep(plan.PlanRequest(ARM, defines={"e": 0.01}), [2, 3], {"nope": 1.0})
    with pytest.raises(CalError, match="not found"):
        plan.plan(plan.PlanRequest(ARM, tmp_path / "none.csv"), 3)
