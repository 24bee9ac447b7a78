"""A data table with one cell moved: the faulty files the outlier, conflict and load tests
solve (the table's text in, the text out; each test writes it where it needs)."""

from __future__ import annotations


def moved_cell(text: str, row: int, column: str, by: float) -> str:
    """The CSV `text` with the value in line `row` (the header is line 0) of `column` moved
    by `by`, written back exactly (repr)."""
    lines = text.splitlines()
    j = lines[0].split(",").index(column)
    cells = lines[row].split(",")
    cells[j] = repr(float(cells[j]) + by)
    lines[row] = ",".join(cells)
    return "\n".join(lines) + "\n"
