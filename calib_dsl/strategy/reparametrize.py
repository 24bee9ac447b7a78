"""Unknowns along the identifiable combinations of parameters the data cannot separate.

On the RX90 only r2 + r3 is identifiable (alpha3 = 0: two translations along one axis), so
r2 and r3 keep their whole search domains whatever the data. Every relaxation over the box
pays for that: the lever arms the model's derivatives are made of hold r2 and r3 over their
ranges, although only their sum moves the tool. With s = r2 + r3 an unknown of its own and
r2 = s - r3 computed from it, the relaxations see one unknown the data pins down (s) and one
the model barely depends on (r3), and the relaxations need no cut of the box into pieces.

The change of unknowns is exact: the new program has the same solutions, mapped one to one
(s takes its domain from r2's and r3's, rounded outward, and r2 keeps its own domain as a
constraint). Its slots are the old ones, at the same indices, then the new ones, so a box of
the new program read on its first slots is a box of the old one.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from calib_dsl.analysis.identify import analyse_design
from calib_dsl.arith.exact import add_rounded
from calib_dsl.arith.interval import dn1, up1
from calib_dsl.compile.group import make_groups
from calib_dsl.ir.primitives import Primitive, Slots
from calib_dsl.ir.program import Program
from calib_dsl.ir.status import SlotKind
from calib_dsl.relax.layout import independents
from calib_dsl.settings import Settings


@dataclass
class Reparametrized:
    """A program in new unknowns (`prog`), and which of its slots are the combinations."""

    prog: Program
    old_slots: int  # the original program's slots are the first ones
    # per combination: its text ("r2 + r3"), its slot, its members' slots and coefficients
    combinations: list[tuple[str, int, np.ndarray, np.ndarray]] = field(default_factory=list)
    # the members left as unknowns in a changed group (r3): only the combination is seen
    free: list[int] = field(default_factory=list)


def along_combinations(prog: Program, s: Settings | None = None) -> Reparametrized | None:
    """The program with one new unknown per identifiable combination of each group of
    parameters the data cannot separate (identify.py, at the middle of the search domains),
    each replacing one member (its pivot), which becomes computed from it. None when there
    is no such group, or no analysis (no finite domains, a Jacobian without finite values, a
    program over `routine_max_primitives`, where the analysis would cost more than it
    saves)."""
    s = s or Settings()
    if len(prog.primitives) > s.routine_max_primitives:
        return None  # the analysis would cost more than it can save
    info = analyse_design(prog, s.rank_tol)
    if info is None:
        return None
    slot_of = dict(zip(info.names, independents(prog).tolist(), strict=True))
    combos = []
    for members, rows in info.groups:
        if not rows:
            continue  # not identifiable at all: nothing to pin down
        slots = np.array([slot_of[m] for m in members], dtype=np.int64)
        for pivot, coef in _echelon(np.array(rows, dtype=float), s.snap):
            if np.count_nonzero(coef) > 1:
                combos.append((members, slots, pivot, coef))
    if not combos:
        return None
    return _rewritten(prog, combos)


def _echelon(rows: np.ndarray, snap: float) -> list[tuple[int, np.ndarray]]:
    """The combinations as rows with a pivot each (coefficient exactly 1, 0 in the other
    rows), by Gauss-Jordan elimination with partial pivoting; coefficients next to an integer
    snapped to it (any coefficients give an exact change of unknowns; simple ones keep it
    exact in floating point too)."""
    a = rows.copy()
    out = []
    used: list[int] = []
    for r in range(len(a)):
        free = [c for c in range(a.shape[1]) if c not in used]
        if not free:
            break
        p = free[int(np.argmax(np.abs(a[r, free])))]
        if abs(a[r, p]) < 1e-12:
            continue
        a[r] = a[r] / a[r, p]
        for q in range(len(a)):
            if q != r:
                a[q] = a[q] - a[q, p] * a[r]
        used.append(p)
    for r, p in enumerate(used):
        coef = a[r].copy()
        near = np.round(coef)
        snapped = np.abs(coef - near) <= snap * np.maximum(1.0, np.abs(coef))
        coef[snapped] = near[snapped]
        coef[p] = 1.0
        out.append((p, coef))
    return out


def _rewritten(prog: Program, combos: list) -> Reparametrized:
    """The new program: slots appended (combinations, coefficients, partial sums), each pivot
    a temporary defined by pivot = s - sum of the others' terms, computed before everything
    else (negative levels: the groups run in list order, the new ones first)."""
    from calib_dsl.analysis.identify import format_combination

    s = prog.slots
    names, kinds = list(s.names), list(s.kinds)
    lo, hi = list(s.lo), list(s.hi)
    origin = list(s.origin)
    true = dict(prog.true_values)
    stated = set(prog.true_stated)
    domains = dict(prog.domains or {})
    prims: list[tuple[str, tuple[int, ...], int]] = []  # (op, (out, a, b), chain step)

    def new_slot(name: str, kind: str, a: float, b: float) -> int:
        names.append(name)
        kinds.append(kind)
        lo.append(a)
        hi.append(b)
        origin.append(None)
        return len(names) - 1

    out = Reparametrized(prog, len(names))
    pivots = []
    for members, slots, p, coef in combos:
        text = format_combination(members, coef)
        a, b = _sum_enclosure(coef, s.lo[slots], s.hi[slots])
        top = new_slot(text, "param", a, b)
        values = [prog.true_values.get(m) for m in members]
        true[text] = (None if any(v is None for v in values)
                      else float(np.dot(coef, np.array(values, dtype=float))))
        if all(m in prog.true_stated for m in members):
            stated.add(text)
        domains[text] = (a, b)
        # pivot = top - sum over the others of coef * member, one term per step
        terms = [(int(slots[k]), float(coef[k])) for k in range(len(slots))
                 if k != p and coef[k] != 0.0]
        acc = top
        for step, (slot, c) in enumerate(terms):
            dest = int(slots[p]) if step == len(terms) - 1 else new_slot("", "temp",
                                                                          -np.inf, np.inf)
            if c == 1.0 or c == -1.0:
                prims.append(("sub" if c == 1.0 else "add", (dest, acc, slot), step + 1))
            else:
                k = new_slot(repr(c), "const", c, c)
                t = new_slot("", "temp", -np.inf, np.inf)
                prims.append(("mul", (t, k, slot), 0))
                prims.append(("sub", (dest, acc, t), step + 1))
            acc = dest
        out.combinations.append((text, top, slots, coef))
        pivots.append(int(slots[p]))
        out.free += [int(slots[k]) for k in range(len(slots)) if k != p and coef[k] != 0.0]
    for p in pivots:  # computed now: a temporary, no longer an unknown
        kinds[p] = SlotKind.TEMP
    _name_new_temporaries(names, out.old_slots)
    depth = 1 + max(step for _, _, step in prims)
    first = len(prog.primitives)
    new = [tuple.__new__(Primitive, (op, (o,), (a, b), None, None, step - depth))
           for op, (o, a, b), step in prims]
    groups = [replace(g, prim=g.prim + first) for g in make_groups(new)]
    declared = [d for d in s.declared if d not in pivots] + [c[1] for c in out.combinations]
    extra = len(names) - len(s.names)
    slots2 = Slots(names, kinds, np.array(lo, dtype=float), np.array(hi, dtype=float), origin,
                   declared, [names[d] for d in declared],
                   None if s.cell_row is None else np.concatenate([s.cell_row,
                                                                  np.full(extra, -1)]),
                   None if s.cell_col is None else np.concatenate([s.cell_col,
                                                                  np.full(extra, -1)]),
                   s.row_keys, s.col_keys, implied=set(s.implied))
    out.prog = Program(prog.source, prog.formulation, slots2, list(prog.primitives) + new,
                       groups + prog.groups, true, domains, true_stated=stated,
                       units=prog.units, tables=prog.tables, sources=prog.sources)
    return out


def _sum_enclosure(coef: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[float, float]:
    """[sum coef_i x_i] over the box, rounded outward (each product and each sum)."""
    a = np.minimum(coef * lo, coef * hi)
    b = np.maximum(coef * lo, coef * hi)
    exact = np.abs(coef) == 1.0  # a product by +-1 does not round
    a = np.where(exact, a, dn1(a))
    b = np.where(exact, b, up1(b))
    total_lo, total_hi = 0.0, 0.0
    for x, y in zip(a.tolist(), b.tolist(), strict=True):
        total_lo = float(add_rounded(np.array(total_lo), x, -1.0))
        total_hi = float(add_rounded(np.array(total_hi), y, 1.0))
    return total_lo, total_hi


def _name_new_temporaries(names: list[str], start: int) -> None:
    count = 0
    for k in range(start, len(names)):
        if not names[k]:
            count += 1
            names[k] = f"u{count}"


def pivots(rep: Reparametrized) -> dict[int, int]:
    """Each combination's slot -> the slot of the member it replaced as an unknown (its
    pivot, computed from it in the new program)."""
    unknown = set(independents(rep.prog).tolist())
    out = {}
    for _, slot, members, _ in rep.combinations:
        replaced = [int(m) for m in members if int(m) not in unknown]
        if len(replaced) == 1:
            out[int(slot)] = replaced[0]
    return out


def back(rep: Reparametrized, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A box of the new program as a box of the old one (its first slots)."""
    return lo[: rep.old_slots].copy(), hi[: rep.old_slots].copy()
