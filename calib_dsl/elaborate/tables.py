"""Measurement tables: CSV files with a header row, one configuration per row.

A file is read as it comes: its separator and decimal mark (`Dialect`), its own header names
(mapped to the model's column names), and only the rows selected (`rows.Selection`: a row
left out is not parsed at all). Only the declared columns are read (extra columns are
ignored, whatever they hold). Every problem is a `CalError` located in the CSV file itself:
`Loc(csv path, line, column number)` where the column number is the 1-based position of the
field in its row.
"""

from __future__ import annotations

import csv
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from calib_dsl.arith.exact import add_rounded, enclose_decimal
from calib_dsl.elaborate.rows import EVERY_ROW, Selection, select
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.frontend.files import MAX_TABLE_BYTES, NotUtf8, TooLarge, capped_lines

FloatArray = NDArray[np.float64]

_NUMBER = re.compile(r"[+-]?([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][+-]?[0-9]+)?")
_NON_FINITE = re.compile(r"[+-]?(nan|inf|infinity)", re.IGNORECASE)


@dataclass(frozen=True)
class Dialect:
    separator: str = ","
    decimal: str = "."  # or ",": a decimal comma (the separator must then be another)


@dataclass
class CsvData:
    """The declared columns of a CSV file: `columns[name][row - 1]` is a cell value (the
    nearest float); `enclosures[name]` = (lo, hi), the tightest floats around the exact decimal
    value of each cell (lo == hi when the decimal is a float)."""

    path: str
    rows: int
    columns: dict[str, FloatArray] = field(default_factory=dict)
    enclosures: dict[str, tuple[FloatArray, FloatArray]] = field(default_factory=dict)
    lines: list[int] = field(default_factory=list)  # the CSV line of each row read
    numbers: list[int] = field(default_factory=list)  # its data row number (1: after the header)


def read_csv(path: str | Path, columns: Sequence[str], decl_loc: Loc | None = None, *,
             dialect: Dialect = Dialect(), headers: Mapping[str, str] | None = None,
             selection: Selection = EVERY_ROW, selection_loc: Loc | None = None) -> CsvData:
    """Read the declared `columns` of the CSV file at `path`: `headers` maps a column to the
    file's name for it (default: the same name), `selection` picks the rows.

    `decl_loc` (where the model declares the table) locates a missing or unreadable file;
    `selection_loc` a selection that does not fit the file.
    """
    name = str(path)
    shown = {c: (headers or {}).get(c, c) for c in columns}
    _, header, data = _stream(name, decl_loc, dialect, shown)
    try:
        keep = select(selection, len(data))
    except ValueError as err:
        raise CalError(f"data file '{name}': {err}", selection_loc) from None
    out = CsvData(name, len(keep), lines=[data[k][0] for k in keep],
                  numbers=[int(k) + 1 for k in keep])
    values = np.empty((3, len(columns), len(keep)))  # nearest, lo, hi
    field_no = [header.index(shown[c]) + 1 for c in columns]  # (names are unique)
    for i, k in enumerate(keep.tolist()):
        line, fields = data[k]
        if isinstance(fields, int):
            raise CalError(f"data file '{name}', row {k + 1}: {fields} fields, but the "
                           f"header has {len(header)}",
                           Loc(name, line, min(fields, len(header)) + 1, field=True,
                               sep=dialect.separator))
        for j, col in enumerate(columns):
            values[:, j, i] = _cell(fields[j], name, line, k + 1, _named(col, shown),
                                    field_no[j], dialect)
    out.columns = {col: values[0, j] for j, col in enumerate(columns)}
    out.enclosures = {col: (values[1, j], values[2, j]) for j, col in enumerate(columns)}
    return out


def _named(col: str, shown: Mapping[str, str]) -> str:
    """How a message names a column: 'q1', or 'q1' ("shoulder_pan_joint") when mapped."""
    return f"'{col}'" if shown[col] == col else f"'{col}' (\"{shown[col]}\")"


def cell_bounds(lo: FloatArray, hi: FloatArray, tol: float) -> tuple[FloatArray, FloatArray]:
    """[lo - tol, hi + tol] for each cell, rounded outward (and exact when it can be)."""
    return -add_rounded(-lo, tol, 1.0), add_rounded(hi, tol, 1.0)


# -- steps ----------------------------------------------------------------------------------
def _stream(name: str, decl_loc: Loc | None, dialect: Dialect, shown: Mapping[str, str]
            ) -> tuple[int, list[str], list[tuple[int, tuple[str, ...] | int]]]:
    """The file read a line at a time: the header's line and fields, and per data row its
    line and the fields of the declared columns (in their order), or its number of fields
    when that is not the header's (an error if the row is used). Nothing else is kept."""
    lines = _lines(name, decl_loc)
    reader = csv.reader(lines, delimiter=dialect.separator)
    header: list[str] | None = None
    at: list[int] = []
    data: list[tuple[int, tuple[str, ...] | int]] = []
    try:
        for row in reader:
            if _blank(row):
                continue
            if header is None:
                header, head_line = row, reader.line_num
                where = _column_positions(name, head_line, [h.strip() for h in header], shown,
                                          dialect)
                at = [where[c] for c in shown]
                continue
            data.append((reader.line_num, tuple(row[j] for j in at)
                         if len(row) == len(header) else len(row)))
    except csv.Error as err:
        raise CalError(f"data file '{name}' is not valid CSV: {err}",
                       Loc(name, reader.line_num, 1)) from None
    if header is None:
        raise CalError(f"data file '{name}' is empty: it needs a header row naming the "
                       "columns, then one row per configuration", Loc(name, 1, 1))
    if not data:
        raise CalError(f"data file '{name}' has a header but no data rows",
                       Loc(name, head_line + 1, 1))
    return head_line, [h.strip() for h in header], data


