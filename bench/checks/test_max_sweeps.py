"""`--max-sweeps` on Test A at caps 9 and 1000 (nearer a whole RX90 solve each): too heavy
for `make test`, where tests/test_cli.py keeps caps 1 and 4
(test_max_sweeps_caps_the_tight_strategy, the same body)."""

from __future__ import annotations

import pytest

from tests.test_cli import capped_solve_holds_the_truth


@pytest.mark.parametrize("cap", [9, 1000])
def test_max_sweeps_caps_the_tight_strategy_near_a_whole_solve(cap, tmp_path):
    """--max-sweeps caps the sweeps of the whole tight solve (its propagations and rounds
    together), and a capped solve still holds the truth."""
    capped_solve_holds_the_truth(cap, tmp_path)
