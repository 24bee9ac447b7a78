"""The predictions' certified-point search started beside their LPs (accuracy/ahead.py): the
same boxes, inner intervals and certified points as the search run after them; and the
search's two parts, split, are the whole search's points in its order."""

from __future__ import annotations

import shutil

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.accuracy import predict
from calib_dsl.accuracy.ahead import Ahead
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.pipeline import predict_at
from calib_dsl.settings import DEFAULT
from tests.accuracy.test_certified_predictions import (
    EXAMPLES,
    READING,
    assert_inner_ends,
    table,
    tip,
)

E = 0.02


@settings(max_examples=6, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.floats(0.85, 1.15), st.floats(0.35, 0.65), st.integers(0, 2 ** 31))
def test_the_search_beside_the_lps_finds_what_it_finds_after_them(tmp_path, monkeypatch, l1,
                                                                   l2, seed):
    rng = np.random.default_rng(seed)
    for name in ("planar_arm.cal", "planar_arm_robot.cal"):
        shutil.copy(EXAMPLES / name, tmp_path)
    q = rng.uniform(-np.pi, np.pi, (10, 2))
    x, y = tip(l1, l2, q[:, 0], q[:, 1])
    train = table(tmp_path / "train.csv", q,
                  (x + rng.uniform(-E, E, len(x)), y + rng.uniform(-E, E, len(y))))
    qh = rng.uniform(-np.pi, np.pi, (6, 2))
    truth = np.array(tip(l1, l2, qh[:, 0], qh[:, 1])).T
    held = table(tmp_path / "held.csv", qh, (truth[:, 0], truth[:, 1]))
    inputs = Inputs(data={"m": train}, consts={"e": repr(E)})
    got, started = {}, []

    class Spy(Ahead):
        def points(self, directions: np.ndarray, optima: np.ndarray) -> list:
            started.append(self.started is not None)
            return super().points(directions, optima)

    for early in (False, True):  # (without: the search after the LPs, as before)
        with monkeypatch.context() as m:
            m.setattr(predict, "Ahead", Spy if early else
                      lambda c, o, w, _: Spy(c, o, w, threads=1))
            _, p = predict_at(tmp_path / "planar_arm.cal", held, inputs=inputs,
                              settings=DEFAULT.tuned(workers=2))
        assert p is not None
        assert np.all(p.lo <= truth) and np.all(truth <= p.hi)
        got[early] = p
    assert started == [False, True]  # (the search did start beside the LPs)
    one, two = got[False], got[True]
    for name in ("lo", "hi", "inner_lo", "inner_hi", "inner_points", "inner_readings",
                 "inner_from", "inner_held"):
        np.testing.assert_array_equal(getattr(one, name), getattr(two, name), err_msg=name)
    assert_inner_ends(two, qh, READING)


def _search(directions: np.ndarray, optima: np.ndarray) -> list:
    """A stand-in search: one point per direction (its first part), then one per optimum."""
    return [("near", tuple(d)) for d in directions] + [("far", tuple(o)) for o in optima]


def test_the_split_search_keeps_the_whole_ones_points_and_order():
    order = np.array([2, 0])
    gradient = np.array([[1.0, 2.0], [3.0, 4.0]])
    optima = np.array([[5.0, 6.0]])
    with Ahead(_search, order, 3, threads=2) as ahead:
        ahead.start(gradient)
        ahead.start(gradient + 1)  # (only the first gradients start the search)
        directions = ahead.directions(gradient)
        assert directions.tolist() == [[2.0, 0.0, 1.0], [4.0, 0.0, 3.0]]
        at = ahead.directions(optima)
        assert ahead.points(directions, at) == _search(directions, at)


def test_other_directions_than_those_started_run_the_whole_search():
    calls = []

    def search(directions: np.ndarray, optima: np.ndarray) -> list:
        calls.append((len(directions), len(optima)))
        return _search(directions, optima)

    with Ahead(search, np.arange(2), 2, threads=2) as ahead:
        ahead.start(np.eye(2))
        more = np.vstack([np.eye(2), np.ones((1, 2))])  # a first-order row's direction too
        assert ahead.points(more, np.ones((1, 2))) == _search(more, np.ones((1, 2)))
    assert (3, 1) in calls


def test_one_thread_starts_nothing_early():
    calls = []

    def search(directions: np.ndarray, optima: np.ndarray) -> list:
        calls.append(len(directions))
        return _search(directions, optima)

    with Ahead(search, np.arange(2), 2, threads=1) as ahead:
        ahead.start(np.eye(2))
        assert calls == []
        assert ahead.points(np.eye(2), np.zeros((0, 2))) == _search(np.eye(2),
                                                                    np.zeros((0, 2)))
    assert calls == [2]
    with Ahead(None, np.arange(2), 2, threads=2) as none:
        none.start(np.eye(2))
        assert none.points(np.eye(2), np.zeros((0, 2))) == []
