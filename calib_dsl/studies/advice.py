"""Identifiability advice a user can act on: which parameters the data determine, which only
move with others (and with which), how well conditioned they are, and a subset to calibrate.

The yardstick is the data's own error bounds. Each row of the Jacobian is divided by its
measurement bound and each column multiplied by the parameter's half domain, so a singular
value is how far, in error bounds (root-sum-square over all rows), the measurements move when
the parameters move along that direction to the edge of their domains. A direction that moves
them by less than `seen` of a bound is not seen at all (the rank); one under `well_seen` bound
is seen so faintly that the data cannot pin it down. The analysis is made at the least-squares
estimate of the data (where the robot is, not where its drawing says), else at the middle of
the domains. It is advice, not a guarantee: the solve's enclosures are the guarantee.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.analysis.identify import finite_jacobian
from calib_dsl.analysis.lsq import estimate, residuals
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents
from calib_dsl.settings import Settings


@dataclass(frozen=True)
class Absorbed:
    """Parameters whose effect the kept ones reproduce: `members` move with `by`; `sum` is
    the one combination seen when each member is an exact copy of one kept parameter."""

    members: list[str]
    by: list[str]
    sum: str | None


@dataclass(frozen=True)
class Advice:
    names: list[str]
    point: str  # where the Jacobian was taken
    rows: int  # the Jacobian's rows: one per measured value (a data row has several)
    singular_values: np.ndarray  # in error bounds over the domains, largest first
    rank: int
    condition: float  # of the rank's directions
    absorbed: list[Absorbed]
    faint: dict[str, float]  # parameter: error bounds it adds over its domain, < well_seen
    unseen: list[str]  # parameters that alone move the measurements by less than `seen`
    subset: list[str]
    subset_condition: float
    seen: float  # the settings' `seen`: less moves the measurements by nothing seen


def advise(prog: Program, settings: Settings | None = None) -> Advice:
    st = settings or Settings()
    ind = independents(prog)
    names = [prog.slots.names[i] for i in ind]
    point, where = _point(prog, ind, st)
    with np.errstate(all="ignore"):
        r, jac = residuals(prog, point)
        half = 0.5 * (prog.slots.hi[ind] - prog.slots.lo[ind])
        half = np.where(np.isfinite(half) & (half > 0), half, 1.0)
        # over finite domains, a NaN residual is a row whose value overflowed (its zero row
        # would read as "not seen"); an unbounded domain makes such rows of its own
        bounded = bool(np.all(np.isfinite(prog.slots.lo[ind]) & np.isfinite(prog.slots.hi[ind])))
        overflow = np.isnan(r) & bounded
        js = finite_jacobian(np.where(overflow[:, None], np.nan, jac * half), where)
    s = np.linalg.svd(js, compute_uv=False) if js.size else np.zeros(0)
    rank = int(np.sum(s >= st.seen))
    keep = _subset(js, rank, st)
    unseen = [j for j in range(js.shape[1]) if np.linalg.norm(js[:, j]) < st.seen]
    absorbed, faint = _explain(js, names, keep, unseen, st)
    sub = np.linalg.svd(js[:, keep], compute_uv=False) if keep else np.zeros(1)
    return Advice(names, where, js.shape[0], s, rank, _cond(s[:rank]), absorbed, faint,
                  [names[j] for j in unseen], [names[k] for k in keep], _cond(sub), st.seen)


def _point(prog: Program, ind: np.ndarray, st: Settings) -> tuple[np.ndarray, str]:
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    middle = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), np.clip(0.0, lo, hi))
    est = estimate(prog, start=middle, max_evaluations=st.fits.lsq_evaluations,
                   sampling=st.sampling)
    if est.converged and np.all(np.isfinite(est.values)):
        return est.values, "the least-squares estimate of the data"
    return middle, "the middle of the search domains (least squares did not converge)"


def _cond(s: np.ndarray) -> float:
    return float(s[0] / s[-1]) if len(s) and s[-1] > 0 else float("inf")


def _subset(js: np.ndarray, rank: int, st: Settings) -> list[int]:
    """Gram-Schmidt in the order the parameters are declared: a parameter is kept when it adds
    at least `well_seen` error bounds to what the kept ones already move (so among parameters
    with the same effect, the one declared first is kept: a model declares first what it would
    rather calibrate, the base and the tool before the chain). Then, while the kept set is
    worse conditioned than `subset_cond`, the last declared of the members that lead its
    weakest direction leaves."""
    residual = js.astype(float).copy()
    keep: list[int] = []
    for k in range(js.shape[1]):
        if len(keep) == rank:
            break
        size = float(np.linalg.norm(residual[:, k]))
        if size < st.well_seen:
            continue
        keep.append(k)
        q = residual[:, k] / size
        residual -= np.outer(q, q @ residual)
    while len(keep) > 1:
        _, s, vt = np.linalg.svd(js[:, keep], full_matrices=False)
        if s[-1] > 0 and s[0] / s[-1] <= st.subset_cond:
            break
        lead = np.abs(vt[-1])
        keep.pop(int(np.flatnonzero(lead >= st.leads * lead.max())[-1]))  # the last declared
    return keep


def _explain(js: np.ndarray, names: list[str], keep: list[int], unseen: list[int],
             st: Settings) -> tuple[list[Absorbed], dict[str, float]]:
    """For each parameter left out: the kept ones that reproduce its effect, or how faint
    the effect they cannot reproduce is."""
    groups: dict[tuple[int, ...], list[int]] = {}
    faint: dict[str, float] = {}
    basis = js[:, keep]
    for j in range(js.shape[1]):
        if j in keep or j in unseen:
            continue
        c, *_ = np.linalg.lstsq(basis, js[:, j], rcond=None)
        left = float(np.linalg.norm(js[:, j] - basis @ c))
        if left >= st.seen:
            faint[names[j]] = left
            continue
        big = np.abs(c) >= st.absorbs * np.abs(c).max() if len(c) else np.zeros(0, bool)
        groups.setdefault(tuple(keep[i] for i in np.flatnonzero(big)), []).append(j)
    out = []
    for by, members in groups.items():
        seen = None
        if len(by) == 1:  # each member a copy of one kept parameter: only their sum is seen
            sign = {m: np.sign(js[:, m] @ js[:, by[0]]) for m in members}
            terms = sorted([*members, *by])
            seen = " ".join(("-" if sign.get(i, 1) < 0 else "+") + " " + names[i]
                            for i in terms).removeprefix("+ ")
        out.append(Absorbed([names[m] for m in members], [names[b] for b in by], seen))
    return out, faint


def render(a: Advice) -> str:
    lines = [f"identifiability at {a.point} ({a.rows} measured values): rank {a.rank} of "
             f"{len(a.names)} parameters, condition number {a.condition:.3g}",
             f"  (a direction is seen when moving the parameters along it across their "
             f"domains moves the measurements by at least {a.seen:g} of their error bounds)"]
    for g in a.absorbed:
        verb = "moves" if len(g.members) == 1 else "move"
        line = f"{', '.join(g.members)} {verb} with {', '.join(g.by)}"
        lines.append(line + (f": only {g.sum} is seen" if g.sum else " (absorbed)"))
    if a.unseen:
        lines.append(f"not seen at all: {', '.join(a.unseen)} (alone, less than {a.seen:g} of "
                     "an error bound over the whole domain)")
    if a.faint:
        shown = ", ".join(f"{n} ({v:.2g})" for n, v in a.faint.items())
        lines.append(f"nearly not identifiable: {shown}: error bounds they add to the rest "
                     "over their whole domain")
    lines.append(f"suggested subset ({len(a.subset)} parameters, condition number "
                 f"{a.subset_condition:.3g}): {' '.join(a.subset)}")
    return "\n".join(lines)


def advice_json(a: Advice) -> dict:
    return {
        "point": a.point, "rows": a.rows, "rank": a.rank, "parameters": len(a.names),
        "condition_number": a.condition,
        "singular_values": [float(v) for v in a.singular_values],
        "absorbed": [{"parameters": g.members, "move_with": g.by, "only_seen": g.sum}
                     for g in a.absorbed],
        "nearly_not_identifiable": a.faint, "not_seen": a.unseen,
        "suggested_subset": {"parameters": a.subset, "condition_number": a.subset_condition},
    }
