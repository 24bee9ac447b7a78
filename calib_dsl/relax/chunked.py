"""An Evaluation of a large program with its rows compiled once, a chunk of rows at a time.

`evaluation(...)` is what callers make instead of an `Evaluation`: on a program that fits
in one chunk (settings.chunk_slots) it is one; on a larger program with a loop compiled
once it runs one per chunk of rows (compile/chunks.py) and joins their constraint rows,
with slots and table rows numbered as in the whole program. The per-slot arrays (gradients
in every unknown) then live for one chunk at a time: memory grows with the rows' results,
not with their slots.
"""

from __future__ import annotations

import ctypes
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import TypeVar

import numpy as np

from calib_dsl.compile.chunks import Chunk, chunked
from calib_dsl.ir.program import Program
from calib_dsl.relax.evaluation import Evaluation
from calib_dsl.relax.gradients import Iv
from calib_dsl.relax.layout import independents
from calib_dsl.relax.ownership import row_owners
from calib_dsl.settings import LPSettings, Settings

Row = tuple[Iv, Iv, Iv, np.ndarray]  # what Evaluation.run gives per block of rows
CHUNK_SLOTS = Settings.chunk_slots  # (a module attribute: tests make chunks small)
# the threads a chunked pass shares its chunks among: as many as the LPs' (the cores); two
# chunks' arrays at once, each sized to stay in the cache
CHUNK_THREADS = LPSettings.workers
MALLOC_ARENAS = Settings.malloc_arenas


class Evaluated:
    """The surface of an Evaluation the callers read: `run()` (the constraint rows),
    then `rows` (raw forms whose index 5 holds the target slots), `sources`, `targets()`,
    `e`, and `data_rows()`."""

    rows: list[tuple]
    sources: list[np.ndarray]
    e: np.ndarray

    def run(self) -> list[Row]:
        raise NotImplementedError

    def targets(self) -> np.ndarray:
        return np.concatenate([r[5] for r in self.rows]) if self.rows else np.zeros(0, int)

    def data_rows(self) -> np.ndarray:
        raise NotImplementedError


class Whole(Evaluated):
    """One Evaluation of the whole program."""

    def __init__(self, prog: Program, ind: np.ndarray, ev: Evaluation) -> None:
        self.prog, self.ind, self.ev = prog, ind, ev

    def run(self) -> list[Row]:
        out = self.ev.run()
        self.rows, self.sources, self.e = self.ev.rows, self.ev.sources, self.ev.e
        return out

    def data_rows(self) -> np.ndarray:
        return row_owners(self.prog, self.ind, self.sources, [r[5] for r in self.rows])


class Chunked(Evaluated):
    """Evaluations of the program's rows a chunk at a time, joined."""

    def __init__(self, chunks: list[Chunk], lo: np.ndarray, hi: np.ndarray, ind: np.ndarray,
                 center: np.ndarray, point: bool, mixed: bool, owners: bool) -> None:
        self.chunks, self.box, self.ind = chunks, (lo, hi), ind
        self.center, self.point, self.mixed, self.owners = center, point, mixed, owners
        self.rows, self.sources = [], []
        self.e = np.zeros(0)
        self._owners: list[np.ndarray] = []

    def run(self) -> list[Row]:
        out: list[Row] = []
        for rows, raws, sources, owners, e in in_threads(self._chunk, self.chunks):
            out += rows
            self.rows += raws
            self.sources += sources
            self._owners += owners
            self.e = widest(self.e, e)
        return out

    def _chunk(self, ch: Chunk) -> tuple[list[Row], list[tuple], list[np.ndarray],
                                         list[np.ndarray], np.ndarray]:
        """One chunk's constraint rows, raw rows, sources and owners (the kept ones, numbered
        as in the whole program), and its error bounds."""
        lo, hi = self.box
        ev = Evaluation(ch.prog, ch.box(lo), ch.box(hi), self.ind, self.center,
                        point=self.point, mixed=self.mixed)
        diffs = ev.run()
        owners = (row_owners(ch.prog, self.ind, ev.sources, [r[5] for r in ev.rows])
                  if self.owners else None)
        out: list[Row] = []
        raws: list[tuple] = []
        sources: list[np.ndarray] = []
        mine_all: list[np.ndarray] = []
        at = 0
        for raw, diff, src in zip(ev.rows, diffs, ev.sources, strict=True):
            size = len(raw[5])
            keep = ch.kept(raw[5])
            mine = owners[at: at + size] if owners is not None else None
            at += size
            if not np.any(keep):
                continue
            pick = None if bool(np.all(keep)) else np.flatnonzero(keep)
            out.append(_mapped_row(diff, ch, pick))
            raws.append(_mapped_raw(raw, ch, pick))
            sources.append(ch.slots(src if pick is None else src[pick]))
            if mine is not None:
                mine_all.append(ch.row_ids(mine if pick is None else mine[pick]))
        return out, raws, sources, mine_all, ev.e

    def data_rows(self) -> np.ndarray:
        assert self.owners, "made without owners=True"
        return (np.concatenate(self._owners).astype(np.int64) if self._owners
                else np.zeros(0, dtype=np.int64))


T = TypeVar("T")
U = TypeVar("U")


