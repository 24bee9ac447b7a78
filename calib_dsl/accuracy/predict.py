"""Guaranteed prediction: for configurations the calibration did not use, a box proven to
contain the model's predicted measurement for every parameter vector consistent with the data.

The model reads the configurations as its table (columns it does not find, the measurements a
prediction is for, read as 0: they are not used): derived from the calibration's elaborated model
where it allows (problem.py's `with_table`), else elaborated once more with the file. Its
parameters take the solve's enclosure and its measured sides are set to 0. Where the calibration's
relaxation is a second-order one, each predicted coordinate's second-order Taylor model over the
same box is one more objective over it (accuracy/second_order.py): only the third-order remainder
is left to the box. Otherwise each constraint row `f(p, q) == x` gives f over the box in the mixed
mean-value form of the relaxations (relax/evaluation.py): f in D + h (p - p^) + [-r, r], with h the
gradients' midpoints and r their radii times the box's half-widths plus the joint readings' errors,
and certified LP bounds of h.p over the calibration's relaxation (accuracy/batch_lp.py: one LP per
coordinate) bound f for every consistent vector. Either way the parameters' correlations count,
where the box alone would add every parameter's uncertainty. All of it rounded outward. Validation
compares held-out measurements with these boxes widened by each column's error bound.
"""

from __future__ import annotations

import csv
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from calib_dsl.accuracy.batch_lp import batch_bounds
from calib_dsl.accuracy.certified import inner_at, picks
from calib_dsl.accuracy.held_readings import held_values, reading_moves
from calib_dsl.accuracy.second_order import Bounds, second_order
from calib_dsl.compile.group import compile_model
from calib_dsl.elaborate.elaborator import Inputs, elaborate
from calib_dsl.elaborate.rows import EVERY_ROW, Selection
from calib_dsl.elaborate.tables import CsvData, Dialect, read_csv
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.frontend.files import MAX_TABLE_BYTES, NotUtf8, TooLarge, read_capped
from calib_dsl.ir.model import Model, Table
from calib_dsl.ir.program import Program
from calib_dsl.lp.certify import box_maxes_up
from calib_dsl.relax.chunked import evaluation
from calib_dsl.relax.layout import independents
from calib_dsl.relax.linearize import mid_rad
from calib_dsl.relax.quadratic import FAMILY as SECOND_ORDER
from calib_dsl.relax.relaxation import RHS_REL, LinearRelaxation
from calib_dsl.settings import Settings


@dataclass(frozen=True)
class Prediction:
    file: str
    rows: list[int]  # data row numbers of the configurations (1: the first after the header)
    lines: list[int]  # their lines in the file
    columns: list[str]  # the predicted measurements
    lo: np.ndarray  # (rows, columns)
    hi: np.ndarray
    measured: np.ndarray  # (rows, columns) the file's values (nan where it had none)
    bound: np.ndarray  # (columns,) each measurement's error bound
    # (rows, columns) certified inner intervals: within the hull of the predictions at
    # certified points (accuracy/certified.py); nan where there is none
    inner_lo: np.ndarray | None = None
    inner_hi: np.ndarray | None = None
    # the certified points those are the predictions of (one a row, in `names`' order)
    inner_points: np.ndarray | None = None
    names: tuple[str, ...] = ()
    inner_readings: np.ndarray | None = None  # the calibration's readings each was proven at
    # (rows, columns, 2): which of inner_points each inner end is the prediction of (-1: none)
    inner_from: np.ndarray | None = None
    # (rows, columns, 2, readings): the configuration's readings (`held_columns`) each inner
    # end was evaluated at, within their errors (accuracy/held_readings.py)
    inner_held: np.ndarray | None = None
    held_columns: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()  # about the file: configurations beyond the joints' limits

    def covered(self) -> np.ndarray:
        """Per row: every measured value within its box widened by its bound (a column the
        file lacks, nan, has no value to compare: it neither covers nor fails a row)."""
        with np.errstate(invalid="ignore"):
            inside = (self.measured >= self.lo - self.bound) & \
                (self.measured <= self.hi + self.bound)
        return np.all(inside | np.isnan(self.measured), axis=1)


Certified = tuple[np.ndarray, np.ndarray]  # a certified point and the readings of its proof


