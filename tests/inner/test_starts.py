"""Warm starts keyed by meaning (inner/starts.py): a basis found on one LP read onto another whose
rows and columns are the same quantities in another order, some missing, some new."""

from __future__ import annotations

import numpy as np

from calib_dsl.inner.starts import from_certificates
from calib_dsl.lp.certify import Certificates
from calib_dsl.lp.highs import BASIC, LOWER
from calib_dsl.relax.relaxation import LinearRelaxation, Rows

UPPER = 2  # HiGHS's kUpper


def _certs() -> Certificates:
    """One first-order LP: 3 rows comparing with slots 40, 10, 30; columns: unknowns (slots
    7, 5), then cells (configuration 2, column 1) and (0, 3)."""
    A = Rows.join(np.ones((3, 2)), np.array([0, 1]), np.array([0, 1]), np.ones(2), 2)
    rel = LinearRelaxation(A, np.ones(3), -np.ones(4), np.ones(4), main=2,
                           cells=np.array([[2, 1], [0, 3]]), b_lo=-np.ones(3),
                           keys=np.arange(3), family="first order",
                           col_keys=np.arange(4), targets=np.array([40, 10, 30]))
    certs = Certificates()
    rows = np.array([UPPER, BASIC, LOWER], np.int8)
    cols = np.array([BASIC, UPPER, LOWER, UPPER], np.int8)
    certs.record(rel, 1, 1.0, np.zeros(3), (rows, cols))
    return certs


def test_statuses_follow_what_rows_and_columns_mean():
    starts = from_certificates(_certs(), np.array([7, 5]))
    assert starts is not None and set(starts.ends) == {(5, 1.0)}
    rows, cols = starts.statuses(5, 1.0, row_slots=np.array([30, 99, 40]),
                                 unknowns=np.array([5, 6, 7]),
                                 cells=np.array([[0, 3], [2, 1], [4, 4]]))
    assert rows.tolist() == [LOWER, BASIC, UPPER]  # slot 99: new, its slack basic
    assert cols.tolist() == [UPPER, LOWER, BASIC, UPPER, LOWER, LOWER]
    assert starts.statuses(5, -1.0, np.array([30]), np.array([5]), np.zeros((0, 2))) is None


def test_a_combination_reads_as_its_pivot():
    """The LP's unknown slot 5 was a combination standing for slot 3 (its pivot)."""
    starts = from_certificates(_certs(), np.array([7, 5]), {5: 3})
    assert starts is not None and set(starts.ends) == {(3, 1.0)}
    _, cols = starts.statuses(3, 1.0, np.array([10]), np.array([3, 7]), np.zeros((0, 2)))
    assert cols.tolist() == [UPPER, BASIC]


def test_second_order_bases_are_not_starts():
    certs = _certs()
    certs.family = "second order"
    assert from_certificates(certs, np.array([7, 5])) is None
