"""A report read back as a test reads it: the parameter rows (name, and per column its
printed ends and the JSON value it came from) and every element's tag and attributes, with
the standard library's HTML parser."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from html.parser import HTMLParser
from typing import Any


@dataclass
class Cell:
    key: str | None
    json: Any
    text: str = ""


@dataclass
class Page(HTMLParser):
    rows: dict[str, list[Cell]] = field(default_factory=dict)
    tags: list[tuple[str, dict[str, str | None]]] = field(default_factory=list)
    values: list[Cell] = field(default_factory=list)  # every element with data-json
    _row: str | None = None
    _cell: Cell | None = None
    _text: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        HTMLParser.__init__(self)

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        self.tags.append((tag, a))
        if tag == "tr" and "param" in (a.get("class") or "").split():
            self._row = a["data-name"]
            self.rows[self._row] = []
        if "data-json" in a:
            raw = a["data-json"] or ""
            try:
                value = json.loads(raw)
            except ValueError:
                value = raw
            self._cell = Cell(a.get("data-key"), value)
            self.values.append(self._cell)
            if self._row is not None:
                self.rows[self._row].append(self._cell)
        elif tag == "td" and self._row is not None:
            self._cell = Cell(None, None)  # (a keyed cell's upper end, or another column)
            self.rows[self._row].append(self._cell)

    def handle_endtag(self, tag: str) -> None:
        if tag in ("td", "span") and self._cell is not None:
            self._cell.text = "".join(self._text).strip()
            self._cell, self._text = None, []
        if tag == "tr":
            self._row = None

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._text.append(data)


def read(html: str) -> Page:
    page = Page()
    page.feed(html)
    return page


def intervals(page: Page, name: str) -> dict[str, tuple[Any, str, str]]:
    """Per column key (domain, result, inner): (the JSON value, printed lo, printed hi)."""
    cells = page.rows[name]
    out = {}
    for k, c in enumerate(cells):
        if c.key in ("domain", "result", "inner"):
            out[c.key] = (c.json, c.text, cells[k + 1].text)
    return out