@dataclass(frozen=True)
class Calibrated:
    """What a prediction takes from the calibration: its enclosure `box` (name: (lo, hi));
    its relaxation on that box (`data`: columns the box's parameters, in its order; None:
    every vector of the box), with `center` for a second-order one (columns t,
    p = center + scale t); certified points (`points`: each in the box's order, with the
    calibration's readings it was proven at), `certify` ((the predictions' gradients, the
    LPs' optima), each a row in the box's order -> more certified points, towards the
    predictions' extremes) and the settings."""

    box: dict[str, tuple[float, float]]
    settings: Settings
    data: LinearRelaxation | None = None
    center: np.ndarray | None = None
    points: tuple[Certified, ...] = ()
    certify: Callable[[np.ndarray, np.ndarray], list[Certified]] | None = None


Held = tuple[Model, Program]  # the model with the configurations as its table, compiled


@dataclass(frozen=True)
class Source:
    """The calibration's model a prediction is of: its file, formulation and inputs (its
    consts), its elaborated model (the table's declaration), and `derive`: a file's rows as
    its table's -> that model and its program, without elaborating (None where the model
    does not allow it: then it is elaborated once more, with the file)."""

    path: str | Path
    formulation: str
    inputs: Inputs
    model: Model
    derive: Callable[[CsvData], Held | None] | None = None


@dataclass(frozen=True)
class HeldAt:
    """The file of configurations read and compiled, before any calibration: its faults
    are found before the solve's time is spent."""

    file: str
    table: Table
    program: Program
    present: set[str]


def held_at(source: Source, at: str | Path, table: str | None = None,
            at_rows: Selection | None = None) -> HeldAt:
    """The configurations of the file `at` (its rows `at_rows`, all by default) as table
    `table` (the model's first) reads them, compiled."""
    t = _table(source.model, table)
    lines, present = _present(Path(at), t)
    held = _derived(source, Path(at), t, present, at_rows) or \
        _elaborated(source, (Path(at), lines), t, present, at_rows)
    model, prog = held
    _inputs_present(prog, _table(model, t.name), present, str(at))
    return HeldAt(str(at), _table(model, t.name), prog, present)


def predict(held: HeldAt, calibrated: Calibrated) -> Prediction:
    """Boxes of the measurements of the held configurations for every parameter vector of
    the calibration (`calibrated`), and their certified inner intervals where it has
    certified points."""
    return _enclose(held.program, held.table, calibrated, held.present, held.file)


def _derived(source: Source, at: Path, t: Table, present: set[str],
             at_rows: Selection | None) -> Held | None:
    """The file's rows as the table's, derived (None where the model does not allow it):
    read as the elaborator reads a table, the columns it lacks as 0."""
    if source.derive is None or t is not source.model.tables[0] \
            or any(c.derived for c in t.columns):
        return None
    files = [c for c in t.columns if c.name in present]
    data = read_csv(at, [c.name for c in files], dialect=Dialect(t.separator, t.decimal),
                    headers={c.name: c.header for c in files if c.header},
                    selection=at_rows or EVERY_ROW)
    for c in t.columns:
        if c.name not in present:  # a measurement to predict: not used
            data.enclosures[c.name] = (np.zeros(data.rows), np.zeros(data.rows))
    return source.derive(data)


def _elaborated(source: Source, file: tuple[Path, list[str]], t: Table, present: set[str],
                at_rows: Selection | None) -> Held:
    """The model elaborated once more, with the file (completed) as its table."""
    at, lines = file
    inputs = source.inputs
    with tempfile.TemporaryDirectory(prefix="calibc-predict-") as tmp:
        path = _completed(at, lines, t, present, Path(tmp))
        try:
            model = elaborate(source.path, formulation=source.formulation, inputs=Inputs(
                data={**inputs.data, t.name: path},
                rows={t.name: at_rows} if at_rows is not None else {}, consts=inputs.consts))
        except CalError as err:  # located in the copy: the user's file has the same lines
            raise _in_file(err, str(path), str(at)) from None
    return model, compile_model(model)


def _table(model: Model, name: str | None) -> Table:
    if not model.tables:
        raise CalError("the model has no table: there is nothing to predict")
    for t in model.tables:
        if name is None or t.name == name:
            return t
    raise CalError(f"the model has no table '{name}'")


