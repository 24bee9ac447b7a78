"""The flat program's data types: groups of primitives as integer arrays, ready for a
vectorized propagator (compile/group.py makes them), and what the solvers derive from a
program once.
"""

from __future__ import annotations

import threading
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from calib_dsl.ir.primitives import Primitive, Slots
from calib_dsl.ir.rows import RowLayout, Tiled

T = TypeVar("T")


@dataclass
class Group:
    op: str
    level: int
    out: np.ndarray  # (n, 1), or (n, 2) for rot
    args: np.ndarray  # (n, k) slot indices
    param: np.ndarray | None  # (n,) exponent for pow
    prim: np.ndarray  # (n,) index into Program.primitives (for reports)
    # Column j of `out`/`args` has no repeated slot: a plain fancy assignment intersects it.
    out_unique: tuple[bool, ...]
    args_unique: tuple[bool, ...]


@dataclass
class Program:
    source: str
    formulation: str
    slots: Slots
    primitives: Sequence[Primitive]  # a list, or ir/rows.Tiled for a loop compiled once
    groups: list[Group]
    true_values: dict[str, float | None]
    domains: dict[str, tuple[float, float]] | None = None  # as declared (the search domains)
    # `lsq(start) +- w` domains: (start, w) by name; once centred (analysis/priors.py), the
    # estimate each was centred on, and w
    priors: dict[str, tuple[float, float]] = field(default_factory=dict)
    centred: dict[str, tuple[float, float]] = field(default_factory=dict)
    # the unknowns whose true value the model states (`true v`); the others' `true_values`
    # are their `c +- w` centres, what `calibc simulate` draws data from, not a known truth
    true_stated: set[str] = field(default_factory=set)
    # a loop compiled once: where its rows' slots and primitives are (ir/rows.py)
    rows: RowLayout | None = None
    # the unknowns whose unit the model says (a robot frame's length or angle), by name
    units: dict[str, str] = field(default_factory=dict)
    # the data it was compiled from: per table, the file read and the rows used (provenance)
    tables: dict[str, tuple[str, int]] = field(default_factory=dict)
    sources: tuple[str, ...] = ()  # the model's files: the model, then what it includes
    # What the solvers derive from the program whatever the box (propagation kernels,
    # layouts, plans), by kind, with the groups it was made from (see `derived`).
    derived_cache: dict[str, tuple[list[Group], Any]] = field(
        default_factory=dict, init=False, repr=False, compare=False)

    def __getstate__(self) -> dict[str, Any]:
        # the cache holds closures, and a child process rebuilds what it needs
        return {**self.__dict__, "derived_cache": {}}

    @property
    def op_counts(self) -> dict[str, int]:
        return dict(sorted(_count(self.primitives, lambda p: p.op).items()))

    def counts(self) -> dict:
        kinds = _count(self.slots.kinds, lambda k: k)
        return {
            "variables": len(self.slots.names) - kinds["const"],
            "declared": len(self.slots.declared),
            "temporaries": kinds["temp"],
            "constants": kinds["const"],
            "primitives": len(self.primitives),
            "groups": len(self.groups),
            "levels": 1 + max((g.level for g in self.groups), default=0),
            "ops": self.op_counts,
        }


def _count(seq: Sequence[T], key: Callable[[T], str]) -> Counter[str]:
    """Counter(map(key, seq)); a loop compiled once counts its template once per row."""
    if isinstance(seq, Tiled):  # (rendering a row keeps the op and the kind)
        shared = Counter(map(key, seq.shared))
        for k, v in Counter(map(key, seq.template)).items():
            shared[k] += v * seq.rows
        return shared
    return Counter(map(key, seq))


def derived(prog: Program, kind: str, build: Callable[[], T], wait: bool = True) -> T:
    """build(), made once per program and `kind` (the tight strategy runs the same program
    dozens of times), and made again if the program's groups were replaced. Threads that
    ask while another builds wait for its table (one build, not one per thread); with
    `wait` False, a build that runs threads of its own (which may ask for other tables, and
    would wait forever for this one's lock) is made outside the lock: two threads asking at
    once then build it twice, the same table."""
    cached = prog.derived_cache.get(kind)
    if cached is not None and cached[0] is prog.groups:
        return cached[1]  # type: ignore[no-any-return]
    if not wait:
        value = build()
        prog.derived_cache[kind] = (prog.groups, value)
        return value
    with _BUILDING:  # (reentrant: a build may ask for other tables)
        cached = prog.derived_cache.get(kind)
        if cached is not None and cached[0] is prog.groups:
            return cached[1]  # type: ignore[no-any-return]
        value = build()
        prog.derived_cache[kind] = (prog.groups, value)
        return value


_BUILDING = threading.RLock()  # held while a derived table is built
