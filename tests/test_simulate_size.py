"""`calibc simulate` refuses, as one user error, a campaign whose elaborated model would not
fit in memory (rows x the nodes a row adds), before elaborating it; the campaigns the
benchmarks draw (12,000 UR10 rows) stay within it."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_run import run

from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.studies.simulate import MAX_NODES, _check_size

ROOT = Path(__file__).resolve().parents[1]
ARM = ROOT / "models" / "examples" / "planar_arm.cal"
UR10 = ROOT / "models" / "ur10_simulated.cal"


def test_a_campaign_past_the_memory_guard_is_one_user_error(tmp_path):
    res = run("simulate", ARM, "--configs", 1_000_000, "-o", tmp_path / "s.csv", "-q")
    assert res.exit_code == 2
    assert res.output.startswith("error: simulate: 1,000,000 configurations of ")
    assert "simulate several files with their own --seed" in res.output
    assert not (tmp_path / "s.csv").exists()


def test_the_guard_counts_the_nodes_a_row_adds():
    _check_size(UR10, 12_000, "matrix", Inputs())  # bench/campaigns.py's largest
    with pytest.raises(CalError, match="at most") as err:
        _check_size(UR10, MAX_NODES, "matrix", Inputs())
    most = int(str(err.value).split("at most ")[1].split(" ")[0].replace(",", ""))
    _check_size(UR10, most, "matrix", Inputs())
    with pytest.raises(CalError):
        _check_size(UR10, most + 1, "matrix", Inputs())