def _present(at: Path, t: Table) -> tuple[list[str], set[str]]:
    """The lines of `at`, and which of the table's columns it has."""
    try:
        lines = read_capped(at, MAX_TABLE_BYTES, encoding="utf-8-sig").splitlines()
    except TooLarge as err:
        raise CalError(f"'{at}' is {err}: too large for a table") from None
    except FileNotFoundError:
        raise CalError(f"'{at}' not found") from None
    except IsADirectoryError:
        raise CalError(f"'{at}' is a directory: give a CSV file") from None
    except NotUtf8 as err:
        byte = f"{err.reason}: byte {err.object[err.start]:#04x}"
        raise CalError(f"'{at}' is not UTF-8 text ({byte}; save it as UTF-8)",
                       Loc(str(at), err.line, err.col)) from None
    except OSError as err:
        raise CalError(f"cannot read '{at}': {err.strerror}") from None
    if not lines:
        raise CalError(f"'{at}' is empty: it has no header")
    header = [h.strip() for h in next(csv.reader([lines[0]], delimiter=t.separator))]
    files = [c for c in t.columns if not c.derived]  # (a derived column is no file's)
    present = {c.name for c in files if (c.header or c.name) in header}
    present |= {c.name for c in t.columns if c.derived and set(c.derived) <= present}
    return lines, present


def _completed(at: Path, lines: list[str], t: Table, present: set[str], tmp: Path) -> Path:
    """`at` as the table reads it: a copy with the columns it lacks as 0 where it lacks some
    (the measurements a prediction is for)."""
    missing = [c.header or c.name for c in t.columns if not c.derived and c.name not in present]
    if not missing:
        return at
    out = tmp / at.name
    fill = t.separator + t.separator.join("0" for _ in missing)
    body = [ln + fill if ln.strip() else ln for ln in lines[1:]]  # (the same line numbers)
    out.write_text("\n".join([lines[0] + t.separator + t.separator.join(missing), *body])
                   + "\n", encoding="utf-8")
    return out


def _in_file(err: CalError, copy: str, at: str) -> CalError:
    """The error `err` of the completed copy, said of the user's file `at`."""
    loc = err.loc
    if loc is not None and loc.file == copy:
        loc = replace(loc, file=at)
    return CalError(err.message.replace(copy, at), loc)


def _inputs_present(prog: Program, t: Table, present: set[str], at: str) -> None:
    """Only measured columns (a row's compared side) may be absent from the --at file: a
    configuration is its inputs, and an input read as 0 would predict somewhere else."""
    s = prog.slots
    measured = {s.col_keys[c] for _, c in (s.measured_sides or {}).values()} \
        if s.col_keys is not None else set()
    lacking = [c.header or c.name for c in t.columns if not c.derived
               and c.name not in present and (t.name, c.name) not in measured]
    if lacking:
        raise CalError(f"'{at}' has no column {', '.join(repr(n) for n in lacking)}: the "
                       "configurations need it (only the measured columns may be absent; "
                       f"the table's separator is {t.separator!r})")


