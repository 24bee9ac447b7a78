"""The 6-DOF tracker model's verdict on the public UR10 rows (every 250th, every 15th: 6 and
100 rows): too heavy for `make test`, where tests/strategy/test_verdict.py keeps the verdict
said on simulated and hand-written models, an undecided one with its effort
(test_an_undecided_solve_says_so). Skipped where the data set is absent."""

from __future__ import annotations

import pytest

from tests.strategy.test_verdict import ROOT, assert_said, verdict_of

UR10_DATA = [p / "shared" / "data" / "ur10" / "measurements_joint_configurations.csv"
             for p in (ROOT.parent, ROOT.parent.parent)]


@pytest.mark.skipif(not any(p.exists() for p in UR10_DATA),
                    reason="the public UR10 data set is not at ../shared/data/ur10 "
                           "(docs/real-data.md says where to get it)")
def test_the_ur10_tracker6d_verdict_is_not_silent(tmp_path, rows="1..1495:250"):
    """On every 250th public row (6 rows; every 15th below): the verdict is
    said, and an undecided one names the proof effort it spent."""
    data = next(p for p in UR10_DATA if p.exists())
    code, out, text, err = verdict_of(ROOT / "models" / "ur10_tracker6d.cal", "--data",
                                      f"m={data}", "--rows", rows,
                                      out=tmp_path / "r.json")
    assert_said(code, out, text, err)
    if out["verdict"] != "consistent":
        assert out["decision"]["budget"] is not None and out["decision"]["tried"]


@pytest.mark.skipif(not any(p.exists() for p in UR10_DATA),
                    reason="the public UR10 data set is not at ../shared/data/ur10 "
                           "(docs/real-data.md says where to get it)")
def test_the_ur10_tracker6d_verdict_on_every_15th_row_is_not_silent(tmp_path):
    test_the_ur10_tracker6d_verdict_is_not_silent(tmp_path, rows="1..1495:15")
