"""Passes over a program in chunks of rows (compile/chunks.py, relax/chunked.py) give what
one pass over the whole program gives: the same constraint rows (as a set: the order
follows the chunks), the same targets, sources, data rows and cell error bounds."""

from __future__ import annotations

from unittest import mock

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import calib_dsl.compile.chunks as chunks_module
import calib_dsl.relax.chunked as chunked_module
import calib_dsl.relax.taylor as taylor
from calib_dsl.compile.chunks import chunked
from calib_dsl.relax.chunked import evaluation
from calib_dsl.relax.layout import independents
from calib_dsl.relax.linearize import relax
from calib_dsl.relax.taylor import expand
from tests.relax.test_linearize import clean_version, random_robot, robot_source, simulate_cal


def _rows(ev, out) -> dict[int, tuple]:
    """Each constraint row by its target slot (unique in these programs) and what it reads:
    (D, H, Q, owner, data row, sources)."""
    targets = ev.targets()
    sources = np.concatenate([np.pad(s, ((0, 0), (0, 3 - s.shape[1])), constant_values=-1)
                              for s in ev.sources])
    data = ev.data_rows()
    pieces = {}
    k = 0
    for r in out:
        for i in range(len(r[3])):
            pieces[(int(targets[k]), tuple(sources[k].tolist()))] = (
                tuple(np.concatenate([r[0][0][i:i + 1], r[0][1][i:i + 1]]).tolist()),
                tuple(np.concatenate([r[1][0][i].ravel(), r[1][1][i].ravel()]).tolist()),
                tuple(np.concatenate([r[2][0][i].ravel(), r[2][1][i].ravel()]).tolist()),
                int(r[3][i]), int(data[k]))
            k += 1
    assert k == len(targets) == len(data)
    return pieces


def chunk_count(least: int, rows: int) -> int:
    """The chunks compile/chunks.py makes of `rows` rows that need at least `least`: a
    multiple of the threads sharing them."""
    return least if least <= 1 else min(-(-least // chunks_module.THREADS) * chunks_module.THREADS,
                                        rows)


def chunk_slots(n: int):
    """Chunks of about n slots while the block runs (a hypothesis test has no monkeypatch)."""
    return mock.patch.object(chunked_module, "CHUNK_SLOTS", n)


def _box(prog, point: bool):
    """The domains and their centre's independents; with `point`, the box is the centre."""
    ind = independents(prog)
    lo, hi = prog.slots.lo.copy(), prog.slots.hi.copy()
    center = 0.5 * (lo[ind] + hi[ind])
    if point:
        lo[ind], hi[ind] = center, center
    return lo, hi, center


@settings(max_examples=10, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), joints=st.integers(1, 3), rows=st.integers(5, 14),
       formulation=st.sampled_from(["matrix", "rotation"]), point=st.booleans())
def test_chunks_give_the_whole_programs_rows(tmp_path_factory, seed, joints, rows,
                                             formulation, point):
    sim = random_robot(tmp_path_factory.mktemp("chunks"), seed, joints, rows, formulation)
    prog = sim.prog
    if prog.rows is None:  # (a planar arm's shared measured side: unrolled)
        return
    lo, hi, center = _box(prog, point)
    width = prog.rows.width
    small = prog.rows.shared + 2 * width  # two rows a chunk (the last may have one)
    assert len(chunked(prog, small)) == chunk_count((rows + 1) // 2, rows)
    with chunk_slots(10**9):
        whole = evaluation(prog, lo, hi, center, point=point, mixed=not point, owners=True)
    with chunk_slots(small):
        parts = evaluation(prog, lo, hi, center, point=point, mixed=not point, owners=True)
    a, b = _rows(whole, whole.run()), _rows(parts, parts.run())
    same(a, b)
    assert np.array_equal(whole.e, parts.e)


def same(a: dict, b: dict) -> None:
    """The same rows; their floats up to the last bits (matrix products round differently
    on arrays of other sizes: each enclosure is rigorous all the same)."""
    assert a.keys() == b.keys()
    for k in a:
        for x, y in zip(a[k][:3], b[k][:3], strict=True):
            assert np.allclose(x, y, rtol=1e-12, atol=1e-300), k
        assert a[k][3:] == b[k][3:], k


def test_a_relaxation_in_chunks_is_the_same_relaxation(tmp_path, monkeypatch):
    rng = np.random.default_rng(5)
    source = robot_source(rng, 2, 1e-6, 1e-4, spatial=True)
    prog = simulate_cal(tmp_path, source, clean_version(source), 12, 5, "matrix").prog
    assert prog.rows is not None
    lo, hi = prog.slots.lo, prog.slots.hi
    one = relax(prog, lo, hi, max_cell_columns=3000)
    monkeypatch.setattr(chunked_module, "CHUNK_SLOTS", prog.rows.shared + 2 * prog.rows.width)
    two = relax(prog, lo, hi, max_cell_columns=3000)
    assert one is not None and two is not None
    assert one.A.shape == two.A.shape
    key = np.lexsort(np.vstack([one.b, one.b_lo]))
    key2 = np.lexsort(np.vstack([two.b, two.b_lo]))
    assert np.allclose(one.b[key], two.b[key2], rtol=1e-12)
    assert np.allclose(one.b_lo[key], two.b_lo[key2], rtol=1e-12)


def test_a_subset_of_rows(tmp_path):
    """evaluation(rows=...) gives exactly the rows of those configurations, and the shared
    part's once."""
    rng = np.random.default_rng(11)
    source = robot_source(rng, 2, 1e-6, 1e-4, spatial=True)
    prog = simulate_cal(tmp_path, source, clean_version(source), 10, 11, "matrix").prog
    assert prog.rows is not None
    ind = independents(prog)
    lo, hi = prog.slots.lo, prog.slots.hi
    center = 0.5 * (lo[ind] + hi[ind])
    with chunk_slots(10**9):
        whole = evaluation(prog, lo, hi, center, owners=True)
    whole_rows = _rows(whole, whole.run())
    pick = np.array([1, 4, 5, 9])
    with chunk_slots(10**9):
        part = evaluation(prog, lo, hi, center, owners=True, rows=pick)
    part_rows = _rows(part, part.run())
    lay = prog.rows
    ids = {int(r) * len(lay.tables) for r in pick}
    expect = {k: v for k, v in whole_rows.items()
              if v[4] in ids or k[0] < lay.shared}
    same(part_rows, expect)
    assert len(expect) < len(whole_rows)


@settings(max_examples=8, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), joints=st.integers(1, 3), rows=st.integers(5, 12),
       formulation=st.sampled_from(["matrix", "rotation"]))
