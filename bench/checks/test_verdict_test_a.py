"""Verdicts that take whole solves of Test A (50 RX90 rows) or of six 6-DOF campaigns: too
heavy for `make test`. The suite keeps, in tests/strategy/test_verdict.py, a moved coordinate
never called consistent and proven inconsistent on small drawn robots, and exact Test A
below its smallest bound ending in the solve's own LPs; in
tests/strategy/test_verdict_orientation.py, one simulated 6-DOF campaign certified
consistent and one draw of each fault."""

from __future__ import annotations

import csv
import random

from calib_dsl.pipeline import min_error
from tests.strategy.test_verdict import ROOT, assert_said, exact_test_a, verdict_of
from tests.strategy.test_verdict_orientation import certified_with_truth


def test_the_issues_repro_a_moved_coordinate_of_test_a(tmp_path):
    """Test A (50 rows) with one coordinate of one row moved by 6 mm: proven inconsistent,
    that row named."""
    rows = list(csv.reader((ROOT / "models" / "data" / "rx90_50.csv").open(encoding="utf-8")))
    rows[11][7] = repr(float(rows[11][7]) + 0.006)  # data row 11's a1y
    data = tmp_path / "moved.csv"
    with data.open("w", newline="", encoding="utf-8") as f:
        csv.writer(f).writerows(rows)
    code, out, text, err = verdict_of(ROOT / "models" / "rx90_lengths.cal", "--data", str(data),
                                      out=tmp_path / "r.json")
    assert_said(code, out, text, err)
    assert out["verdict"] == "inconsistent" and out["status"] == "infeasible"
    # the solve's own LPs prove it (their relaxation is empty), and the conflict names the row
    # (before the relaxation's emptiness was certified, the effort's proof against it did)
    assert [r["row"] for r in out["conflict"]["rows"]] == [11]
    assert out["conflict"]["rest_consistent"] and "(data row 11" in text


def test_exact_test_a_below_its_smallest_bound_is_proven_inconsistent(tmp_path):
    """The issue's RX90 case: Test A with exact joints and every coordinate within +- e, at 3 %
    below its smallest consistent e (the bracket's upper end). It ended undecided: the LPs
    found their relaxation empty, which was not certified (lp/bounds.py `_farkas` now is)."""
    model = exact_test_a(tmp_path, "a1x, a1y, a1z, a2x, a2y, a2z, a3x, a3y, a3z", 1e-4)
    found = min_error(model, "e")
    assert found.lo is not None and found.hi / found.lo <= 1.02, (found.lo, found.hi)
    code, out, text, err = verdict_of(model, "-D", f"e={0.97 * found.hi!r}",
                                      out=tmp_path / "r.json")
    assert_said(code, out, text, err)
    assert out["verdict"] == "inconsistent"


def test_simulated_six_dof_campaigns_are_certified_consistent(tmp_path):
    draw = random.Random(4405)
    verdicts = [certified_with_truth(tmp_path / f"c{i}", draw, 24) for i in range(6)]
    assert verdicts == ["consistent"] * len(verdicts)
