"""`--min-error` on the public UR10 file (every 50th row): too heavy for `make test`, where
tests/analysis/test_min_error.py brackets the shipped models' bounds (the same search) and
exact linear fits. Skipped where the data set is absent."""

from __future__ import annotations

from pathlib import Path

from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.pipeline import min_error
from tests.test_ur10 import UR10, needs_ur10


@needs_ur10
def test_the_public_data_every_50th_row():
    from calib_dsl.elaborate.rows import Selection, parse_ranges

    root = Path(__file__).resolve().parents[2]
    inputs = Inputs(data={"m": UR10}, rows={"m": Selection(parse_ranges("1..1495:50"), ())})
    found = min_error(root / "models" / "ur10_tracker.cal", "e", inputs=inputs)
    assert found.lo is not None and found.lo < found.hi < 1.0
    assert found.binding and all(b.line == b.row + 1 for b in found.binding)
