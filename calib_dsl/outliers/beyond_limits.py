"""Joint readings outside the robot's joint limits: a reading the joint cannot take is a
fault of the file (a unit, a typo, a corrupted cell), yet it does not always show as an
inconsistency (a huge angle's sine is all of [-1, 1], so the row constrains nothing and the
solve proves nothing either way). The rows are named so the user can look."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from calib_dsl.ir.model import Model, Table


def beyond_limits(model: Model | None) -> list[str]:
    """A warning per table column whose readings leave the limits of the joint they feed."""
    if model is None:
        return []
    return [w for t in model.tables for w in table_beyond_limits(model, t)]


def table_beyond_limits(model: Model, t: Table) -> list[str]:
    """The same for one table read with `model`'s joints (a file of configurations to
    predict at, read as the model's table)."""
    out: list[str] = []
    for c in t.columns:
        limits = model.joint_limits.get((t.name, c.name))
        if limits is None or c.name not in t.readings:
            continue
        lo, hi = t.readings[c.name]
        bad = np.flatnonzero((hi < limits[0]) | (lo > limits[1]))
        if len(bad):
            out.append(_line(t, c.name, limits, bad, 0.5 * (lo + hi)))
    return out


def _line(t: Table, column: str, limits: tuple[float, float], bad: np.ndarray,
          value: np.ndarray) -> str:
    return outside_limits(f"{t.name}.{column}", limits, bad, value,
                          lambda k: f"{t.path}:{t.lines[k]} (data row {t.numbers[k]})"
                          if k < len(t.lines) else f"row {k + 1}")


def outside_limits(what: str, limits: tuple[float, float], bad: np.ndarray,
                   value: np.ndarray, place: Callable[[int], str]) -> str:
    """The one warning for readings of the column `what` beyond its joint's limits: the
    rows `bad` (0-based), each named by `place` with its value; five named, the count says
    the rest."""
    where = "; ".join(f"{place(int(k))} {value[k]:.6g}" for k in bad[:5])
    more = f", ... ({len(bad) - 5} more)" if len(bad) > 5 else ""
    many = len(bad) > 1
    return (f"{len(bad)} reading{'s' if many else ''} of {what} "
            f"lie{'' if many else 's'} "
            f"outside the joint's limits [{limits[0]:.6g}, {limits[1]:.6g}] (the robot "
            f"cannot be there: check the file and the column's unit): {where}{more}")
