"""The data rows a solve with outliers names, as the user counts them: the table, the data
row number (1: the first row after the header, as `--rows`/`--exclude` count) and the line of
its file; and the inputs without some of them."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.elaborate.rows import EVERY_ROW, Selection
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program

SHOWN = 10  # rows the text report lists (the JSON has every one)


@dataclass(frozen=True)
class Row:
    table: str
    file: str
    line: int
    row: int  # the data row number (1: the first after the header)


@dataclass(frozen=True)
class Outliers:
    k: int
    certain: list[Row]  # fail on the whole enclosure: outliers for every vector in it
    possible: list[Row]  # not proven to hold on the whole enclosure
    # the first `proven` certain rows were proven before any LP, each by disjoint sets of the
    # other rows inconsistent with it (outliers/proof.py)
    proven: int = 0

    def as_json(self) -> dict[str, Any]:
        return {"k": self.k, "certain": [r.row for r in self.certain], "proven": self.proven,
                "possible": [r.row for r in self.possible],
                "rows": [{"table": r.table, "row": r.row, "line": r.line, "file": r.file,
                          "certain": r in self.certain}
                         for r in self.certain + self.possible]}

    def render(self) -> str:
        def listed(rows: list[Row]) -> str:
            shown = ", ".join(f"{r.file}:{r.line} (row {r.row})" for r in rows[:SHOWN])
            more = f", ... ({len(rows) - SHOWN} more; the JSON lists them all)" \
                if len(rows) > SHOWN else ""
            return shown + more or "none"

        most = f"at most {self.k} row{'s' if self.k > 1 else ''}"
        how = f"\n({self.proven} proven first: each with disjoint sets of the other rows, as " \
            "many as outliers were left, proven inconsistent with it)" if self.proven else ""
        return (f"outliers ({most}): certain {listed(self.certain)}{how}\n"
                f"possible outliers (not proven to hold on the whole result): "
                f"{listed(self.possible)}")


def data_rows(model: Model, prog: Program, ids: list[int]) -> list[Row]:
    """The data rows of these ids (`Slots.row_keys`: table, model row k of `table.col[k]`)."""
    keys = prog.slots.row_keys or []
    tables = {t.name: t for t in model.tables}
    out = []
    for i in ids:
        name, k = keys[i]
        t = tables[name]
        out.append(Row(name, t.path, t.lines[k - 1], t.numbers[k - 1]))
    return out


def excluding(inputs: Inputs, rows: list[Row], first: str) -> Inputs:
    """The inputs with these data rows left out (as `--exclude` does; `first`: the first
    table's name, whose selection may be under "": a named one would replace it)."""
    sel = dict(inputs.rows)
    for r in rows:
        key = "" if r.table == first and "" in sel and first not in sel else r.table
        now = sel.get(key, EVERY_ROW)
        sel[key] = Selection(now.ranges, tuple(sorted({*now.excluded, r.row})))
    return replace(inputs, rows=sel)
