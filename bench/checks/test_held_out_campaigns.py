"""The shipped robots on held-out campaigns of 300-3000 rows (grid and repeated poses,
systematic errors within and beyond the bound): too heavy for `make test`, where
tests/test_held_out_battery.py runs the same command on a hundred rows or so of each."""

from __future__ import annotations

import pytest

from tests.test_held_out_battery import held_out_campaign

CAMPAIGNS = [  # (model, simulate's options, the exit code expected)
    ("rx90_lengths.cal", ("--configs", 300, "--seed", 2, "--poses", "grid"), 0),
    ("ur5_simulated.cal", ("--configs", 500, "--seed", 1), 0),
    ("ur5_simulated.cal", ("--configs", 800, "--seed", 2, "--poses", "repeated",
                           "--repeats", 4), 0),
    ("ur10_simulated.cal", ("--configs", 1000, "--seed", 4, "--poses", "grid"), 0),
    ("ur10_simulated.cal", ("--configs", 600, "--seed", 5, "--no-noise",
                            "--systematic", 0.08), 0),  # within e = 0.1
    ("ur10_simulated.cal", ("--configs", 600, "--seed", 6, "--systematic", 1), 1),
    ("ur10_simulated.cal", ("--configs", 3000, "--seed", 7), 0),
]


@pytest.mark.parametrize("model, options, code", CAMPAIGNS,
                         ids=[f"{m}-{'-'.join(map(str, o))}" for m, o, _ in CAMPAIGNS])
def test_a_shipped_robot_on_a_large_held_out_campaign(tmp_path, model, options, code):
    held_out_campaign(tmp_path, model, options, code)