def test_second_order_models_in_chunks(tmp_path_factory, monkeypatch, seed, joints, rows,
                                       formulation):
    """taylor.expand in chunks of two rows gives every row's model of the whole expansion
    (matched by target slot), and a subset of rows gives those rows' models."""
    prog = random_robot(tmp_path_factory.mktemp("taylor"), seed, joints, rows,
                        formulation).prog
    if prog.rows is None:
        return
    lo, hi = prog.slots.lo, prog.slots.hi
    whole = expand(prog, lo, hi)
    assert whole is not None
    monkeypatch.setattr(taylor, "CHUNK_SLOTS", prog.rows.shared + 2 * prog.rows.width)
    parts = expand(prog, lo, hi)
    pick = np.array([0, rows - 1])
    some = expand(prog, lo, hi, rows=pick)
    assert parts is not None and some is not None
    by_slot = {int(s): k for k, s in enumerate(whole.rows.slots)}
    assert len(by_slot) == len(whole.rows.slots)  # (one row per target here)
    for ex in (parts, some):
        for k, s in enumerate(ex.rows.slots.tolist()):
            w = by_slot[s]
            for a in ("c0", "c1", "c2", "r"):
                x, y = getattr(ex.rows.models, a)[k], getattr(whole.rows.models, a)[w]
                assert np.allclose(x, y, rtol=1e-12, atol=1e-300), (a, s)
            assert ex.rows.lo[k] == whole.rows.lo[w] and ex.rows.hi[k] == whole.rows.hi[w]
    assert sorted(parts.rows.slots.tolist()) == sorted(whole.rows.slots.tolist())
    lay = prog.rows
    owned = (whole.rows.slots - lay.shared) // lay.width
    expect = whole.rows.slots[(whole.rows.slots < lay.shared) | np.isin(owned, pick)]
    assert sorted(some.rows.slots.tolist()) == sorted(expect.tolist())


@settings(max_examples=6, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), rows=st.integers(5, 14), point=st.booleans())
def test_chunks_shared_among_threads_give_one_threads_rows_in_its_order(tmp_path_factory, seed,
                                                                       rows, point):
    """The chunks shared among threads give what one thread gives, bit for bit and in the
    same order (the rows joined in the chunks' order, not as the threads finish)."""
    sim = random_robot(tmp_path_factory.mktemp("threads"), seed, 2, rows, "matrix")
    prog = sim.prog
    if prog.rows is None:
        return
    lo, hi, center = _box(prog, point)
    runs = []
    for threads in (1, 3):
        with chunk_slots(prog.rows.shared + prog.rows.width), \
                mock.patch.object(chunked_module, "CHUNK_THREADS", threads):
            ev = evaluation(prog, lo, hi, center, point=point, mixed=not point, owners=True)
            runs.append((ev, ev.run()))
    (one, out1), (many, out3) = runs
    assert len(out1) == len(out3) > 1
    for r1, r3 in zip(out1, out3, strict=True):
        for x1, x3 in zip(r1, r3, strict=True):
            for a, b in zip(*(x if isinstance(x, tuple) else (x,) for x in (x1, x3)),
                            strict=True):
                assert np.array_equal(a, b, equal_nan=True)
    assert np.array_equal(one.targets(), many.targets())
    assert np.array_equal(one.data_rows(), many.data_rows())
    assert np.array_equal(one.e, many.e)


def test_malloc_arenas_are_capped_on_glibc_only_when_asked():
    import sys

    from calib_dsl.relax.chunked import _cap_arenas

    assert not _cap_arenas(0)  # (0: glibc's default kept)
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            glibc = hasattr(ctypes.CDLL("libc.so.6"), "mallopt")
        except OSError:
            glibc = False
        assert _cap_arenas(8) == glibc  # (glibc accepts the cap: mallopt returns 1)


def test_alone_runs_the_items_on_the_calling_thread_and_then_shares_them_again():
    import threading

    from calib_dsl.relax.chunked import alone, in_threads

    def where(_: int) -> int:
        return threading.get_ident()

    me = threading.get_ident()
    with alone():
        assert set(in_threads(where, list(range(8)), threads=2)) == {me}
    assert len(set(in_threads(where, list(range(8)), threads=2))) == 2
