"""Column units and row selection: conversion factors enclose the exact ratio, converted cells
enclose the exact product, and a row selection is exactly what it says or an error."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from calib_dsl.elaborate import rows, units

PI = units.PI_60  # pi to 60 digits (the factor covers the rest)


def exact(unit: str) -> Fraction:
    return units.LENGTHS.get(unit) or units.ANGLES.get(unit) or PI / 180


@pytest.mark.parametrize("unit,model", [(u, m) for dim in (units.LENGTHS, units.ANGLES)
                                        for u in dim for m in dim]
                         + [("deg", "rad"), ("deg", "mrad"), ("rad", "deg"), ("mrad", "deg")])
def test_factor_encloses_the_exact_ratio_tightly(unit, model):
    lo, hi = units.factor(unit, model)
    if "deg" in (unit, model):  # pi is known to 1e-59: the ratio lies in a 1-2 ulp box
        ratio = exact(unit) / exact(model)
        assert Fraction(lo) <= ratio <= Fraction(hi)
        assert hi <= np.nextafter(np.nextafter(lo, np.inf), np.inf)
        return
    ratio = exact(unit) / exact(model)
    assert Fraction(lo) <= ratio <= Fraction(hi)
    if Fraction(float(ratio)) == ratio:
        assert lo == hi == float(ratio)  # exact ratios stay points
    else:
        assert hi == np.nextafter(lo, np.inf)  # the two floats around it


@given(st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=1, max_size=20),
       st.sampled_from(["mm", "um", "cm", "deg", "mrad"]))
def test_converted_cells_enclose_the_exact_product(values, unit):
    model = "m" if unit in units.LENGTHS else "rad"
    v = np.array(values)
    lo, hi = units.convert(v, v, units.factor(unit, model))
    for x, a, b in zip(values, lo.tolist(), hi.tolist(), strict=True):
        truth = Fraction(x) * exact(unit) / exact(model)
        assert Fraction(a) <= truth <= Fraction(b), (x, a, b)


def test_row_ranges_parse_and_select():
    sel = rows.Selection(rows.parse_ranges("1..40:15"))
    assert rows.select(sel, 40).tolist() == [0, 15, 30]
    assert rows.select(rows.Selection(rows.parse_ranges("38..")), 40).tolist() == [37, 38, 39]
    assert rows.select(rows.Selection(rows.parse_ranges("..2, 5")), 9).tolist() == [0, 1, 4]
    assert rows.select(rows.Selection((), (2, 3)), 4).tolist() == [0, 3]
    both = rows.Selection(rows.parse_ranges("1..10:3"), (4,))
    assert rows.select(both, 10).tolist() == [0, 6, 9]


@given(st.integers(1, 60), st.integers(1, 60), st.integers(1, 9), st.integers(1, 80))
def test_selection_is_the_arithmetic_progression(first, length, step, n):
    last = first + length - 1
    sel = rows.Selection(rows.parse_ranges(f"{first}..{last}:{step}"))
    if last > n:
        with pytest.raises(ValueError, match="past the end"):
            rows.select(sel, n)
        return
    assert rows.select(sel, n).tolist() == [k - 1 for k in range(first, last + 1, step)]


@pytest.mark.parametrize("text,message", [
    ("0..5", "numbered from 1"), ("5..2", "empty"), ("1..5:0", "1 or more"),
    ("a..b", "not a row range"), ("", "not a row range"), ("1...5", "not a row range")])
def test_bad_ranges_say_what_is_wrong(text, message):
    with pytest.raises(ValueError, match=message):
        rows.parse_ranges(text)


def test_selection_outside_the_table_is_an_error():
    with pytest.raises(ValueError, match="past the end"):
        rows.select(rows.Selection(rows.parse_ranges("1..1496")), 1495)
    with pytest.raises(ValueError, match="excluded but the table has rows 1..5"):
        rows.select(rows.Selection((), (6,)), 5)
    with pytest.raises(ValueError, match="leaves no row"):
        rows.select(rows.Selection(rows.parse_ranges("2"), (2,)), 5)
