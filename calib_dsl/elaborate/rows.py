"""Which rows of a table to use: ranges with a step, and rows left out.

Rows are numbered from 1, the first row after the header, as a spreadsheet shows them less
one. `1..1495:15` is every 15th row from 1 (1, 16, 31, ...); `100..` all rows from 100 on;
several ranges are joined by commas. A selection outside the table is an error, never a
silent truncation: a user who asked for rows 1..2000 of a 1495-row file has the wrong file.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

_RANGE = re.compile(r"^\s*(\d+)?\s*(\.\.\s*(\d+)?)?\s*(:\s*(\d+))?\s*$")


@dataclass(frozen=True)
class RowRange:
    first: int
    last: int | None  # None: to the last row
    step: int = 1

    def __str__(self) -> str:
        last = "" if self.last is None else str(self.last)
        step = "" if self.step == 1 else f":{self.step}"
        return f"{self.first}..{last}{step}" if self.last != self.first else str(self.first)


@dataclass(frozen=True)
class Selection:
    ranges: tuple[RowRange, ...] = ()  # empty: every row
    excluded: tuple[int, ...] = ()


EVERY_ROW = Selection()


def parse_ranges(text: str) -> tuple[RowRange, ...]:
    """`1..1495:15`, `7`, `100..`, `..50`, or several joined by commas; ValueError with a
    message that says what is wrong."""
    out = []
    for part in text.split(","):
        m = _RANGE.match(part)
        if not m or not part.strip() or (m.group(1) is None and m.group(2) is None):
            raise ValueError(f"'{part.strip()}' is not a row range (write FIRST..LAST:STEP, "
                             "e.g. 1..1495:15, or a row number)")
        first = int(m.group(1)) if m.group(1) else 1
        last = (int(m.group(3)) if m.group(3) else None) if m.group(2) else first
        step = int(m.group(5)) if m.group(5) else 1
        out.append(_checked(RowRange(first, last, step)))
    return tuple(out)


def parse_numbers(text: str) -> tuple[int, ...]:
    """`533, 856`: row numbers."""
    out = []
    for part in text.split(","):
        if not part.strip().isdigit():
            raise ValueError(f"'{part.strip()}' is not a row number")
        out.append(int(part))
    return tuple(out)


def _checked(r: RowRange) -> RowRange:
    if r.first < 1:
        raise ValueError(f"row {r.first}: rows are numbered from 1 (the first after the header)")
    if r.step < 1:
        raise ValueError(f"a step of {r.step}: it must be 1 or more")
    if r.last is not None and r.last < r.first:
        raise ValueError(f"the range {r.first}..{r.last} is empty (its end is before its start)")
    return r


def select(sel: Selection, n: int) -> np.ndarray:
    """The 0-based indices of the selected rows of an n-row table, in order, each once;
    ValueError when the selection reaches past the table or selects nothing."""
    for r in sel.ranges:
        last = n if r.last is None else r.last
        if r.first > n or last > n:
            raise ValueError(f"rows {r} reach past the end of the table ({n} rows)")
    for k in sel.excluded:
        if not 1 <= k <= n:
            raise ValueError(f"row {k} is excluded but the table has rows 1..{n}")
    if sel.ranges:
        keep = np.zeros(n, dtype=bool)
        for r in sel.ranges:
            last = n if r.last is None else r.last
            keep[np.arange(r.first - 1, last, r.step)] = True
    else:
        keep = np.ones(n, dtype=bool)
    keep[np.array(sel.excluded, dtype=np.int64) - 1] = False
    if not keep.any():
        raise ValueError("the row selection leaves no row")
    return np.flatnonzero(keep)
