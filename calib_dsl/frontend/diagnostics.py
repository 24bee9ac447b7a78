"""User-facing errors: one message `file:line:col: error: ...`, the line, and a caret."""

from __future__ import annotations

import re
from dataclasses import dataclass
from dataclasses import field as _attribute
from pathlib import Path


@dataclass(frozen=True)
class Loc:
    """A place in a model file (1-based line and column)."""

    file: str
    line: int
    col: int
    # `col` counts CSV fields, not characters (a data-file location); only the caret uses it
    field: bool = _attribute(default=False, compare=False)
    sep: str = _attribute(default=",", compare=False)  # the fields' separator in that file

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


class CalError(Exception):
    """An error in the user's input (model, data, options): reported, never a traceback."""

    def __init__(self, message: str, loc: Loc | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.loc = loc

    def render(self) -> str:
        """`file:line:col: error: message`, then the offending line and a caret under the column."""
        if self.loc is None:
            return f"error: {visible(self.message)}"
        head = f"{self.loc}: error: {visible(self.message)}"
        line = _source_line(self.loc.file, self.loc.line)
        if line is None:
            return head
        col = _field_start(line, self.loc.col, self.loc.sep) if self.loc.field else self.loc.col
        before, after = _window(line, max(col, 1) - 1)
        caret = " " * len(visible(before)) + "^"
        return f"{head}\n    {visible(before + after)}\n    {caret}"


def _window(line: str, at: int, half: int = 60) -> tuple[str, str]:
    """The line before and from character `at`, each cut to `half` characters with '...'
    where cut: one long line (a JSON file, a wide CSV row) stays one readable line."""
    before, after = line[:at], line[at:]
    if len(before) > half:
        before = "..." + before[len(before) - half:]
    if len(after) > half:
        after = after[:half] + "..."
    return before, after


def visible(text: str) -> str:
    """`text` with its control characters (a NUL, an escape sequence) written as escapes
    (\\x00), so that a message never sends them raw to the terminal; line breaks stay."""
    return _CONTROL.sub(lambda m: repr(m.group())[1:-1], text)


_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f]")


def _source_line(file: str, line: int) -> str | None:
    try:
        lines = Path(file).read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return None
    if 1 <= line <= len(lines):
        return lines[line - 1].expandtabs(1)
    return None


def _field_start(line: str, field: int, sep: str = ",") -> int:
    """The character column where CSV field number `field` (1-based) starts."""
    import csv

    fields = next(csv.reader([line], delimiter=sep), [])
    col = 1
    for text in fields[: max(field - 1, 0)]:
        col += len(text) + 1  # a quoted field is longer on the line; close enough for a caret
    return col
