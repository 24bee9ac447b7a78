"""Identifiability: which parameters the measurements can determine, and which only through
a combination (e.g. two translations along parallel axes: only their sum is seen).

The Jacobian of all constraints w.r.t. the declared unknowns is taken at their nominal (true)
values, each column scaled by its search-domain width (so a direction is weak relative to what
we wanted to learn). Its singular values give the rank; the null space gives the combinations
that no data of this kind can separate.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents
from calib_dsl.relax.linearize import constraint_jacobian
from calib_dsl.settings import Settings


@dataclass
class Identifiability:
    names: list[str]
    rank: int
    singular_values: np.ndarray
    identifiable: list[str]
    # Each non-identifiable group: its parameters, and the combinations that ARE identifiable
    # (coefficient vectors over the group), e.g. (["r2", "r3"], [[1, 1]]).
    groups: list[tuple[list[str], list[np.ndarray]]] = field(default_factory=list)
    weakest: list[tuple[float, dict[str, float]]] = field(default_factory=list)


def analyse(prog: Program, design: bool = False,
            rank_tol: float = Settings.rank_tol) -> Identifiability:
    """The analysis at the nominal values; with `design`, at the middle of each finite search
    domain instead (the geometry the robot was designed with, e.g. alpha3 = 0, where a true
    value may break a symmetry by a hair and leave a direction identifiable in name only).
    `rank_tol`: singular values below it times the largest are structural zeros."""
    ind = independents(prog)
    names = [prog.slots.names[i] for i in ind]
    point = _nominal(prog, ind, names, design)
    with np.errstate(all="ignore"):
        J = constraint_jacobian(prog, point)
        scale = prog.slots.hi[ind] - prog.slots.lo[ind]
        scale = np.where(np.isfinite(scale) & (scale > 0), scale, 1.0)
        Js = finite_jacobian(J * scale, "the nominal values")
    # only V is needed (n x n either way); a full U would be rows x rows
    _, s, vt = np.linalg.svd(Js, full_matrices=Js.shape[0] < Js.shape[1])
    s_full = np.zeros(len(names))
    s_full[: len(s)] = s
    top = s_full.max() if len(s_full) else 0.0
    rank = int(np.sum(s_full > rank_tol * top)) if top > 0 else 0
    null = vt[rank:].T  # (n, n - rank), in scaled coordinates
    touched = np.linalg.norm(null, axis=1) > 1e-6 if null.size else np.zeros(len(names), bool)
    ident = [n for n, t in zip(names, touched, strict=True) if not t]
    groups = _groups(names, null, touched, scale)
    nonzero = [int(k) for k in np.argsort(s_full) if s_full[k] > rank_tol * top][:3]
    weakest = [(float(s_full[k]), _direction(names, vt[k], scale)) for k in nonzero]
    return Identifiability(names, rank, s_full, ident, groups, weakest)


def finite_jacobian(js: np.ndarray, where: str) -> np.ndarray:
    """`js`, or a user error when it is not finite: its SVD would not converge (a row
    undefined there, or numbers near 1e154, whose squares overflow the floats), and no rank
    can be read from it."""
    if not np.all(np.isfinite(js)):
        raise CalError(f"identifiability: the Jacobian at {where} is not finite: the model's "
                       "rows cannot be differentiated there (a value or derivative is "
                       "undefined, as sqrt(x) at x <= 0: narrow the search domains to where "
                       "the model is defined; or its numbers overflow the floats, as "
                       "coordinates near 1e154 squared: express the model in units that keep "
                       "its numbers smaller)")
    return js


def analyse_design(prog: Program, rank_tol: float = Settings.rank_tol) -> Identifiability | None:
    """analyse(prog, design=True), or None where there is no analysis to make (no nominal
    values or finite domains, a Jacobian without finite values): for the solvers, which then
    go on without it."""
    try:
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            return analyse(prog, True, rank_tol)  # a non-finite Jacobian raises in the SVD
    except (CalError, np.linalg.LinAlgError, ValueError):
        return None


def _nominal(prog: Program, ind: np.ndarray, names: list[str],
             design: bool = False) -> np.ndarray:
    vals = []
    for slot, name in zip(ind, names, strict=True):
        t = prog.true_values.get(name)
        if design and np.isfinite(prog.slots.lo[slot]) and np.isfinite(prog.slots.hi[slot]):
            t = None
        if t is None:  # no nominal value: the middle of a finite domain will do
            lo, hi = prog.slots.lo[slot], prog.slots.hi[slot]
            if not (np.isfinite(lo) and np.isfinite(hi)):
                raise CalError(f"identify needs a nominal value for '{name}' "
                               "(give it `true` or a finite domain)")
            t = 0.5 * (lo + hi)
        vals.append(t)
    return np.array(vals, dtype=float)


def _groups(names, null, touched, scale) -> list[tuple[list[str], list[np.ndarray]]]:
    """Split the null space into groups of coupled parameters; per group, the identifiable
    combinations are the complement of the null directions within the group."""
    if not null.size:
        return []
    idx = np.flatnonzero(touched)
    # couple parameters that appear together in a null vector (connected components)
    comp = {int(i): int(i) for i in idx}

    def find(i: int) -> int:
        while comp[i] != i:
            i = comp[i]
        return i

    for v in null.T:
        members = [int(i) for i in idx if abs(v[i]) > 1e-6]
        for m in members[1:]:
            comp[find(m)] = find(members[0])
    groups: dict[int, list[int]] = {}
    for i in idx:
        groups.setdefault(find(int(i)), []).append(int(i))
    out = []
    for members in groups.values():
        sub = null[members]  # null directions restricted to the group (scaled coordinates)
        u, s, _ = np.linalg.svd(sub, full_matrices=True)
        k = int(np.sum(s > 1e-6))
        complement = u[:, k:].T  # identifiable directions in scaled coordinates
        combos = [c / scale[members] for c in complement]  # back to parameter units
        combos = [c / c[np.argmax(np.abs(c))] for c in combos]
        out.append(([names[i] for i in members], combos))
    return out


def _direction(names, v, scale) -> dict[str, float]:
    c = v / scale
    c = c / np.max(np.abs(c))
    return {n: float(x) for n, x in zip(names, c, strict=True) if abs(x) > 0.05}


def format_combination(names: list[str], coef: np.ndarray) -> str:
    parts = []
    for n, c in zip(names, coef, strict=True):
        if abs(c) < 1e-9:
            continue
        sign = "-" if c < 0 else "+"
        mag = "" if abs(abs(c) - 1) < 1e-9 else f"{abs(c):.4g} "
        parts.append(f"{sign} {mag}{n}")
    text = " ".join(parts)
    return text[2:] if text.startswith("+ ") else text


def render(info: Identifiability) -> str:
    lines = [f"identifiability: rank {info.rank} of {len(info.names)} parameters"]
    lines.append("identifiable: " + (" ".join(info.identifiable) or "(none)"))
    for members, combos in info.groups:
        if combos:
            shown = ", ".join(format_combination(members, c) for c in combos)
            lines.append(f"not identifiable separately: {' '.join(members)}; "
                         f"identifiable only through {shown}")
        else:
            lines.append(f"not identifiable at all: {' '.join(members)}")
    for s, d in info.weakest:
        shown = " ".join(f"{v:+.3g}*{n}" for n, v in d.items())
        lines.append(f"weak direction, a combination the data see least (singular value "
                     f"{s:.3g}): {shown}")
    return "\n".join(lines)


def combination_enclosures(prog: Program, info: Identifiability, lo: np.ndarray,
                           hi: np.ndarray, use_lp: bool, pieces: list | None = None,
                           known: list[tuple[str, float, float]] | None = None
                           ) -> list[tuple[str, float, float]]:
    """A guaranteed enclosure of each identifiable combination over the box [lo, hi]:
    certified LP bounds over the linear relaxation (tight), else interval arithmetic. With
    `pieces` (boxes within [lo, hi] holding every solution: a split solve), the hull of each
    piece's enclosure: on a piece the relaxation is narrower. `known`: certified bounds the
    solve already has for some combinations, by text (the tight strategy solves for them,
    Result.combinations): those are intersected with the box's, and need no LP."""
    if pieces:
        parts = [combination_enclosures(prog, info, a, b, use_lp) for a, b in pieces]
        hull = [(t, min(p[k][1] for p in parts), max(p[k][2] for p in parts))
                for k, (t, _, _) in enumerate(parts[0])]
        return _with_known(hull, known)
    ind = independents(prog)
    index = {n: k for k, n in enumerate(info.names)}
    rows, texts = [], []
    for members, combos in info.groups:
        for c in combos:
            full = np.zeros(len(ind))
            for name, coef in zip(members, c, strict=True):
                full[index[name]] = coef
            rows.append(full)
            texts.append(format_combination(members, c))
    if not rows:
        return []
    obj = np.array(rows)
    from calib_dsl.lp.certify import box_maxes_up

    plo, phi = lo[ind], hi[ind]
    upper = box_maxes_up(obj, obj, plo, phi)
    lower = -box_maxes_up(-obj, -obj, plo, phi)
    if use_lp and not set(texts) <= {t for t, _, _ in known or []}:
        from calib_dsl.lp.bounds import lp_bounds
        from calib_dsl.relax.linearize import relax

        rel = relax(prog, lo, hi)
        if rel is not None:
            a, b = lp_bounds(rel, obj)
            lower, upper = np.maximum(lower, a), np.minimum(upper, b)
    return _with_known([(t, float(a), float(b)) for t, a, b in zip(texts, lower, upper,
                                                                   strict=True)], known)


def _with_known(bounds: list[tuple[str, float, float]],
                known: list[tuple[str, float, float]] | None) -> list[tuple[str, float, float]]:
    """Each enclosure intersected with a known one of the same combination (both hold it)."""
    have = {t: (a, b) for t, a, b in known or []}
    return [(t, max(a, have[t][0]), min(b, have[t][1])) if t in have else (t, a, b)
            for t, a, b in bounds]


def identifiability_json(info: Identifiability) -> dict:
    return {
        "rank": info.rank,
        "parameters": len(info.names),
        "identifiable": info.identifiable,
        "not_identifiable": [
            {"parameters": members,
             "identifiable_combinations": [format_combination(members, c) for c in combos]}
            for members, combos in info.groups],
        "singular_values": [float(v) for v in info.singular_values],
        "weakest_directions": [{"singular_value": s, "direction": d} for s, d in info.weakest],
    }