def _lines(name: str, decl_loc: Loc | None) -> Iterator[str]:
    """capped_lines, its failures as one clear message each."""
    try:
        yield from capped_lines(name, MAX_TABLE_BYTES)
    except TooLarge as err:
        raise CalError(f"data file '{name}' is {err}: too large for a table", decl_loc) from None
    except FileNotFoundError:
        raise CalError(f"data file '{name}' not found", decl_loc) from None
    except IsADirectoryError:
        raise CalError(f"data file '{name}' is a directory", decl_loc) from None
    except NotUtf8 as err:
        raise CalError(f"data file '{name}' is not UTF-8 text ({err.reason}: byte "
                       f"{err.object[err.start]:#04x}; save it as UTF-8)",
                       Loc(name, err.line, err.col)) from None
    except OSError as err:
        raise CalError(f"cannot read data file '{name}': {err.strerror}", decl_loc) from None


def _blank(row: list[str]) -> bool:
    return not row or (len(row) == 1 and not row[0].strip())


def _column_positions(name: str, line: int, header: list[str], columns: Mapping[str, str],
                      dialect: Dialect) -> dict[str, int]:
    """{declared column: its field index}, looked up by its name in the file (`columns`
    maps each declared column to it); each must appear exactly once."""
    wanted = {h: c for c, h in columns.items()}
    where: dict[str, int] = {}
    for j, h in enumerate(header):
        if h in wanted:
            c = wanted[h]
            if c in where:
                raise CalError(f"data file '{name}': column '{h}' appears twice in the header "
                               f"(fields {where[c] + 1} and {j + 1})",
                               Loc(name, line, j + 1, field=True, sep=dialect.separator))
            where[c] = j
    missing = [columns[c] for c in columns if c not in where]
    if missing:
        have = ", ".join(h for h in header if h) or "none"
        raise CalError(f"data file '{name}' has no column {_quoted(missing)} (its columns: "
                       f"{have}){_separator_hint(header, dialect)}{_case_hint(missing, header)}",
                       Loc(name, line, 1))
    return where


# The separators a table may declare, as the table writes them.
SEPARATORS = {",": '","', ";": '";"', "\t": '"tab"', "|": '"|"'}


def _case_hint(missing: list[str], header: list[str]) -> str:
    """Missing names the header spells in another case: header names are exact."""
    folded = {h.strip().casefold(): h.strip() for h in header}
    near = [(m, folded[m.casefold()]) for m in missing if m.casefold() in folded]
    if not near:
        return ""
    said = ", ".join(f"'{h}' for '{m}'" for m, h in near)
    return f" (the file has {said}: header names are case-sensitive)"


def _separator_hint(header: list[str], dialect: Dialect) -> str:
    """A header read as one field that holds another separator: the file's, most likely."""
    if len(header) != 1:
        return ""
    for sep, spelled in SEPARATORS.items():
        if sep != dialect.separator and sep in header[0]:
            what = "tab" if sep == "\t" else f'"{sep}"'
            return f" (the file looks {what}-separated: say separator = {spelled} in the table)"
    return ""


def _quoted(names: list[str]) -> str:
    return ", ".join(f"'{n}'" for n in names)


def _cell(text: str, name: str, line: int, row: int, col: str,
          field_no: int, dialect: Dialect) -> tuple[float, float, float]:
    """(nearest float, lo, hi) of a cell: [lo, hi] holds its exact decimal value."""
    cell = text.strip()
    where = f"data file '{name}', row {row}, column {col}"
    loc = Loc(name, line, field_no, field=True, sep=dialect.separator)
    if not cell:
        raise CalError(f"{where}: empty cell", loc)
    if _NON_FINITE.fullmatch(cell):
        raise CalError(f"{where}: '{cell}' is not a finite number", loc)
    if dialect.decimal == ",":
        if "." in cell:
            raise CalError(f"{where}: '{cell}' has a decimal point, but the table says its "
                           "decimal mark is a comma", loc)
        number = cell.replace(",", ".")
    else:
        number = cell
    match = _NUMBER.fullmatch(number)
    if not match:
        raise CalError(f"{where}: '{cell}' is not a number", loc)
    value = float(number)  # correctly rounded, however many digits
    if not np.isfinite(value):
        raise CalError(f"{where}: '{cell}' is too large for a float", loc)
    exponent = match.group(3)
    if len(number) > MAX_EXACT_CHARS or (exponent and abs(int(exponent[1:])) > MAX_EXACT_CHARS):
        # exactly, it would cost a huge integer; the floats on each side of the correctly
        # rounded value hold the exact one
        return value, float(np.nextafter(value, -np.inf)), float(np.nextafter(value, np.inf))
    return (value, *enclose_decimal(number))


# a cell longer than this is enclosed by its float's neighbours instead of exactly (an
# exponent past it would make an exact Fraction of 10**exponent): far past a float's 17 digits
MAX_EXACT_CHARS = 400
