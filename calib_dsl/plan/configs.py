"""Configurations: the input columns of a table (`simulate in`, the poses a robot is sent
to) read from a file in the table's own dialect, drawn within the model's limits, and
written back: a plan is a subset of a candidate file's own lines (its header, its rows as
they are), so what is planned is what was given, to the last digit.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from calib_dsl.elaborate.tables import Dialect, read_csv
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.frontend.files import MAX_TABLE_BYTES, TooLarge, read_capped
from calib_dsl.ir.model import Column, Model, Table
from calib_dsl.studies.simulate import write_csv


@dataclass(frozen=True, eq=False)
class Configurations:
    """Rows of configurations for table `table`: `q` (rows, inputs) in the model's units,
    `raw` the same in the file's units; `lines` the file's text (header first) and `line`
    each row's line number in it (1-based), for writing subsets verbatim."""

    table: str
    path: str
    columns: tuple[str, ...]
    q: np.ndarray
    raw: np.ndarray
    lines: tuple[str, ...] = ()
    line: tuple[int, ...] = ()
    header: str = ""

    def __len__(self) -> int:
        return len(self.q)

    def subset(self, rows: list[int] | np.ndarray) -> Configurations:
        """These rows (0-based), in the order given."""
        idx = np.asarray(rows, dtype=int)
        return replace(self, q=self.q[idx], raw=self.raw[idx],
                       line=tuple(self.line[k] for k in idx) if self.line else ())


def table_of(model: Model, name: str = "") -> Table:
    """The model's table `name` ("": its only table)."""
    if not model.tables:
        raise CalError("the model has no table: there are no configurations to measure")
    if not name:
        if len(model.tables) > 1:
            raise CalError(f"the model has {len(model.tables)} tables: name the one the "
                           "configurations are for (TABLE=FILE)", model.tables[-1].loc)
        return model.tables[0]
    for t in model.tables:
        if t.name == name:
            return t
    raise CalError(f"the model has no table '{name}' (its tables: "
                   f"{', '.join(t.name for t in model.tables)})")


def inputs_of(t: Table) -> list[Column]:
    """The table's input columns: those with a `simulate in` range."""
    ins = [c for c in t.columns if c.sim is not None]
    if not ins:
        raise CalError(f"table '{t.name}' has no input column (a column group with "
                       "`simulate in [lo, hi]`): nothing says what a configuration is", t.loc)
    return ins


def read_configurations(t: Table, path: str | Path) -> Configurations:
    """The input columns of the file at `path`, read as the table reads its own file (its
    separator, decimal mark, header names, units); other columns may be absent."""
    ins = inputs_of(t)
    names = [c.name for c in ins]
    data = read_csv(path, names, dialect=Dialect(t.separator, t.decimal),
                    headers={c.name: c.header for c in ins if c.header})
    if data.rows == 0:
        raise CalError(f"'{path}' has no configurations (no row after its header)")
    raw = np.column_stack([data.columns[n] for n in names])
    factor = np.array([0.5 * (c.factor[0] + c.factor[1]) for c in ins])
    try:
        text = read_capped(Path(path), MAX_TABLE_BYTES, encoding="utf-8-sig").splitlines()
    except (TooLarge, OSError, UnicodeDecodeError) as err:  # (read_csv read it: unlikely)
        raise CalError(f"cannot read '{path}': {err}") from None
    header = next((ln for ln in text if ln.strip()), "")
    return Configurations(t.name, str(path), tuple(names), raw * factor, raw, tuple(text),
                          tuple(data.lines), header)


def draw_configurations(t: Table, count: int, rng: np.random.Generator,
                        limits: dict[str, tuple[float, float]] | None = None
                        ) -> Configurations:
    """`count` configurations drawn uniformly within each input's limits (`limits` by
    column name where the model declares joint limits, else its `simulate in` range)."""
    ins = inputs_of(t)
    ranges = [(limits or {}).get(c.name, c.sim) for c in ins]
    for c, (a, b) in zip(ins, ranges, strict=True):  # type: ignore[misc]
        if not a < b:
            raise CalError(f"column '{c.name}' of table '{t.name}': the joints whose values "
                           f"it holds have limits that do not overlap ({a:g} to {b:g})", t.loc)
    q = np.column_stack([rng.uniform(a, b, size=count) for a, b in ranges])  # type: ignore[misc]
    factor = np.array([0.5 * (c.factor[0] + c.factor[1]) for c in ins])
    return Configurations(t.name, "<drawn>", tuple(c.name for c in ins), q, q / factor)


def write_configurations(configs: Configurations, t: Table, out: str | Path) -> None:
    """The rows: the file's own header and lines when read from one, else the input columns
    in the table's dialect."""
    if configs.lines and configs.line:
        text = [configs.header, *(configs.lines[k - 1] for k in configs.line)]
        body = "\n".join(text) + "\n"
        if str(out) == "-":
            print(body, end="")
            return
        try:
            Path(out).write_text(body, encoding="utf-8")
        except OSError as err:
            raise CalError(f"cannot write '{out}': {err.strerror or err}") from None
        return
    only = replace(t, columns=inputs_of(t))
    factor = np.array([0.5 * (c.factor[0] + c.factor[1]) for c in only.columns])
    write_csv(Path(out), only, configs.raw * factor)
