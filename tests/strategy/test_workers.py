"""Calls run in child interpreters (workers.py): results in the calls' order, or None."""

import operator

import numpy as np

from calib_dsl.strategy.workers import Children, map_in_processes


def test_results_come_back_in_the_calls_order():
    calls = [(k, 10 * k) for k in range(7)]  # 7 calls over 3 children: uneven shares
    assert map_in_processes(operator.add, calls, 3) == [11 * k for k in range(7)]


def test_arrays_come_back_bit_for_bit():
    rng = np.random.default_rng(3)
    calls = [(rng.standard_normal(50), rng.standard_normal(50)) for _ in range(4)]
    out = map_in_processes(np.multiply, calls, 2)
    assert out is not None
    for (a, b), got in zip(calls, out, strict=True):
        assert np.array_equal(got, a * b)


def test_a_failing_child_gives_none():
    # the caller then makes the calls itself
    assert map_in_processes(operator.truediv, [(1, 2), (1, 0)], 2) is None


def test_no_interpreter_to_start_gives_none(monkeypatch):
    import sys

    monkeypatch.setattr(sys, "executable", "")
    assert map_in_processes(operator.add, [(1, 2), (3, 4)], 2) is None


def test_what_a_child_prints_does_not_spoil_its_results():
    # print writes to the child's stdout, the pipe its results come back through
    assert map_in_processes(print, [("noise",), ("more noise",)], 2) == [None, None]


def test_children_started_ahead_then_given_their_calls():
    children = Children(2, "operator")
    assert children.map(operator.add, [(1, 2), (3, 4), (5, 6)]) == [3, 7, 11]
    assert children.procs == []  # map stops them
    assert children.map(operator.add, [(1, 2)]) is None  # once only


def test_children_never_given_calls_are_stopped():
    children = Children(2, "numpy")
    procs = list(children.procs)
    assert len(procs) == 2
    children.close()
    assert all(p.poll() is not None for p in procs)


def test_a_child_that_cannot_import_its_module_gives_none():
    assert Children(2, "no_such_module_for_calibc").map(operator.add, [(1, 2), (3, 4)]) is None
