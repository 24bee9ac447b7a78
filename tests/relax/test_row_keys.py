"""A second-order relaxation's row keys name each row by its constraint in the whole
program, so that rows joining a working set (strategy/working.py) leave the other rows'
keys as they were: the multipliers and starting rows carried from one pass's LPs to the
next stay on their constraints."""

from __future__ import annotations

import warnings

import numpy as np
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from relax.test_linearize import clean_version, random_box, robot_source, simulate_cal

from calib_dsl.lp.bounds import lp_bounds
from calib_dsl.lp.certify import Certificates, mapped
from calib_dsl.relax.quadratic import relax_quadratic
from calib_dsl.relax.quadratic_readings import relax_quadratic_readings
from calib_dsl.relax.taylor import ids_end


def _by_key(rel) -> dict[int, int]:
    return {int(k): int(t) for k, t in zip(rel.keys, rel.targets, strict=True)}


@settings(max_examples=10, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**31 - 1), rows=st.integers(4, 8), readings=st.booleans(),
       mccormick=st.booleans(), chunk=st.sampled_from([1, 2, 100]))
def test_row_keys_survive_rows_joining(tmp_path_factory, monkeypatch, seed, rows, readings,
                                       mccormick, chunk):
    """Relaxed on every other row and then on all rows (the others joined between them),
    each row of the first relaxation has the same key in the second, for the same
    constraint (target slot) with the same sides; McCormick's rows come after every
    constraint's key; and the rows the first one's LPs bound on are found in the second by
    their keys (Certificates.binding), the same constraints."""
    import calib_dsl.relax.quadratic_readings as qr
    import calib_dsl.relax.taylor as taylor

    rng = np.random.default_rng(seed)
    source = robot_source(rng, 2, 1e-4, 1e-4, True)
    sim = simulate_cal(tmp_path_factory.mktemp("robot"), source, clean_version(source), rows,
                       seed, "matrix")
    prog = sim.prog
    assume(prog.rows is not None)
    small = prog.rows.shared + chunk * prog.rows.width
    monkeypatch.setattr(qr, "CHUNK_SLOTS", small)
    monkeypatch.setattr(taylor, "CHUNK_SLOTS", small)
    lo, hi = random_box(rng, prog, sim.p_true, sim.cell_true, False)
    some, every = np.arange(0, rows, 2), np.arange(rows)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        if readings:
            built = [relax_quadratic_readings(prog, lo, hi, mccormick=mccormick, rows=r)
                     for r in (some, every)]
        else:
            built = [relax_quadratic(prog, lo, hi, prune=0.0, mccormick=mccormick, rows=r)
                     for r in (some, every)]
    assume(all(b is not None for b in built))
    first, second = (b[0] for b in built if b is not None)
    for rel in (first, second):
        assert len(np.unique(rel.keys)) == len(rel.keys)
        assert np.all((rel.keys >= ids_end(prog)) == (rel.targets < 0))
    old, new = _by_key(first), _by_key(second)
    assert set(k for k, t in old.items() if t >= 0) <= set(new)
    assert all(new[k] == t for k, t in old.items() if t >= 0)
    at = {int(k): j for j, k in enumerate(second.keys)}
    for i, k in enumerate(first.keys.tolist()):
        if first.targets[i] >= 0:
            j = at[k]
            assert np.isclose(first.b[i], second.b[j], rtol=1e-12, atol=0)
            assert np.isclose(first.b_lo[i], second.b_lo[j], rtol=1e-12, atol=0)
    # the first relaxation's LPs' binding rows, found in the second by their keys
    certs = Certificates()
    n = first.main
    lp_bounds(first, np.eye(n), certificates=certs)
    objectives = list(certs.y)
    assume(objectives)
    bound = certs.bound_keys(objectives)
    found = certs.binding(second, objectives)
    want = sorted(new[int(k)] for k in bound if int(k) in new)
    got = [] if found is None else sorted(int(t) for t in second.targets[found])
    assert got == want


def test_mapped_reads_unsorted_keys():
    """A relaxation's keys need not increase: each key's value is found all the same (the
    first of a repeated key's)."""
    rng = np.random.default_rng(3)
    old = rng.permutation(40)[:25] * 7
    values = rng.normal(size=25)
    keys = np.concatenate([old[::3], [1, 2, 3 * 7 + 1]])
    got = mapped(old, values, keys, -9.0)
    want = [values[list(old).index(k)] if k in old else -9.0 for k in keys]
    assert np.array_equal(got, np.array(want))