def _enclose(prog: Program, t: Table, cal: Calibrated, present: set[str],
             file: str) -> Prediction:
    s = prog.slots
    box = cal.box
    ind = independents(prog)
    lo, hi = s.lo.copy(), s.hi.copy()
    for k in ind:
        name = s.names[k]
        if name not in box:
            raise CalError(f"the enclosure has no parameter '{name}'")
        lo[k], hi[k] = box[name]
    sides = s.measured_sides or {}
    measured_side = np.zeros(len(lo), dtype=bool)
    measured_side[list(sides)] = True
    original = (lo.copy(), hi.copy())
    lo[measured_side], hi[measured_side] = 0.0, 0.0
    names = [s.names[k] for k in ind]
    # the mean-value form over the box: its remainder chooses the form of each row, and
    # its box bounds a row whose LP stopped by its limits
    box_only = _first_order(prog, lo, hi, measured_side, replace(cal, data=None))
    parts = [box_only]
    found = None
    if cal.data is not None and names == list(box):  # (the relaxation's columns: the box's)
        first = np.full(len(lo), np.inf)
        assert box_only.charge is not None
        first[box_only.targets] = box_only.charge
        found = second_order(prog, lo, hi, measured_side, cal.data, cal.settings, first)
    # the first-order LP for the rows the second order did not take or did not settle (an
    # LP stopped by its limits): the intersection of both is kept
    rest = np.setdiff1d(box_only.targets, [] if found is None else
                        found.targets[found.settled] if found.settled is not None
                        else found.targets)
    if found is not None:
        parts.append(found)
    if len(rest) and cal.data is not None:
        only = np.zeros(len(lo), dtype=bool)
        only[rest] = True
        parts.append(_first_order(prog, lo, hi, measured_side & only, cal))
    # (_arrange keeps the intersection of a cell's enclosures)
    targets, plo, phi = (np.concatenate([getattr(b, a) for b in parts])
                         for a in ("targets", "lo", "hi"))
    outer = _arrange(prog, t, targets, (plo, phi), original, measured_side, present, file)
    solved = parts[1:] if len(parts) > 1 else parts
    gradient = np.concatenate([b.gradient for b in solved])
    found_optima = np.concatenate([b.optima for b in solved])
    order = np.array([list(box).index(n) for n in names])
    directions = np.zeros((len(gradient), len(box)))
    directions[:, order] = gradient
    optima = np.zeros((len(found_optima), len(box)))
    optima[:, order] = found_optima
    known = [*cal.points, *(cal.certify(directions, optima) if cal.certify else [])]
    if not known:
        return outer
    P = np.array([p[order] for p, _ in known])
    # each cell's inner ends: the exact predictions at the certified points an approximate
    # model (the second-order one where a row has it) puts at its extremes
    assert box_only.value is not None
    chosen = picks(box_only.value, P)
    if found is not None and found.value is not None:
        sort = np.argsort(box_only.targets)
        at = sort[np.minimum(np.searchsorted(box_only.targets, found.targets, sorter=sort),
                             len(sort) - 1)]
        assert np.array_equal(box_only.targets[at], found.targets)  # (the same rows' cells)
        chosen[at] = picks(found.value, P)
    # each end at the configuration's readings moved within their errors towards it
    assert box_only.readings is not None
    moves = reading_moves(prog, box_only.targets, *box_only.readings) \
        if cal.settings.prediction_move_readings else None
    ilo, ihi, ends, read = inner_at(prog, P, box_only.targets, chosen,
                                    cal.settings.prediction_hull_rows, moves)
    inner = _arrange(prog, t, box_only.targets, (ilo, ihi), original, measured_side, present,
                     file)
    some = np.isfinite(inner.lo) & np.isfinite(inner.hi)  # (a cell no point predicted)
    # (each end's point and readings as one code: a cell's two named from the same row)
    n_read = 1 + (0 if moves is None else len(moves.configs))
    code = _witnesses(prog, box_only.targets, measured_side, inner, (ilo, ihi),
                      np.where(ends >= 0, ends * n_read + read + 1, -1))
    witness = np.where(code >= 0, code // n_read, -1)
    held = held_values(prog, t, moves, np.where(code >= 0, code % n_read - 1, -1))
    return replace(outer, inner_lo=np.where(some, inner.lo, np.nan),
                   inner_hi=np.where(some, inner.hi, np.nan), inner_points=P,
                   inner_from=np.where(some[..., None], witness, -1),
                   names=tuple(s.names[k] for k in ind),
                   inner_readings=np.array([r for _, r in known]),
                   inner_held=held[1], held_columns=held[0])


def _first_order(prog: Program, lo: np.ndarray, hi: np.ndarray, measured_side: np.ndarray,
                 cal: Calibrated) -> Bounds:
    """The rows' enclosures in the mixed mean-value form: f in D + h (p - p^) + [-r, r],
    h.p bounded over the data's relaxation (or the box); `lo`, `hi` as for second_order."""
    s = prog.slots
    ind = independents(prog)
    center = 0.5 * (lo[ind] + hi[ind])
    ev = evaluation(prog, lo, hi, center)
    rows = ev.run()
    targets = ev.targets()
    dlo, dhi = (np.concatenate([r[0][i] for r in rows]) for i in (0, 1))
    hlo, hhi = (np.concatenate([r[1][i] for r in rows]) for i in (0, 1))
    qmax = np.concatenate([np.maximum(np.abs(r[2][0]), np.abs(r[2][1])) for r in rows])
    slope = np.concatenate([0.5 * r[2][0] + 0.5 * r[2][1] for r in rows])
    owner = np.concatenate([r[3] for r in rows])
    h, hrad = mid_rad(hlo, hhi)
    w = np.maximum(center - lo[ind], hi[ind] - center) * (1 + 4 * RHS_REL)
    with np.errstate(invalid="ignore"):
        rad = hrad @ w + (qmax @ ev.e if qmax.shape[1] else 0.0)
    use = np.flatnonzero(measured_side[targets])
    # h.p over the box, or over the data's relaxation (certified LP bounds)
    lin_lo, lin_hi, optima = _linear_range(h[use], lo[ind], hi[ind], cal,
                                           [s.names[k] for k in ind])
    hc = h[use] @ center
    err = RHS_REL * (rad[use] + np.abs(dlo[use]) + np.abs(dhi[use]) + np.abs(h[use])
                     @ np.abs(center) + np.abs(lin_lo) + np.abs(lin_hi)) + 1e-300
    plo = dlo[use] - hc + lin_lo - rad[use] - err
    phi = dhi[use] - hc + lin_hi + rad[use] + err
    order = np.array([list(cal.box).index(s.names[k]) for k in ind])
    mid = 0.5 * (dlo[use] + dhi[use])

    def value(points: np.ndarray) -> np.ndarray:  # (floats, without the remainder)
        return mid[:, None] + h[use] @ (points - center).T

    return Bounds(plo, phi, targets[use], h[use], optima[:, order], value, charge=rad[use],
                  readings=(slope[use], owner[use]))


def _arrange(prog: Program, t: Table, targets: np.ndarray, ends: tuple[np.ndarray, np.ndarray],
             original: tuple[np.ndarray, np.ndarray], measured_side: np.ndarray,
             present: set[str], file: str) -> Prediction:
    """The rows' enclosures `ends` as a (configuration, measured column) table."""
    plo, phi = ends
    s = prog.slots
    assert s.row_keys is not None and s.col_keys is not None
    sides = s.measured_sides or {}
    pick = np.flatnonzero(measured_side[targets])
    cols = sorted({s.col_keys[sides[int(targets[i])][1]][1] for i in pick},
                  key=[c.name for c in t.columns].index)
    n = t.rows
    lo, hi = np.full((n, len(cols)), -np.inf), np.full((n, len(cols)), np.inf)
    measured = np.full((n, len(cols)), np.nan)
    for i in pick:
        slot = int(targets[i])
        row, col = sides[slot]
        k = s.row_keys[row][1] - 1
        j = cols.index(s.col_keys[col][1])
        lo[k, j], hi[k, j] = max(lo[k, j], plo[i]), min(hi[k, j], phi[i])
        if cols[j] in present:
            measured[k, j] = 0.5 * original[0][slot] + 0.5 * original[1][slot]
    bound = np.array([next(c.tol for c in t.columns if c.name == name) for name in cols])
    return Prediction(file, list(t.numbers), list(t.lines), cols, lo, hi, measured, bound)


def _witnesses(prog: Program, targets: np.ndarray, measured_side: np.ndarray,
               inner: Prediction, ends: tuple[np.ndarray, np.ndarray], named: np.ndarray
               ) -> np.ndarray:
    """(rows, columns, 2): per cell of `inner`, the point each inner end is the prediction
    of: `named` (per row: the points its two `ends` are at) of the row whose end the cell's
    end is (a cell of several rows takes their intersection: the largest low end, the
    smallest high end); -1 for none."""
    s = prog.slots
    assert s.row_keys is not None and s.col_keys is not None
    sides = s.measured_sides or {}
    out = np.full((*inner.lo.shape, 2), -1, dtype=np.int64)
    for i in np.flatnonzero(measured_side[targets]):
        row, col = sides[int(targets[i])]
        k, j = s.row_keys[row][1] - 1, inner.columns.index(s.col_keys[col][1])
        for side, cell in ((0, inner.lo), (1, inner.hi)):
            if ends[side][i] == cell[k, j] and out[k, j, side] < 0:
                out[k, j, side] = named[i, side]
    return out


def _linear_range(h: np.ndarray, plo: np.ndarray, phi: np.ndarray, cal: Calibrated,
                  names: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rigorous [min, max] of each row of h . p: over the data's relaxation (its columns in
    the box's order), else over the box; and the LPs' optima (parameter vectors in the
    box's order, one a row: candidates, not proofs)."""
    data = cal.data
    if data is None:
        lo = -box_maxes_up(-h, -h, plo, phi)
        hi = box_maxes_up(h, h, plo, phi)
        return lo, hi, np.zeros((0, len(names)))
    cols = np.array([list(cal.box).index(n) for n in names])
    obj = np.zeros((len(h), data.main))
    if data.family != SECOND_ORDER:
        obj[:, cols] = h
        return batch_bounds(data, obj, cal.settings)[:3]
    # a second-order relaxation's columns are t (p = c + w t): h.p = h.c + (h w).t
    assert data.scale is not None and cal.center is not None
    c, w = cal.center[cols], data.scale[cols]
    obj[:, cols] = h * w
    err = RHS_REL * (np.abs(h * w) @ np.ones(len(w)) + np.abs(h) @ np.abs(c)) + 1e-300
    lo, hi, optima, _ = batch_bounds(data, obj, cal.settings)
    hc = h @ c
    return lo + hc - err, hi + hc + err, cal.center + optima * data.scale
