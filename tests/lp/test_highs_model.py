"""The HiGHS models lp/highs.py loads: one thread each (ours run one a thread already) and
no Python callback (HiGHS copies it at every run's start under the interpreter's lock)."""

from __future__ import annotations

from unittest import mock

import numpy as np

from calib_dsl.lp import highs as lp_highs
from calib_dsl.lp.highs import load, optimal
from calib_dsl.relax.relaxation import LinearRelaxation, Rows


def _rel() -> LinearRelaxation:
    # max x + y subject to x + y <= 1 over [0, 1]^2
    rows = Rows(np.array([1.0, 1.0]), np.array([0, 1]), np.array([0, 2]), (1, 2))
    return LinearRelaxation(rows, np.array([1.0]), np.zeros(2), np.ones(2), 2)


def _threads(h) -> int:
    got = h.getOptionValue("threads")  # ((status, value) in some highspy versions)
    return got[1] if isinstance(got, tuple) else got


def test_a_model_runs_on_one_thread_with_callbacks_off_and_solves():
    made = []
    real = lp_highs._new_highs

    def spied():
        h = real()
        made.append(h)
        h.disableCallbacks = mock.Mock(wraps=h.disableCallbacks)
        return h

    with mock.patch.object(lp_highs, "_new_highs", spied):
        h = load(_rel())
    assert made and made[0].disableCallbacks.call_count == 1
    assert _threads(h) == 1
    h.changeColsCost(2, np.arange(2, dtype=np.int32), np.array([-1.0, -1.0]))
    h.run()
    assert optimal(h) and abs(h.getInfo().objective_function_value + 1.0) < 1e-9


def test_a_highspy_without_disable_callbacks_still_loads():
    real = lp_highs._new_highs

    class Older:  # (highspy's model without the method)
        def __init__(self) -> None:
            self.h = real()

        def __getattr__(self, name: str):
            if name == "disableCallbacks":
                raise AttributeError(name)
            return getattr(self.h, name)

    with mock.patch.object(lp_highs, "_new_highs", Older):
        h = load(_rel())
    assert _threads(h) == 1


def test_a_kept_basis_restarts_its_lp_where_it_ended_and_a_refused_one_is_taken_as_alien():
    from calib_dsl.accuracy.corrections import kept_basis, restart

    h = load(_rel())
    h.changeColsCost(2, np.arange(2, dtype=np.int32), np.array([-1.0, -2.0]))
    h.run()
    basis = kept_basis(h)
    assert basis is not None
    other = load(_rel())  # (a model of the same rows and columns, as the corrections' are)
    other.changeColsCost(2, np.arange(2, dtype=np.int32), np.array([-1.0, -2.0]))
    restart(other, basis)
    other.run()
    assert optimal(other) and other.getInfo().simplex_iteration_count == 0
    assert not basis.alien  # (set as it is: no completion)
    wide = load(_rel())
    wide.addCol(0.0, 0.0, 1.0, 0, np.zeros(0, dtype=np.int32), np.zeros(0))
    restart(wide, basis)  # (a column short: HiGHS refuses it as it is)
    assert basis.alien
    wide.run()
    assert optimal(wide)
