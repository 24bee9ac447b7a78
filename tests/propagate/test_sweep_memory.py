"""The propagator's sweeps keep no copy of the box: where a fast step would empty a domain it
is undone and the sweep goes on in the general steps from there. The result is the general
sweeps', bit for bit (bounds, sweeps, stop, and the primitive named where the data are
inconsistent), on random programs and boxes, consistent or not; and a sweep allocates far
less than one box-sized array on top of the box it contracts."""

from __future__ import annotations

import tracemalloc

import numpy as np
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from calib_dsl.ir.program import Program
from calib_dsl.ir.status import Status, Stop
from calib_dsl.propagate.diagnose import sweep_from
from calib_dsl.propagate.fixpoint import _contraction, _watched, propagate
from calib_dsl.propagate.kernels import sweep
from calib_dsl.relax.layout import independents
from tests.propagate.test_soundness_propagation import (
    BOXES,
    make_model,
    quiet,
)
from tests.relax.test_linearize import random_robot, robot_draws


def general_propagate(prog: Program, tol: float, max_sweeps: int, lo: np.ndarray,
                      hi: np.ndarray) -> tuple:
    """The propagator's definition: whole general sweeps, each from a saved copy of the box,
    the failing one replayed from that copy to name the primitive."""
    box = [lo.copy(), hi.copy()]
    watch = _watched(prog)
    sweeps, stop = 0, Stop.MAX_SWEEPS
    while sweeps < max_sweeps:
        before = (box[0][watch].copy(), box[1][watch].copy())
        saved = (box[0].copy(), box[1].copy())
        sweeps += 1
        sweep(prog.groups, box[0], box[1])
        if np.any(box[0] > box[1]):
            return Status.INFEASIBLE, box, sweeps, Stop.EMPTY, sweep_from(prog, *saved, 0)
        gain = _contraction(before, (box[0][watch], box[1][watch]))
        if gain == 0.0:
            stop = Stop.FIXED_POINT
            break
        if gain < tol:
            stop = Stop.TOLERANCE
            break
    return Status.CONTRACTED, box, sweeps, stop, None


def assert_same_as_general(prog: Program, tol: float, max_sweeps: int, lo: np.ndarray,
                           hi: np.ndarray) -> Status:
    status, box, sweeps, stop, emptied = quiet(general_propagate, prog, tol, max_sweeps,
                                               lo, hi)
    got = quiet(propagate, prog, tol=tol, max_sweeps=max_sweeps, lo=lo, hi=hi)
    assert (got.status, got.sweeps, got.stop) == (status, sweeps, stop)
    assert np.array_equal(got.lo, box[0], equal_nan=True)
    assert np.array_equal(got.hi, box[1], equal_nan=True)
    assert got.emptied == emptied
    event(f"{status}")
    return status


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(**BOXES, tol=st.sampled_from([0.0, 1e-5]), anywhere=st.booleans())
def test_sweeps_equal_the_general_ones(trees, point, widths, relations, box, tol,
                                       anywhere) -> None:
    """Random expression programs, in a box around their solution or anywhere in the
    domains (then often inconsistent: the failing sweep's primitive must be the same)."""
    made = make_model(trees, point, widths, relations)
    if made is None:
        return
    prog, at = made
    lo, hi = prog.slots.lo.copy(), prog.slots.hi.copy()
    for name, slot in zip(prog.slots.declared_names, prog.slots.declared, strict=True):
        if anywhere:  # (real numbers: a box's bound at an infinity holds none)
            a, b = sorted(box.draw(st.floats(max(lo[slot], -20.0), min(hi[slot], 20.0)))
                          for _ in range(2))
        else:
            a = at[name] - box.draw(st.floats(0.0, 1.0))
            b = at[name] + box.draw(st.floats(0.0, 1.0))
        lo[slot], hi[slot] = max(lo[slot], a), min(hi[slot], b)
    assert_same_as_general(prog, tol, 60, lo, hi)


@settings(max_examples=8, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(**robot_draws(st.integers(5, 40)), shift=st.floats(-0.3, 0.3),
       shrink=st.floats(0.0, 0.49))
def test_robot_sweeps_equal_the_general_ones(tmp_path_factory, seed, joints, rows,
                                             formulation, shift, shrink) -> None:
    """Random robots (rotations, products, every row's constraints) in a box cut from their
    domains and moved off the truth by `shift` of its width (inconsistent where it left)."""
    sim = random_robot(tmp_path_factory.mktemp("general"), seed, joints, rows, formulation)
    prog = sim.prog
    lo, hi = prog.slots.lo.copy(), prog.slots.hi.copy()
    ind = np.array(prog.slots.declared, dtype=np.int64)
    width = np.where(np.isfinite(hi[ind] - lo[ind]), hi[ind] - lo[ind], 1.0)
    lo[ind] = np.maximum(lo[ind], lo[ind] + (shrink + shift) * width)
    hi[ind] = np.minimum(hi[ind], hi[ind] - (shrink - shift) * width)
    ok = lo[ind] <= hi[ind]
    lo[ind[~ok]], hi[ind[~ok]] = prog.slots.lo[ind[~ok]], prog.slots.hi[ind[~ok]]
    assert_same_as_general(prog, 1e-9, 40, lo, hi)


def test_a_sweep_allocates_no_copy_of_the_box(tmp_path) -> None:
    """Contracting a robot's box in place (own=True) allocates, at its peak, less than three
    of the box's arrays: what its largest steps' own arrays need (here about two: the
    program has about ten slots for each entry of its largest group), and no saved copy of
    the box (two more)."""
    sim = random_robot(tmp_path, 4, 3, 300, "matrix")  # (planar: many sweeps from this box)
    prog, ind = sim.prog, independents(sim.prog)

    def box() -> tuple[np.ndarray, np.ndarray]:  # each unknown's domain cut around the truth
        lo, hi = prog.slots.lo.copy(), prog.slots.hi.copy()
        width = np.where(np.isfinite(hi[ind] - lo[ind]), hi[ind] - lo[ind], 0.0)
        lo[ind] = np.minimum(lo[ind] + 0.45 * width, sim.p_true)
        hi[ind] = np.maximum(hi[ind] - 0.45 * width, sim.p_true)
        return lo, hi

    quiet(propagate, prog, max_sweeps=2, lo=box()[0], hi=box()[1])  # (its kernels: made once)
    lo, hi = box()
    largest_group = max(len(g.out) for g in prog.groups)
    assert largest_group * 8 * 8 < lo.nbytes
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        res = quiet(propagate, prog, tol=0.0, max_sweeps=30, lo=lo, hi=hi, own=True)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert res.sweeps == 30 and res.lo is lo
    assert peak < 3 * lo.nbytes, (peak, lo.nbytes)
