"""Rows as a batch dimension: the layout of a program whose loop over a table's rows was
compiled once (compile/replicate.py), and the per-slot and per-primitive sequences that such
a program reads on demand instead of holding one Python object per row.

Slots: the `shared` ones first (unknowns, constants, what depends on no row), then one block
of `width` slots per row, in the order of the loop's rows; slot `shared + r * width + j` is
the template's row slot j in row r. Primitives likewise: the shared ones, then one block of
`count` per row.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar, overload

import numpy as np

from calib_dsl.frontend.diagnostics import Loc

T = TypeVar("T")


@dataclass(frozen=True)
class RowLayout:
    """Where a batched loop's rows sit in the program."""

    rows: np.ndarray  # the loop index k of each row, in order
    shared: int  # slots before the first row's block
    width: int  # slots per row
    shared_prims: int  # primitives before the first row's block
    count: int  # primitives per row
    tables: tuple[str, ...]  # the tables the loop reads
    loc: Loc | None  # the loop

    def row_slot(self, slot: int) -> tuple[int, int] | None:
        """(row index r, template slot j) of a row slot; None for a shared one."""
        if slot < self.shared:
            return None
        return divmod(slot - self.shared, self.width)

    def shift(self, slots: tuple[int, ...], r: int) -> tuple[int, ...]:
        """Row 0's slots as row r's (shared slots unchanged)."""
        step = r * self.width
        return tuple(s + step if s >= self.shared else s for s in slots)


class Tiled(Sequence[T], Generic[T]):
    """`shared + template * rows`, without the copies: item i of a row block is
    `render(template item, row index)` (the template item itself when render is None)."""

    def __init__(self, shared: list[T], template: list[T], rows: int,
                 render: Callable[[T, int, int], T] | None = None) -> None:
        self.shared, self.template, self.rows = shared, template, rows
        self.render = render

    def __len__(self) -> int:
        return len(self.shared) + len(self.template) * self.rows

    @overload
    def __getitem__(self, i: int) -> T: ...
    @overload
    def __getitem__(self, i: slice) -> list[T]: ...

    def __getitem__(self, i: int | slice) -> T | list[T]:
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self)))]
        n = len(self)
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError(i)
        if i < len(self.shared):
            return self.shared[i]
        r, j = divmod(i - len(self.shared), len(self.template))
        item = self.template[j]
        return item if self.render is None else self.render(item, r, j)

    def __iter__(self) -> Iterator[T]:
        yield from self.shared
        for r in range(self.rows):
            if self.render is None:
                yield from self.template
            else:
                for j, item in enumerate(self.template):
                    yield self.render(item, r, j)

    def __setitem__(self, i: int, value: T) -> None:
        if not 0 <= i < len(self.shared):
            raise TypeError("a row slot's entry is the template's: it cannot be set alone")
        self.shared[i] = value

    def __add__(self, other: Any) -> list[T]:
        return list(self) + list(other)

    def index(self, value: Any, start: int = 0, stop: int | None = None) -> int:
        if start == 0 and stop is None and value in self.shared:  # names of unknowns
            return self.shared.index(value)
        return super().index(value, start, len(self) if stop is None else stop)


def tiled_mask(seq: Sequence[str], wanted: tuple[str, ...]) -> np.ndarray:
    """Per item of a sequence of kinds, whether it is one of `wanted` (a Tiled sequence is
    read once per template, not once per row)."""
    if isinstance(seq, Tiled):
        shared = np.array([k in wanted for k in seq.shared], dtype=bool)
        row = np.array([k in wanted for k in seq.template], dtype=bool)
        return np.concatenate([shared, np.tile(row, seq.rows)])
    return np.fromiter((k in wanted for k in seq), dtype=bool, count=len(seq))
