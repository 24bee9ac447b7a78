"""An orientation reading as three measured angles, like a position's three coordinates.

`R == euler_xyz(m.rx[k], m.ry[k], m.rz[k])`, with R a rotation by construction (a robot's
`axes`, an `euler_xyz`, or `compose` of two such), compares two computed 9-vectors: no
point can be proven to satisfy it (an interval equals an interval only as a point), so a
solve could never certify one. Written with R's X-Y-Z Euler angles instead,

    atan2(-R12, R22) == m.rx[k],  atan2(R02, sqrt(R00^2 + R01^2)) == m.ry[k],
    atan2(-R01, R00) == m.rz[k],

each constraint has a measured side (a reading's interval) as a position's has, and the point
check chooses the readings. The two forms hold for the same values when, on every row,
ry's interval lies inside (-pi/2, pi/2) and rx's and rz's inside (-pi, pi): a rotation R
with cos(ry) > 0 is Rx(a) Ry(b) Rz(c) for exactly one (a, b, c) with b in (-pi/2, pi/2)
and a, c in (-pi, pi] (up to 2 pi, which those intervals exclude), and these are the
formulas' values (R02 = sin b, R12 = -sin a cos b, R22 = cos a cos b, R00 = cos b cos c,
R01 = -cos b sin c). R must be a rotation: the angles of any other matrix would accept
values the matrix form rejects. Anything else is compiled as written (nine rows).
"""

from __future__ import annotations

import math
import re

from calib_dsl.elaborate.context import Context
from calib_dsl.elaborate.scope import Value
from calib_dsl.ir.status import SlotKind

# The intervals must lie strictly inside the angles' ranges; the float bounds of a reading
# are rounded outward, so a margin far above rounding and far below any reading's bound
_MARGIN = 1e-9
_DATA = re.compile(r"(\w+)\.(\w+)\[(\d+)\]")  # a simulated cell's name
_LIMITS = (math.pi - _MARGIN, math.pi / 2 - _MARGIN, math.pi - _MARGIN)


class Orientation(Context):
    """Rotations by construction, and orientation readings as three angles."""

    def note_rotation(self, value: tuple[int, ...], angles: tuple[int, ...] | None = None
                      ) -> tuple[int, ...]:
        """Remember `value` as a rotation (its X-Y-Z Euler angles, if made from them)."""
        self.rotations.add(value)
        if angles is not None:
            self.euler_angles.setdefault(value, angles)
        return value

    def is_rotation(self, value: Value) -> bool:
        return isinstance(value, tuple) and value in self.rotations

    def orientation_pairs(self, lhs: Value, rhs: Value) -> list[tuple[int, int]] | None:
        """(computed angle, reading) pairs for `lhs == rhs` when it is an orientation reading
        (either side measured), else None."""
        for rot, meas in ((lhs, rhs), (rhs, lhs)):
            if not (self.is_rotation(rot) and isinstance(meas, tuple)):
                continue
            cells = self.euler_angles.get(meas)  # type: ignore[arg-type]
            if cells is not None and self._readings(cells):
                return self._angles(rot, cells)  # type: ignore[arg-type]
        return None

    def _readings(self, nodes: tuple[int, ...]) -> bool:
        """Whether the angles are three readings (cells with an error bound) of one row of
        one table whose intervals, on every row, lie inside the formulas' ranges."""
        cells = [self._cell_of(n) for n in nodes]
        found = [c for c in cells if c is not None]
        if len(found) != 3 or len({(t, r) for t, _, r in found}) != 1 \
                or len({c for _, c, _ in found}) != 3:
            return False
        table = next((t for t in self.tables if t.name == found[0][0]), None)
        if table is None:
            return False
        tol = {c.name: c.tol for c in table.columns if not c.derived}
        for (_, col, _), limit in zip(found, _LIMITS, strict=True):
            if tol.get(col, 0.0) <= 0:
                return False
            if self.simulate_rows is not None:  # the formulas will give the values
                continue
            lo, hi = table.bounds[col]
            if not (bool((lo > -limit).all()) and bool((hi < limit).all())):
                return False
        return True

    def _cell_of(self, node: int) -> tuple[str, str, int] | None:
        """(table, column, row) of a cell's node: a measured value, or in simulation mode the
        data variable `table.column[row]` the simulation will give a value."""
        tags = self.dag.cells.get(node, set())
        if len(tags) == 1:
            return next(iter(tags))
        n = self.dag.nodes[node]
        if self.simulate_rows is None or n.op != "var":
            return None
        var = self.dag.variables.get(str(n.data))
        found = _DATA.fullmatch(str(n.data))
        if var is None or var.kind != SlotKind.DATA or found is None:
            return None
        return found[1], found[2], int(found[3])

    def _angles(self, r: tuple[int, ...], cells: tuple[int, ...]) -> list[tuple[int, int]]:
        """R's X-Y-Z Euler angles (cos of the middle one >= 0), each with its reading."""
        op = self.dag.op
        cos_b = op("sqrt", op("add", op("sqr", r[0]), op("sqr", r[1])))
        return [(op("atan2", op("neg", r[5]), r[8]), cells[0]),
                (op("atan2", r[2], cos_b), cells[1]),
                (op("atan2", op("neg", r[1]), r[0]), cells[2])]
