"""The classical start: a D-optimal design, greedy then improved by exchanges (Fedorov's),
then exchanges for the unknowns one by one.

The information of a set S of configurations is M = prior + sum over S of A_c' A_c, with
A_c the configuration's rows in domain and bound units (linear.py). D-optimality maximizes
log det M: the volume of the least-squares confidence ellipsoid, shrunk. The prior is the
domain itself as information (`ridge` times the identity in domain units): it makes M
invertible before 23 unknowns have 23 rows, and it leaves out of the count what the
domains already say. With rows of several configurations (r rows each), adding c changes
log det M by log det(I_r + A_c M^-1 A_c') (the determinant lemma), for every candidate at
once.

D-optimality shrinks the ellipsoid's volume, which a design can do by shrinking some axes
and leaving some unknowns wide; the widths a calibration reports are the ellipsoid's
shadows on each unknown, sqrt((M^-1)_kk). `marginal_exchange` then swaps members while the
sum of log (M^-1)_kk falls (an A-optimality on the logs: each unknown's width relative to
its domain counts alike), each candidate's change given by the Woodbury identity.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def information(blocks: np.ndarray, chosen: np.ndarray | list[int], ridge: float,
                given: np.ndarray | None = None) -> np.ndarray:
    """M = ridge I + the chosen (and the `given` rows') A' A."""
    n = blocks.shape[2]
    m = ridge * np.eye(n)
    a = blocks[np.asarray(chosen, dtype=int)].reshape(-1, n)
    m += a.T @ a
    if given is not None and len(given):
        m += given.T @ given
    return m


def gains(blocks: np.ndarray, m: np.ndarray) -> np.ndarray:
    """log det(I + A_c M^-1 A_c') for every candidate c."""
    c, r, n = blocks.shape
    b = (blocks.reshape(c * r, n) @ np.linalg.inv(m)).reshape(c, r, n)
    s = np.matmul(b, blocks.transpose(0, 2, 1))
    sign, logdet = np.linalg.slogdet(np.eye(r)[None] + s)
    return np.where(sign > 0, logdet, -np.inf)


def d_optimal(blocks: np.ndarray, count: int, ridge: float, passes: int, shortlist: int,
              given: np.ndarray | None = None) -> np.ndarray:
    """`count` distinct candidates, greedy, then exchanged for better ones while an
    exchange raises log det M (at most `passes` passes over the set)."""
    total = len(blocks)
    if count > total:
        raise ValueError(f"{count} configurations asked of {total} candidates")
    chosen: list[int] = []
    taken = np.zeros(total, dtype=bool)
    m = information(blocks, [], ridge, given)
    for _ in range(count):
        g = gains(blocks, m)
        g[taken] = -np.inf
        c = int(np.argmax(g))
        chosen.append(c)
        taken[c] = True
        m += blocks[c].T @ blocks[c]
    return exchange(blocks, chosen, m, gains, passes, shortlist)


def log_widths(blocks: np.ndarray, m: np.ndarray) -> np.ndarray:
    """For every candidate c: sum_k log (M + A_c' A_c)^-1_kk."""
    c, r, n = blocks.shape
    inv = np.linalg.inv(m)
    b = (blocks.reshape(c * r, n) @ inv).reshape(c, r, n)
    s = np.eye(r)[None] + np.matmul(b, blocks.transpose(0, 2, 1))
    drop = (b * np.matmul(np.linalg.inv(s), b)).sum(axis=1)
    return np.log(np.maximum(np.diag(inv)[None] - drop, TINY)).sum(axis=1)


def marginal_exchange(blocks: np.ndarray, chosen: np.ndarray, ridge: float, passes: int,
                      shortlist: int, given: np.ndarray | None = None) -> np.ndarray:
    """`chosen`, its members swapped for candidates while the sum of the unknowns' log
    variances falls (at most `passes` passes)."""
    m = information(blocks, chosen, ridge, given)
    return exchange(blocks, [int(c) for c in chosen], m,
                    lambda b, mm: -log_widths(b, mm), passes, shortlist)


def exchange(blocks: np.ndarray, chosen: list[int], m: np.ndarray,
             value: Callable[[np.ndarray, np.ndarray], np.ndarray], passes: int,
             shortlist: int) -> np.ndarray:
    """Each member in turn swapped for the candidate whose `value` (of the information
    with it, higher is better) is highest without the member, while a swap raises it.
    Each pass weighs only the `shortlist` candidates of highest value on the whole set
    (those a member could be worth leaving for), not all of them, for every member."""
    chosen = list(chosen)
    taken = np.zeros(len(blocks), dtype=bool)
    taken[chosen] = True
    for _ in range(passes):
        v = value(blocks, m)
        v[taken] = -np.inf
        short = np.argsort(-v, kind="stable")[:shortlist]
        swapped = False
        for i, c in enumerate(chosen):
            without = m - blocks[c].T @ blocks[c]
            pool = np.concatenate([[c], short[~taken[short]]])
            vals = value(blocks[pool], without)
            best = int(np.argmax(vals))
            if best and vals[best] > vals[0] + EXCHANGE_GAIN:
                new = int(pool[best])
                taken[c], taken[new] = False, True
                chosen[i] = new
                m = without + blocks[new].T @ blocks[new]
                swapped = True
        if not swapped:
            break
    return np.array(chosen)


TINY = 1e-300  # a variance rounded to 0 or below: its log, finite
# an exchange must raise log det M by this much: less is rounding, and would cycle
EXCHANGE_GAIN = 1e-9
