"""A sweep whose large steps are shared among threads (propagate/kernels.Share) contracts a
box to the same bounds, bit for bit, and in as many sweeps, as one thread's sweeps."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.propagate.fixpoint import propagate
from calib_dsl.propagate.kernels import Share
from calib_dsl.relax.chunked import in_threads
from calib_dsl.relax.layout import independents
from tests.relax.test_linearize import random_robot, robot_draws


def _serial(fn, parts):
    return [fn(p) for p in parts]


@settings(max_examples=10, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(**robot_draws(st.integers(60, 300)), shrink=st.floats(0.0, 0.45),
       threads=st.integers(2, 3))
def test_shared_sweeps_give_the_same_box(tmp_path_factory, seed, joints, rows, formulation,
                                         shrink, threads) -> None:
    sim = random_robot(tmp_path_factory.mktemp("shared"), seed, joints, rows, formulation)
    prog = sim.prog
    ind = independents(prog)
    lo, hi = prog.slots.lo.copy(), prog.slots.hi.copy()
    # a box around the truth, each unknown's domain cut by `shrink` of its width each side
    width = np.where(np.isfinite(hi[ind] - lo[ind]), hi[ind] - lo[ind], 0.0)
    lo[ind] = np.minimum(lo[ind] + shrink * width, sim.p_true)
    hi[ind] = np.maximum(hi[ind] - shrink * width, sim.p_true)
    whole = propagate(prog, tol=1e-9, lo=lo, hi=hi)
    for share in (Share(lambda fn, parts: in_threads(fn, parts, 2), 2, 1),
                  Share(_serial, threads, 1)):
        got = propagate(prog, tol=1e-9, lo=lo, hi=hi, share=share)
        assert got.status == whole.status and got.sweeps == whole.sweeps
        assert np.array_equal(got.lo, whole.lo, equal_nan=True)
        assert np.array_equal(got.hi, whole.hi, equal_nan=True)
    mine = lo.copy(), hi.copy()
    owned = propagate(prog, tol=1e-9, lo=mine[0], hi=mine[1], own=True)
    assert owned.lo is mine[0] and np.array_equal(owned.hi, whole.hi, equal_nan=True)
