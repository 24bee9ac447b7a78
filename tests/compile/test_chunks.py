"""compile/chunks.py: a loop's rows in chunks of even sizes, each row in one chunk."""

from __future__ import annotations

import numpy as np
import pytest

import calib_dsl.compile.chunks as chunks_module
from calib_dsl.compile.chunks import chunked
from calib_dsl.relax.chunked import evaluation
from calib_dsl.relax.layout import independents
from tests.relax.test_chunked import _rows, chunk_slots, same
from tests.relax.test_linearize import clean_version, robot_source, simulate_cal


def _program(tmp_path, rows: int):
    rng = np.random.default_rng(3)
    source = robot_source(rng, 2, 1e-6, 1e-4, spatial=True)
    prog = simulate_cal(tmp_path, source, clean_version(source), rows, 3, "matrix").prog
    assert prog.rows is not None
    return prog


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_chunks_are_as_many_as_the_largest_size_needs_and_even(tmp_path, monkeypatch,
                                                               threads):
    prog = _program(tmp_path, 9)
    lay = prog.rows
    monkeypatch.setattr(chunks_module, "THREADS", threads)
    for most in range(1, 10):
        chunks = chunked(prog, lay.shared + most * lay.width)
        if most >= 9:  # (the whole program fits: no chunks)
            assert chunks is None
            continue
        assert chunks is not None
        # as few chunks as the size allows, rounded up to a multiple of the threads
        least = -(-9 // most)
        count = min(-(-least // threads) * threads, 9) if least > 1 else 1
        assert len(chunks) == count
        sizes = [len(ch.rows) for ch in chunks]
        real = [ch.real for ch in chunks]
        assert max(sizes) <= most and len(set(sizes)) == 1
        assert max(real) - min(real) <= 1  # (a short chunk costs a full one)
        got = np.concatenate([ch.rows[:ch.real] for ch in chunks])
        assert np.array_equal(got, np.arange(9))


def test_even_chunks_give_the_whole_programs_rows(tmp_path, monkeypatch):
    # 9 rows at 4 a chunk: three chunks of 3 (were 4, 4 and 1 padded to 4)
    prog = _program(tmp_path, 9)
    lay = prog.rows
    ind = independents(prog)
    lo, hi = prog.slots.lo, prog.slots.hi
    center = 0.5 * (lo[ind] + hi[ind])
    small = lay.shared + 4 * lay.width
    monkeypatch.setattr(chunks_module, "THREADS", 1)
    assert [len(ch.rows) for ch in chunked(prog, small)] == [3, 3, 3]
    monkeypatch.setattr(chunks_module, "THREADS", 2)
    assert [ch.real for ch in chunked(prog, small)] == [2, 2, 2, 3]
    with chunk_slots(10**9):
        whole = evaluation(prog, lo, hi, center, mixed=True, owners=True)
    with chunk_slots(small):
        parts = evaluation(prog, lo, hi, center, mixed=True, owners=True)
    same(_rows(whole, whole.run()), _rows(parts, parts.run()))
