"""The fits' evaluations (analysis/lsq.py): the residuals alone are the same bits as with
the Jacobian, in one piece and in chunks of rows; a fit evaluates no point twice."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import calib_dsl.analysis.lsq as lsq
import calib_dsl.relax.chunked as chunked
from calib_dsl.pipeline import load
from calib_dsl.relax.layout import independents

ROOT = Path(__file__).resolve().parents[2]
MODELS = ("ur10_simulated.cal", "rx90_full.cal")
_PROGS: dict[str, object] = {}


def _prog(name: str):  # type: ignore[no-untyped-def]
    if name not in _PROGS:
        _PROGS[name] = load(ROOT / "models" / name)
    return _PROGS[name]


def _point(prog, shares: list[float]) -> np.ndarray:  # type: ignore[no-untyped-def]
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    lo, hi = np.where(np.isfinite(lo), lo, -10.0), np.where(np.isfinite(hi), hi, 10.0)
    s = np.resize(np.array(shares), len(ind))
    return lo + s * (hi - lo)


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("chunked_rows", [False, True])
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(shares=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=8))
def test_the_residuals_alone_are_the_same_bits(monkeypatch: pytest.MonkeyPatch, name: str,
                                               chunked_rows: bool, shares: list[float]) -> None:
    prog = _prog(name)
    if chunked_rows:  # (chunks of three rows, where a loop is compiled once)
        rows = getattr(prog, "rows", None)
        small = 1 if rows is None else rows.shared + 3 * rows.width
        monkeypatch.setattr(chunked, "CHUNK_SLOTS", small)
    p = _point(prog, shares)
    full = lsq.linearized(prog, p, owners=False)
    alone = lsq.linearized(prog, p, owners=False, jacobian=False)
    assert alone.jac.shape == (len(full.d), 0)
    for a, b in ((full.d, alone.d), (full.half, alone.half), (full.r_lo, alone.r_lo),
                 (full.r_hi, alone.r_hi), (full.dq, alone.dq)):
        assert np.array_equal(a, b, equal_nan=True)
    assert np.array_equal(full.slots, alone.slots)


@pytest.mark.parametrize("name", MODELS)
def test_a_fit_evaluates_no_point_twice(monkeypatch: pytest.MonkeyPatch, name: str) -> None:
    prog = _prog(name)
    seen: list[tuple[bytes, int]] = []
    plain = lsq.residuals

    def counted(prog, p, rows=None):  # type: ignore[no-untyped-def]
        seen.append((p.tobytes(), -1 if rows is None else len(rows)))
        return plain(prog, p, rows)

    monkeypatch.setattr(lsq, "residuals", counted)
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    fit = lsq.estimate(prog, start=np.where(np.isfinite(lo) & np.isfinite(hi),
                                            0.5 * (lo + hi), np.clip(0.0, lo, hi)))
    assert np.all(np.isfinite(fit.values))
    assert len(seen) == len(set(seen))
    monkeypatch.setattr(lsq, "residuals", plain)
    # and the estimate is the one every evaluation anew gives (the cache changes no bit)
    again = lsq.estimate(prog, start=np.where(np.isfinite(lo) & np.isfinite(hi),
                                              0.5 * (lo + hi), np.clip(0.0, lo, hi)))
    assert np.array_equal(fit.values, again.values) and fit.rms == again.rms
