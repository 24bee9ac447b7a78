"""Tables given as values instead of files (the Python API's arrays and lists).

A `Values` stands where a table's CSV file would: the same columns, in the file's units (a
column declared `in deg` is converted as a file's would be), the same row selection. Its
numbers are floats, each its own exact value: a cell's enclosure is the float itself (a file's
decimal is enclosed by the floats around it), so nothing is lost on the way. It becomes the
same `CsvData` a file gives, and everything after (units, tolerances, DAG cells) is shared.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from calib_dsl.elaborate.rows import EVERY_ROW, Selection, select
from calib_dsl.elaborate.tables import CsvData
from calib_dsl.frontend.diagnostics import CalError, Loc


@dataclass(frozen=True, eq=False)
class Values:
    """A table's cells: a mapping from the model's column names to sequences of numbers
    (extra columns ignored, as a file's are), or a 2-D array-like, one row per configuration
    and one column per declared column, in the order the table declares them."""

    cells: Mapping[str, Sequence[float]] | Sequence[Sequence[float]] | np.ndarray
    name: str = "<values>"  # how messages and reports name it, where a file's path would be

    def __str__(self) -> str:
        return self.name


def read_values(values: Values, columns: Sequence[str], table: str,
                selection: Selection = EVERY_ROW, decl_loc: Loc | None = None) -> CsvData:
    """The declared `columns` of table `table` from `values`, rows as `selection` picks."""
    where = f"table '{table}' ({values.name})"
    grid = _grid(values.cells, columns, where, decl_loc)
    if len(grid) == 0:
        raise CalError(f"{where} has no rows", decl_loc)
    bad = np.argwhere(~np.isfinite(grid))
    if len(bad):
        row, col = (int(x) for x in bad[0])
        cell = float(grid[row, col])
        raise CalError(f"{where}, row {row + 1}, column '{columns[col]}': {cell!r} is not a "
                       "finite number", decl_loc)
    try:
        keep = select(selection, len(grid))
    except ValueError as err:
        raise CalError(f"{where}: {err}", decl_loc) from None
    numbers = [int(k) + 1 for k in keep]
    out = CsvData(values.name, len(keep), lines=numbers, numbers=list(numbers))
    out.columns = {c: grid[keep, j].copy() for j, c in enumerate(columns)}
    out.enclosures = {c: (out.columns[c], out.columns[c].copy()) for c in columns}
    return out


def _grid(cells: Any, columns: Sequence[str], where: str, loc: Loc | None) -> np.ndarray:
    """The cells as a (rows, declared columns) float array."""
    if isinstance(cells, Mapping):
        missing = [c for c in columns if c not in cells]
        if missing:
            have = ", ".join(map(str, cells)) or "none"
            raise CalError(f"{where} has no column '{missing[0]}' (its columns: {have})", loc)
        lengths = {c: len(_numbers(cells[c], f"{where}, column '{c}'", loc)) for c in columns}
        if len(set(lengths.values())) > 1:
            shown = ", ".join(f"{c}: {n}" for c, n in lengths.items())
            raise CalError(f"{where}: its columns differ in length ({shown})", loc)
        return np.column_stack([_numbers(cells[c], f"{where}, column '{c}'", loc)
                                for c in columns]).reshape(-1, len(columns))
    grid = _numbers(cells, where, loc, dims=2)
    if grid.shape[1] != len(columns):
        raise CalError(f"{where} has {grid.shape[1]} columns; the table declares "
                       f"{len(columns)} ({', '.join(columns)}), in this order", loc)
    return grid


def _numbers(x: Any, what: str, loc: Loc | None, dims: int = 1) -> np.ndarray:
    if isinstance(x, str | bytes):
        raise CalError(f"{what}: a string is not numbers (a file's path goes where the "
                       "whole table does)", loc)
    try:
        out = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise CalError(f"{what}: not numbers", loc) from None
    if out.ndim != dims:
        shape = "a sequence of numbers" if dims == 1 else "rows of numbers (a 2-D array)"
        raise CalError(f"{what}: expected {shape}, got {out.ndim} dimension(s)", loc)
    return out
