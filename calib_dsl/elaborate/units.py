"""Units of table columns, and their conversion to the model's units with outward rounding.

A column read in `mm` into a model whose lengths are in `m` is multiplied by 1/1000, which
no float holds exactly: each factor is an interval of two floats around the exact ratio,
and every converted cell is the interval product of its exact decimal enclosure with it,
rounded outward. Angles convert through pi/180 (deg) the same way.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from calib_dsl.arith import interval as iv
from calib_dsl.arith.exact import enclose_fraction

# the exact size of each unit in its dimension's base unit (m, rad); pi is handled apart
LENGTHS = {"m": Fraction(1), "mm": Fraction(1, 1000), "um": Fraction(1, 10**6),
           "cm": Fraction(1, 100)}
ANGLES = {"rad": Fraction(1), "mrad": Fraction(1, 1000), "urad": Fraction(1, 10**6)}
DEGREE = "deg"  # pi/180 rad: not a rational multiple of the radian
UNITS = (*LENGTHS, *ANGLES, DEGREE)

# pi to 60 digits: its float neighbours are found from it exactly
PI_60 = Fraction("3.141592653589793238462643383279502884197169399375105820974944")
PI_60_ERR = Fraction(1, 10**59)


def dimension(unit: str) -> str:
    return "length" if unit in LENGTHS else "angle"


def factor(unit: str, model_unit: str) -> tuple[float, float]:
    """[lo, hi] floats around the exact factor from `unit` to `model_unit` (same dimension)."""
    if unit == model_unit:
        return 1.0, 1.0
    if dimension(unit) == "length":
        return _enclose(LENGTHS[unit] / LENGTHS[model_unit], Fraction(0))
    size = {**{k: (v, Fraction(0)) for k, v in ANGLES.items()},
            DEGREE: (PI_60 / 180, PI_60_ERR / 180)}
    (a, ea), (b, eb) = size[unit], size[model_unit]
    if eb == 0:
        return _enclose(a / b, ea / b)
    # b is inexact (a model in degrees): bound a / b over b's enclosure
    lo, hi = (a - ea) / (b + eb), (a + ea) / (b - eb)
    return _enclose((lo + hi) / 2, (hi - lo) / 2)


def convert(lo: np.ndarray, hi: np.ndarray, f: tuple[float, float]
            ) -> tuple[np.ndarray, np.ndarray]:
    """The cells [lo, hi] times the factor [f0, f1], rounded outward (exact for 1)."""
    if f == (1.0, 1.0):
        return lo, hi
    return iv.mul((lo, hi), (np.full_like(lo, f[0]), np.full_like(lo, f[1])))


def _enclose(q: Fraction, err: Fraction) -> tuple[float, float]:
    """The tightest floats around [q - err, q + err]."""
    return enclose_fraction(q - err)[0], enclose_fraction(q + err)[1]