def in_threads(fn: Callable[[T], U], items: Sequence[T], threads: int | None = None) -> list[U]:
    """[fn(x) for x in items], shared among `threads` threads (CHUNK_THREADS if None): this
    one and the others of one pool that lives as long as the process, in the items' order.
    Each runs under the caller's floating-point error handling (np.errstate, which a thread
    does not inherit). Few, lasting threads: each thread's freed memory stays in its own
    malloc arena, so a new thread per pass would grow the process's peak."""
    n = threads or CHUNK_THREADS
    if len(items) <= 1 or n <= 1 or getattr(_here, "worker", False):
        return [fn(x) for x in items]  # (a pool's worker never waits on its own pool)
    err = np.geterr()

    def run(x: T) -> U:
        _here.worker = True
        with np.errstate(**err):
            return fn(x)

    # (the first items may each build a program's derived tables that the others read: a
    # table built twice is the same table, for a small part of a chunk's time)
    theirs = [_pool(n - 1).submit(run, x) for i, x in enumerate(items) if i % n]
    mine = [fn(x) for x in items[::n]]
    return [mine[i // n] if i % n == 0 else theirs[i - i // n - 1].result()
            for i in range(len(items))]


_here = threading.local()
_pools: dict[int, ThreadPoolExecutor] = {}
_lock = threading.Lock()


def _pool(workers: int) -> ThreadPoolExecutor:
    with _lock:  # (callers in several threads: the inner bounds' own)
        if workers not in _pools:
            if not _pools:
                _cap_arenas(MALLOC_ARENAS)
            _pools[workers] = ThreadPoolExecutor(workers, thread_name_prefix="chunks")
        return _pools[workers]


@contextmanager
def alone() -> Iterator[None]:
    """Within it, this thread's in_threads calls run their items themselves: for a caller
    that already runs beside another busy thread of its own (both cores taken), where the
    pool's workers would only contend with the two for the cores and the interpreter."""
    before = getattr(_here, "worker", False)
    _here.worker = True
    try:
        yield
    finally:
        _here.worker = before


def _cap_arenas(arenas: int) -> bool:
    """glibc's malloc arenas capped at `arenas` (mallopt M_ARENA_MAX) before the threads
    start (False where this is no glibc, or `arenas` is 0): freed memory is then shared
    among threads instead of held per thread. Only the memory's placement changes."""
    if arenas <= 0 or not sys.platform.startswith("linux"):
        return False
    try:
        m_arena_max = -8  # (glibc's malloc.h)
        return bool(ctypes.CDLL("libc.so.6").mallopt(m_arena_max, arenas))
    except (OSError, AttributeError):
        return False


def release_freed() -> bool:
    """Freed heap memory handed back to the system (glibc's malloc_trim; False where this is
    no glibc): memory a phase freed in one thread's arena is otherwise still held there
    while another arena grows for the next phase, and the peak adds both. Only the memory's
    placement changes."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        return bool(ctypes.CDLL("libc.so.6").malloc_trim(0))
    except (OSError, AttributeError):
        return False


def evaluation(prog: Program, lo: np.ndarray, hi: np.ndarray, center: np.ndarray,
               point: bool = False, mixed: bool = False, owners: bool = False,
               rows: np.ndarray | None = None) -> Evaluated:
    """An Evaluation of the program over [lo, hi] (see relax/evaluation.py), its unknowns
    the program's independents (`center` their values), in chunks of CHUNK_SLOTS slots
    where the program is large and its rows were compiled once. With `owners`,
    `data_rows()` then gives each constraint row's data row (relax/ownership.py). `rows`:
    only these rows of the loop compiled once (indices; a program without one: all rows),
    with the shared part's constraints. An empty `center` (of a program with unknowns, in
    point mode, whose box fixes them): the rows' values only, without gradients (G with no
    columns; a value never depends on a gradient, so it is the same bits)."""
    ind = independents(prog)
    if not len(center):
        ind = ind[:0]
    chunks = chunked(prog, CHUNK_SLOTS, rows)
    if chunks is None:
        return Whole(prog, ind, Evaluation(prog, lo, hi, ind, center, point=point,
                                           mixed=mixed))
    return Chunked(chunks, lo, hi, ind, center, point, mixed, owners)


def _take(x: Iv, pick: np.ndarray | None) -> Iv:
    return x if pick is None else (x[0][pick], x[1][pick])


def _mapped_row(row: Row, ch: Chunk, pick: np.ndarray | None) -> Row:
    d, h, q, owner = row
    owner = owner if pick is None else owner[pick]
    return _take(d, pick), _take(h, pick), _take(q, pick), ch.row_ids(owner)


def _mapped_raw(raw: tuple, ch: Chunk, pick: np.ndarray | None) -> tuple:
    f, c, gr, dd, owner, slots, flag = raw
    if pick is not None:
        f, c, gr, dd = (_take(x, pick) for x in (f, c, gr, dd))
        owner, slots = owner[pick], slots[pick]
    return f, c, gr, dd, ch.row_ids(owner), ch.slots(slots), flag


def widest(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The larger of two per-column error bounds (of different lengths: the longer's tail)."""
    if len(a) < len(b):
        a, b = b, a
    out = a.copy()
    out[: len(b)] = np.maximum(out[: len(b)], b)
    return out
