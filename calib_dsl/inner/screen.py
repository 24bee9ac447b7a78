"""The inner bounds' point checks on the rows that can fail at their points only.

Every candidate point of the inner bounds lies in one box (the result, within the domains). The
rows' second-order models over that box (analysis/row_screen.py, the predictions' screen: made
once per program and box, dropped when the inner bounds end) prove most rows inside their
targets at a point with a few float products, their roundings bounded; a point check then
evaluates only the loop rows (configurations) with a row some point of the pass leaves open,
and the shared part's.
The rows left out are filled back in, in the order a check of every row gives: held (`ok`),
no excess, their computed side the box's enclosure (which holds the point's). The callers
compare two checks row by row on the rows that failed only (inner/bounds._pull_back, whose
centre's check is of every row; LinearModel.excess): those were evaluated at the point, as
by a check of every row.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.analysis.certify_point import PointCheck, check_points
from calib_dsl.analysis.row_screen import row_screen, screened_checks
from calib_dsl.ir.program import Program


def checks(prog: Program, box: tuple[np.ndarray, np.ndarray], points: np.ndarray,
           readings: np.ndarray) -> list[PointCheck]:
    """check_points(prog, points, readings), of the rows some point's models leave open
    only where every point lies in `box` (the others filled in: held)."""
    scr = row_screen(prog, *box)
    if scr is None:
        return check_points(prog, points, readings)
    return screened_checks(scr, points, readings)
