"""Warm starts for another LP over the same constraints: the simplex's final bases of a
solve's last LPs, keyed by what their rows and columns mean (the slot a row compares with, an
unknown's slot, a measured cell) rather than by their places in the LP that made them.

The inner bounds (inner/bounds.py) solve, for each end of each unknown, an LP over the
model linearized at a point, the joint readings' errors among its columns: the same rows and
columns as the solve's last first-order LPs with the errors as columns, over another box. From
the solve's final basis for the same end, HiGHS starts near the optimum and needs far fewer
pivots (docs/decisions/14). A start only saves pivots: from any basis the simplex reaches the
same optimal value (another optimal vertex where it is not unique, so other candidates).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.lp.certify import Certificates, mapped
from calib_dsl.lp.highs import BASIC, LOWER


@dataclass(frozen=True)
class EndBasis:
    """One objective's final basis: each row's status by the slot it compares with, each
    column's by the unknown's slot or the cell (configuration, table column) it is."""

    row_slots: np.ndarray  # sorted
    row_status: np.ndarray
    unknowns: np.ndarray  # sorted slots
    unknown_status: np.ndarray
    cells: np.ndarray  # sorted keys configuration * CELL_KEY + column
    cell_status: np.ndarray


CELL_KEY = 1 << 20  # more table columns than any table has


@dataclass(frozen=True)
class Starts:
    """The final bases of a solve's last first-order LPs with the errors as LP columns, by
    (unknown's slot, sign): +1 for its largest value, -1 for its smallest."""

    ends: dict[tuple[int, float], EndBasis]

    def statuses(self, slot: int, sign: float, row_slots: np.ndarray, unknowns: np.ndarray,
                 cells: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """The start (row statuses, column statuses) of an LP whose rows compare with
        `row_slots` and whose columns are the unknowns `unknowns` (slots) then the `cells`
        (configuration, table column), for the end (slot, sign); None where the solve kept
        none. A row or column the solve's LP did not have: its slack basic, at its lower
        bound (HiGHS completes such an "alien" basis)."""
        end = self.ends.get((slot, sign))
        if end is None:
            return None
        keys = cells[:, 0] * CELL_KEY + cells[:, 1] if len(cells) else np.zeros(0, np.int64)
        return (mapped(end.row_slots, end.row_status, row_slots, BASIC),
                np.concatenate([mapped(end.unknowns, end.unknown_status, unknowns, LOWER),
                                mapped(end.cells, end.cell_status, keys, LOWER)]))


def from_certificates(certs: Certificates, unknowns: np.ndarray,
                      renamed: dict[int, int] | None = None) -> Starts | None:
    """The starts kept in `certs` (first-order rounds only: the second-order ones' columns
    are other quantities), their LP's unknown columns being the slots `unknowns`, each
    renamed as `renamed` says (a combination's slot -> its pivot's, strategy/reparametrize.py);
    None when there are none."""
    if certs.family != "first order":
        return None
    renamed = renamed or {}
    named = np.array([renamed.get(int(s), int(s)) for s in unknowns], np.int64)
    ends = {}
    for (i, sign), (_, rows, _, cols) in certs.basis.items():
        meaning = certs.meaning.get((i, sign))
        if meaning is None or i >= len(unknowns):
            continue
        targets, cells, main = meaning
        keys = cells[:, 0] * CELL_KEY + cells[:, 1]
        ends[(int(named[i]), sign)] = EndBasis(
            *_sorted(targets, rows), *_sorted(named[:main], cols[:main]),
            *_sorted(keys, cols[main:]))
    return Starts(ends) if ends else None


def _sorted(keys: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(keys, kind="stable")
    return keys[order], values[order]
