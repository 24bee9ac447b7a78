"""A linear relaxation: the rows a relaxation of the program holds over a box, as data
(the relaxations in relax/ make them; the LPs in lp/ bound over them).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from scipy import sparse

# Relative rounding-error budget of a float dot product of length <= 10^6 in round-to-nearest
# (gamma_n = n u / (1 - n u) with u = 2^-53, n <= 10^6, is below 1.2e-10): 1e-9 covers it.
RHS_REL = 1e-9


RHS_ABS = 1e-300


@dataclass
class Rows:
    """A sparse matrix stored by rows (CSR: the same three arrays as scipy's csr_matrix). The
    tight strategy builds its relaxations as these, so that it never imports scipy.sparse
    (a slow import, a noticeable share of a small solve); a scipy CSR matrix is accepted
    wherever a Rows is.
    """

    data: np.ndarray
    indices: np.ndarray
    indptr: np.ndarray
    shape: tuple[int, int]

    @staticmethod
    def join(dense: np.ndarray, rows: np.ndarray, cols: np.ndarray, vals: np.ndarray,
             width: int) -> Rows:
        """[dense | S] where S (m x width) has the entries vals at (rows, cols)."""
        m, k = dense.shape
        r, c = np.nonzero(dense)
        r = np.concatenate([r, rows])
        c = np.concatenate([c, k + cols])
        v = np.concatenate([dense[dense != 0], vals])
        order = np.lexsort((c, r))
        indptr = np.zeros(m + 1, dtype=np.int64)
        np.cumsum(np.bincount(r, minlength=m), out=indptr[1:])
        return Rows(v[order].astype(float), c[order].astype(np.int64), indptr, (m, k + width))

    def take(self, rows: np.ndarray) -> Rows:
        start, stop = self.indptr[rows], self.indptr[rows + 1]
        lengths = stop - start
        at = np.repeat(start - np.cumsum(lengths) + lengths, lengths) + np.arange(lengths.sum())
        indptr = np.zeros(len(rows) + 1, dtype=np.int64)
        np.cumsum(lengths, out=indptr[1:])
        return Rows(self.data[at], self.indices[at], indptr, (len(rows), self.shape[1]))

    def row_nonzeros(self) -> np.ndarray:
        return np.diff(self.indptr)


def transpose_times(A: Any, y: np.ndarray, absolute: bool = False) -> np.ndarray:
    """A^T y for a CSR matrix (Rows or scipy's), or |A|^T y. Only the rows where y is nonzero
    are read (an LP's multipliers are nonzero on its binding rows alone): the other rows'
    terms are zeros, so the sums are the same."""
    nz = np.flatnonzero(y)
    start, stop = A.indptr[nz], A.indptr[nz + 1]
    lengths = stop - start
    at = np.repeat(start - np.cumsum(lengths) + lengths, lengths) + np.arange(lengths.sum())
    data = A.data[at]
    data = np.abs(data) if absolute else data
    return np.bincount(A.indices[at], weights=data * np.repeat(y[nz], lengths),
                       minlength=A.shape[1])


@dataclass
class LinearRelaxation:
    """Valid inequalities b_lo <= A p <= b over the box lo <= p <= hi (in exact arithmetic).

    b_lo is optional (no lower sides); an infinite entry of b or b_lo is no constraint. A row
    bounded on both sides is one LP row, not two: the simplex then works on half the rows.
    """

    A: Rows | sparse.csr_matrix  # (m, n)
    b: np.ndarray  # (m,)
    lo: np.ndarray  # (n,)
    hi: np.ndarray  # (n,)
    main: int = 0  # the first `main` columns are the unknowns; the others nuisance variables
    # for each nuisance column: (configuration id, table column id) of the measured cell whose
    # error it is (ids as in decompose.Slots.cell_row / cell_col)
    cells: np.ndarray | None = None
    b_lo: np.ndarray | None = None
    # How much of the rows' width is the linearization's remainder rather than the data's
    # errors (90th percentile over rows of remainder / (remainder + data)); near 0, the model
    # is linear over the box to within a small part of the errors: relaxing again on a
    # smaller box would give (nearly) the same LP. 1 when unknown.
    remainder_share: float = 1.0
    # How curved the model is over the box: the median over rows of the remainder over the
    # first-order range (linearize); LP rounds stall above about 1/7. 0 when unknown.
    curvature: float = 0.0
    # Which constraint each row relaxes (distinct ids, the same in every relaxation of the
    # same kind, `family`, whichever rows it takes), and how much of its unknown one unit of
    # each main column is (p = center + scale t): with them, multipliers found on one box
    # certify bounds on another (Certificates). None: no reuse.
    keys: np.ndarray | None = None
    scale: np.ndarray | None = None
    family: str = ""
    center: np.ndarray | None = None  # (with scale: p = center + scale t; None: p itself)
    col_keys: np.ndarray | None = None  # which quantity each column is (increasing), likewise
    # How the keys number the rows: relaxations of two families with the same key_space
    # (not "") mean the same constraint by the same key (one's LPs' binding rows are where
    # the other's row generation starts).
    key_space: str = ""
    # Each row's remainder: how much its right-hand sides are widened for what the relaxation
    # drops (the model's higher orders over the box), where known. Multipliers times it are
    # what the remainders cost a bound (Certificates.remainder_cost).
    slack: np.ndarray | None = None
    # the slot each row compares with (its measured or bounded side; -1 for a row that
    # compares with none, as McCormick's), where known: what a row means in any LP over the
    # same constraints (inner/starts.py), and which data row it is of (the working set's
    # relaxed check)
    targets: np.ndarray | None = None

    def one_sided(self) -> tuple[sparse.csr_matrix, np.ndarray]:
        """The same inequalities as A' p <= b' only (finite right-hand sides)."""
        from scipy import sparse

        A0 = sparse.csr_matrix((self.A.data, self.A.indices, self.A.indptr), shape=self.A.shape)
        if self.b_lo is None:
            keep = np.flatnonzero(np.isfinite(self.b))
            return A0[keep], self.b[keep]
        up, dn = np.flatnonzero(np.isfinite(self.b)), np.flatnonzero(np.isfinite(self.b_lo))
        A = sparse.vstack([A0[up], -A0[dn]]).tocsr()
        return A, np.concatenate([self.b[up], -self.b_lo[dn]])
