"""Beyond D-optimality: the criterion only a set-membership tool can evaluate, the widths of
the linearized feasible set at the error bound.

For a set S of configurations, the feasible set to first order is the polytope
{u : |A_S u + noise| <= 1} within the domains (linear.py's units); its hull along each
unknown is two LPs (lp/hull.py, as the yardstick's). Without noise the polytope holds every
noisy one's half-difference ((P_e - P_e) / 2 lies in P_0, P_e being convex and P_-e = -P_e),
so its widths bound the widths any noise gives: the criterion is the guaranteed enclosure
in the worst case, to first order. The score is the mean log of width over domain (the log
of the box's volume, relative to the domains'); lower is better.

The exchange is guided by the LPs themselves: a member whose rows carry the least multiplier
(the hull rests least on it) leaves for the candidate whose rows the hull's extreme points
violate most (that would cut it most); a swap is kept when the score falls.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.lp.hull import Hull, linear_hull
from calib_dsl.settings import Settings


@dataclass(frozen=True)
class Refinement:
    """How the local search went: the score before and after, LPs hulls made, swaps kept."""

    chosen: np.ndarray
    start: float
    score: float
    hulls: int
    swaps: int


def rows_of(blocks: np.ndarray, chosen: np.ndarray, given: np.ndarray | None) -> np.ndarray:
    a = blocks[np.asarray(chosen, dtype=int)].reshape(-1, blocks.shape[2])
    return a if given is None or not len(given) else np.vstack([a, given])


def hull_of(rows: np.ndarray, box: tuple[np.ndarray, np.ndarray],
            noise: np.ndarray | None = None) -> Hull:
    """The hull of {u : -1 <= rows u + noise <= 1} within the box (noise in bound units)."""
    shift = np.zeros(len(rows)) if noise is None else noise
    return linear_hull(rows, -1.0 - shift, 1.0 - shift, box[0], box[1])


def score(hull: Hull, box: tuple[np.ndarray, np.ndarray]) -> float:
    """Mean log of width over domain (floored at a millionth of the domain: a width of 0
    would be -inf, and one unknown would outweigh the others)."""
    ratio = (hull.hi - hull.lo) / (box[1] - box[0])
    return float(np.mean(np.log(np.maximum(ratio, 1e-6))))


def refine(blocks: np.ndarray, chosen: np.ndarray, box: tuple[np.ndarray, np.ndarray],
           tries: int, budget: int, given: np.ndarray | None = None,
           improvement: float = Settings.plan_improvement) -> Refinement:
    """Swap members for candidates while the score falls: each round tries the `tries`
    members the hull rests least on against the `tries` candidates that would cut it most,
    keeping the first swap that helps; it stops when a round finds none, or after
    `budget` hulls (a count, not a time: the same inputs give the same plan). A swap helps
    when it lowers the score by `improvement`."""
    chosen = np.array(chosen, dtype=int)
    r = blocks.shape[1]
    hull = hull_of(rows_of(blocks, chosen, given), box)
    first = best = score(hull, box)
    hulls, swaps = 1, 0
    while hulls < budget:
        rests = hull.weight[: len(chosen) * r].reshape(len(chosen), r).sum(axis=1)
        leave = np.argsort(rests, kind="stable")[:tries]
        cut = _cuts(blocks, hull.points)
        cut[chosen] = -np.inf
        join = [int(c) for c in np.argsort(-cut, kind="stable")[:tries] if cut[c] > 0]
        found = False
        for i in leave:
            for c in join:
                if hulls >= budget:
                    break
                trial = chosen.copy()
                trial[i] = c
                h = hull_of(rows_of(blocks, trial, given), box)
                hulls += 1
                s = score(h, box)
                if s < best - improvement:
                    chosen, hull, best, found = trial, h, s, True
                    swaps += 1
                    break
            if found or hulls >= budget:
                break
        if not found:
            break
    return Refinement(chosen, first, best, hulls, swaps)


def _cuts(blocks: np.ndarray, points: np.ndarray) -> np.ndarray:
    """How much each candidate's rows would cut the hull: over its extreme points, the
    excess of each row's |A u| over 1 (the worst row of the candidate at each point)."""
    v = np.abs(np.einsum("crn,kn->crk", blocks, points, optimize=True)).max(axis=1)
    return np.maximum(v - 1.0, 0.0).sum(axis=1)

