"""Identifiability analysis and the least-squares estimate beside the guarantee."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from calib_dsl.analysis.identify import analyse, combination_enclosures, format_combination, render
from calib_dsl.analysis.lsq import estimate
from calib_dsl.compile.group import compile_model
from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.propagate.fixpoint import propagate
from calib_dsl.strategy.tight import solve_tight
from calib_dsl.studies.simulate import simulate

MODELS = Path(__file__).resolve().parents[2] / "models"


@pytest.fixture(scope="module")
def full():
    return compile_model(elaborate(MODELS / "rx90_full.cal"))


def test_rx90_only_r2_plus_r3_is_not_identifiable(full) -> None:
    info = analyse(full)
    assert info.rank == 32 and len(info.names) == 33
    assert len(info.groups) == 1
    members, combos = info.groups[0]
    assert sorted(members) == ["r2", "r3"]
    assert len(combos) == 1
    assert format_combination(members, combos[0]) in ("r2 + r3", "r3 + r2")
    assert "r2" not in info.identifiable and "d3" in info.identifiable
    assert "identifiable only through r2 + r3" in render(info)


def test_two_parallel_translations_are_one_combination(tmp_path: Path) -> None:
    """A made-up model in which a and b only ever act through a + b, and c through 2c."""
    csv = tmp_path / "d.csv"
    xs = np.linspace(-1, 1, 7)
    rows = [(float(x), float(0.3 + x * 0.5 + 0.2 * x * x)) for x in xs]
    csv.write_text("x,y\n" + "".join(f"{x!r},{y!r}\n" for x, y in rows))
    model = tmp_path / "m.cal"
    model.write_text(
        'param a in [0, 1] true 0.1;\nparam b in [0, 1] true 0.2;\n'
        'param c in [0, 1] true 0.25;\nparam e in [0, 1] true 0.2;\n'
        'table m = "d.csv" { x : +- 0; y : +- 1e-6; }\n'
        'for k in 1..rows(m) { a + b + 2 * c * m.x[k] + e * sqr(m.x[k]) == m.y[k]; }\n')
    prog = compile_model(elaborate(model))
    info = analyse(prog)
    assert info.rank == 3
    assert [sorted(m) for m, _ in info.groups] == [["a", "b"]]
    assert set(info.identifiable) == {"c", "e"}
    (members, combos), = info.groups
    coef = dict(zip(members, combos[0], strict=True))
    assert coef["a"] == pytest.approx(coef["b"])
    res = propagate(prog, tol=1e-9)
    (text, lo, hi), = combination_enclosures(prog, info, res.lo, res.hi, use_lp=True)
    assert lo <= 0.3 <= hi and hi - lo < 1e-4  # a + b = 0.3 is pinned although a, b are not


def test_least_squares_estimate_inside_the_enclosure(tmp_path: Path) -> None:
    data = tmp_path / "d.csv"
    simulate(MODELS / "rx90_lengths.cal", 20, 7, out_csv=data)
    prog = compile_model(elaborate(MODELS / "rx90_lengths.cal", data=data))
    res = solve_tight(prog)
    s = prog.slots
    slot = dict(zip(s.declared_names, s.declared, strict=True))
    mid = np.array([0.5 * (res.lo[slot[n]] + res.hi[slot[n]]) for n in s.declared_names])
    est = estimate(prog, start=mid)
    assert est.converged
    assert est.rms < 1.0  # normalized residuals: the data fit within their error bounds
    for name, value in zip(est.names, est.values, strict=True):
        if name in ("r2", "r3"):
            continue
        assert res.lo[slot[name]] - 1e-12 <= value <= res.hi[slot[name]] + 1e-12, name
    for name in ("r0", "d3", "b1x"):
        true = prog.true_values[name]
        assert abs(est.values[est.names.index(name)] - true) < 1e-3
