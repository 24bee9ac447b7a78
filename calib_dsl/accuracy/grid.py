"""A workspace accuracy map: the poses of a grid of joint values (`q1=a:b:step,...`) as a
file in the format of the model's table, and the guaranteed error bound at each predicted
pose.

The bound at a pose is the distance from the middle of its predicted box to the prediction
of any parameter vector consistent with the data: the root of the sum of the squared half
widths of the box over the columns of the distance (those not in an angle unit), rounded
upward. The measured position itself may differ from the model's by the error bound e the
data were consistent with; `with_e` adds e to each half width.
"""

from __future__ import annotations

import itertools
from fractions import Fraction
from pathlib import Path

import numpy as np

from calib_dsl.accuracy.predict import Prediction
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.model import Table

MAX_POSES = 1_000_000  # a grid larger than this is a mistake in its steps, not a request
MAX_VALUE = 1e300  # a joint value beyond this is a typo (and would overflow a float)
# A prediction holds, per pose, the compiled row's values and their derivatives: its memory
# grows as poses x the program's unknowns per row (at most about 0.5 kB each). A grid past
# this many would take about 2 GB, where larger steps map the same workspace: a guard on
# the request, not on a result
MAX_CELLS = 4_000_000


def parse_grid(spec: str) -> dict[str, list[float]]:
    """`NAME=a:b:step,...` (or `NAME=v` for one value) -> each name's values, a to b
    inclusive (exact decimal steps: 0:1:0.1 has 11 values)."""
    out: dict[str, list[float]] = {}
    for part in (p.strip() for p in spec.split(",") if p.strip()):
        name, sep, rng = part.partition("=")
        if not sep or not name.strip():
            raise CalError(f"--grid: '{part}' is not NAME=a:b:step")
        if name.strip() in out:
            raise CalError(f"--grid: {name.strip()} is given twice")
        try:
            ends = [Fraction(v.strip()) for v in rng.split(":")]
        except ValueError:
            raise CalError(f"--grid: '{part}': a, b and step must be numbers") from None
        if any(abs(v) > MAX_VALUE for v in ends):  # (a float would be inf, a pose nonsense)
            raise CalError(f"--grid: '{part}': a value beyond {MAX_VALUE:g}")
        if len(ends) == 1:
            out[name.strip()] = [float(ends[0])]
            continue
        if len(ends) != 3 or ends[2] <= 0 or ends[1] < ends[0]:
            raise CalError(f"--grid: '{part}' is not NAME=a:b:step with a <= b, step > 0")
        a, b, step = ends
        n = int((b - a) / step) + 1
        if n > MAX_POSES:
            raise CalError(f"--grid: '{part}' has {n} values (at most {MAX_POSES})")
        out[name.strip()] = [float(a + k * step) for k in range(n)]
    if not out:
        raise CalError("--grid: no joint given (NAME=a:b:step,...)")
    total = int(np.prod([len(v) for v in out.values()]))
    if total > MAX_POSES:
        raise CalError(f"--grid: {total} poses (at most {MAX_POSES}): take larger steps")
    return out


def check_size(values: dict[str, list[float]], per_pose: int) -> None:
    """A user error where the grid's poses times `per_pose` (the calibration program's
    unknowns per row) exceed MAX_CELLS, saying how many poses the model allows."""
    poses = int(np.prod([len(v) for v in values.values()]))
    if poses * max(per_pose, 1) > MAX_CELLS:
        most = MAX_CELLS // max(per_pose, 1)
        raise CalError(f"--grid: {poses} poses of {per_pose} unknowns each would not fit in "
                       f"memory (at most {most} poses for this model): take larger steps")


def grid_file(values: dict[str, list[float]], t: Table, path: Path) -> Path:
    """The grid's poses (every combination, the last name fastest; values in the file's
    units) as a file the table reads: the columns named, the others (the measurements)
    left out; every input of the table (a column `simulate` draws) must be named, with one
    value if it does not vary."""
    names = {c.name for c in t.columns if not c.derived}
    lacking = [c.name for c in t.columns if c.sim is not None and c.name not in values]
    if lacking:
        raise CalError(f"--grid: give {', '.join(lacking)} too (NAME=v for a fixed value)")
    unknown = sorted(set(values) - names)
    if unknown:
        raise CalError(f"--grid: the table '{t.name}' has no column {', '.join(unknown)} "
                       f"(its columns: {', '.join(c.name for c in t.columns)})")
    given = [c for c in t.columns if c.name in values and not c.derived]
    header = t.separator.join(c.header or c.name for c in given)

    def cell(v: float) -> str:
        text = repr(float(v))
        return text.replace(".", ",") if t.decimal == "," else text

    body = [t.separator.join(cell(v) for v in combo)
            for combo in itertools.product(*(values[c.name] for c in given))]
    path.write_text("\n".join([header, *body]) + "\n", encoding="utf-8")
    return path


def pose_bounds(p: Prediction, angles: frozenset[str] = frozenset()
                ) -> tuple[np.ndarray, np.ndarray]:
    """Per pose, the bound (module docstring) and the bound with each column's error bound
    e added to its half width; columns in `angles` (an angle unit) left out unless every
    column is one."""
    among = np.array([c not in angles for c in p.columns], dtype=bool)
    if not among.any():
        among[:] = True
    half = np.nextafter(0.5 * (p.hi - p.lo), np.inf)[:, among]
    grow = 1.0 + (2 * among.sum() + 4) * 2.0 ** -52
    with np.errstate(over="ignore", invalid="ignore"):
        bound = np.nextafter(np.sqrt(np.sum(half ** 2, axis=1)) * grow, np.inf)
        e = np.nextafter(half + p.bound[among], np.inf)
        with_e = np.nextafter(np.sqrt(np.sum(e ** 2, axis=1)) * grow, np.inf)
    return bound, with_e
