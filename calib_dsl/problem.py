"""A model loaded once: parsed, elaborated with its inputs, compiled (and its `lsq +- w`
domains centred on the data's least-squares estimate, the only least squares a load runs;
the problem keeps that estimate as `fit`, where the accuracy statement starts its own).

Everything a solve reports about the same model and data works on this one `Problem`: the
pipeline, the verdict's proofs, the conflict search, the solve with outliers and the
residuals ask it for the same model with other inputs (`derive`, `without_rows`,
`with_const`, and the loaders over them), and it gives itself for its own inputs. Rows of
its table left out are derived from the elaborated model where it allows
(elaborate/subset.py: then the derived model is compiled, never elaborated), and so are
consts that are only error bounds set to other values; other inputs (rows added, another
file, a const read elsewhere) are elaborated anew. `on_domains` puts a program on
another's domains (a proof about other rows must hold on the same box). `with_table` reads
another file's rows as its table's (the configurations a prediction is at), derived too
where the model allows.
"""

from __future__ import annotations

import gc
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from fractions import Fraction
from pathlib import Path

from calib_dsl.analysis.lsq import Estimate
from calib_dsl.analysis.priors import centre_on_least_squares
from calib_dsl.compile.group import compile_model
from calib_dsl.elaborate.elaborator import Inputs, elaborate
from calib_dsl.elaborate.rows import Selection
from calib_dsl.elaborate.subset import derivable, rows_of, with_table, with_tolerance
from calib_dsl.elaborate.tables import CsvData
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program
from calib_dsl.outliers.proof import pinned
from calib_dsl.outliers.rows import data_rows, excluding
from calib_dsl.settings import SamplingSettings
from calib_dsl.settings_analysis import FitSettings

Loader = Callable[[Inputs], tuple[Model, Program]]


def load_model(model: str | Path, formulation: str = "matrix", data: str | Path | None = None,
               inputs: Inputs | None = None, centre: bool = True,
               fits: FitSettings | None = None,
               sampling: SamplingSettings | None = None) -> tuple[Model, Program]:
    """Parse, elaborate and compile a `.cal` model, with the elaborated model (its tables and
    consts); `centre=False` leaves `lsq +- w` domains unbounded (for a caller that gives
    them another program's); `fits` and `sampling`: the settings of the fit that centres
    them."""
    model_, prog, _ = load_fitted(model, formulation, data, inputs, centre, fits, sampling)
    return model_, prog


def load_fitted(model: str | Path, formulation: str = "matrix",
                data: str | Path | None = None, inputs: Inputs | None = None,
                centre: bool = True, fits: FitSettings | None = None,
                sampling: SamplingSettings | None = None
                ) -> tuple[Model, Program, Estimate | None]:
    """`load_model`, and the least-squares estimate that centred the `lsq +- w` domains
    (None: none did)."""
    # The DAG's nodes live as long as the program: the garbage collector would only rescan
    # them (docs/decisions/11), so it pauses while they are built.
    gc.disable()
    try:
        elaborated = elaborate(model, formulation=formulation, data=data, inputs=inputs)
        prog = compile_model(elaborated)
    finally:
        gc.enable()
    # `param x in lsq +- w`: around the data's estimate
    fit = centre_on_least_squares(prog, fits, sampling) if centre else None
    return elaborated, prog, fit


class _Unrolled(Exception):
    """A derived model's template rows are no copies (never seen: its first were): the model
    is elaborated anew instead of compiled unrolled."""


def _unrolled() -> Model:
    raise _Unrolled


def _compiled(model: Model, centre: bool, fits: FitSettings | None = None,
              sampling: SamplingSettings | None = None
              ) -> tuple[Program, Estimate | None] | None:
    """A derived model's program and the estimate that centred it (as `load_fitted`; None:
    elaborate anew, see _Unrolled)."""
    gc.disable()
    try:
        prog = compile_model(model)
    except _Unrolled:
        return None
    finally:
        gc.enable()
    return prog, centre_on_least_squares(prog, fits, sampling) if centre else None


@dataclass(frozen=True)
class Priors:
    """A program's `lsq +- w` domains (and its declared and centred domains), to put on the
    programs of other inputs."""

    fixed: dict[str, tuple[float, float]]
    centred: dict[str, tuple[float, float]]
    domains: dict[str, tuple[float, float]] | None

    @classmethod
    def of(cls, prog: Program) -> Priors:
        s = prog.slots
        at = {name: s.names.index(name) for name in prog.centred}
        return cls({n: (float(s.lo[j]), float(s.hi[j])) for n, j in at.items()},
                   dict(prog.centred), None if prog.domains is None else dict(prog.domains))

    def put_on(self, prog: Program) -> None:
        for name, (lo, hi) in self.fixed.items():
            j = prog.slots.names.index(name)
            prog.slots.lo[j], prog.slots.hi[j] = lo, hi
        prog.domains = None if self.domains is None else dict(self.domains)
        prog.centred = dict(self.centred)


@dataclass(frozen=True, eq=False)  # (its program's arrays have no single truth value)
class Problem:
    """A model loaded: parsed, elaborated with its inputs, compiled."""

    path: str
    formulation: str
    inputs: Inputs
    model: Model  # the elaborated model: its tables, consts, DAG
    program: Program  # the flat program the solvers work on
    # when set, what it derives is on these `lsq +- w` domains, not centred anew
    priors: Priors | None = None
    fits: FitSettings | None = None  # the fit that centres `lsq +- w` domains (None: defaults)
    sampling: SamplingSettings | None = None  # the same fit's sample of rows (None: defaults)
    # the least-squares estimate that centred this program's `lsq +- w` domains, its rows
    # kept (None: none did)
    fit: Estimate | None = None

    @classmethod
    def load(cls, path: str | Path, formulation: str = "matrix",
             inputs: Inputs | None = None, fits: FitSettings | None = None,
             sampling: SamplingSettings | None = None) -> Problem:
        inputs = inputs or Inputs()
        model, prog, fit = load_fitted(path, formulation, inputs=inputs, fits=fits,
                                       sampling=sampling)
        return cls(str(path), formulation, inputs, model, prog, fits=fits, sampling=sampling,
                   fit=fit)

    @property
    def unknowns(self) -> list[str]:
        """The declared unknowns (params, then vars, as declared), as results list them."""
        return list(self.program.slots.declared_names)

    @property
    def consts(self) -> dict[str, Fraction]:
        return dict(self.model.consts)

    def asks_for(self, inputs: Inputs) -> bool:
        """Whether `inputs` are this problem's own (then it is what loading them gives)."""
        return _same(inputs, self.inputs)

    def derive(self, inputs: Inputs, centre: bool = True) -> Problem:
        """The same model with `inputs`: this problem for its own; its rows `inputs` keep
        derived without elaborating where the model allows (`rows_of`); else loaded anew.
        `centre=False` leaves `lsq +- w` domains unbounded (for `on_domains`)."""
        if self.asks_for(inputs):
            return self
        centre = centre and self.priors is None
        model = self._derived(inputs)
        made = None if model is None else _compiled(model, centre, self.fits, self.sampling)
        if model is None or made is None:
            model, prog, fit = load_fitted(self.path, self.formulation, inputs=inputs,
                                           centre=centre, fits=self.fits,
                                           sampling=self.sampling)
        else:
            prog, fit = made
        if self.priors is not None:
            self.priors.put_on(prog)
        return Problem(self.path, self.formulation, inputs, model, prog, self.priors, self.fits,
                       self.sampling, fit)

    def keeping_priors(self) -> Problem:
        """This problem, but what it derives is on its `lsq +- w` domains (a bracket's
        trials all ask about the same priors)."""
        return replace(self, priors=Priors.of(self.program))

    def without_rows(self, ids: list[int]) -> Problem:
        """The same without these data rows (ids of `Slots.row_keys`), as `--exclude`."""
        first = self.model.tables[0].name
        return self.derive(excluding(self.inputs, data_rows(self.model, self.program, ids),
                                     first))

    def with_const(self, **values: str) -> Problem:
        """The same with these consts set (as `-D name=value`): derived where each is an
        error bound of columns alone (`with_tolerance`), else elaborated anew (a const may
        fold into any node of the DAG)."""
        return self.derive(replace(self.inputs, consts={**self.inputs.consts, **values}))

    def with_table(self, data: CsvData) -> tuple[Model, Program] | None:
        """The model with the rows `data` as its table's (every column, in the file's
        units) and its program, on the declared domains (the caller puts its own on them):
        derived without elaborating; None where the model does not allow it (then the
        caller elaborates it with the file)."""
        model = with_table(self.model, data, _unrolled)
        made = None if model is None else _compiled(model, centre=False)
        return None if model is None or made is None else (model, made[0])

    def on_domains(self, prog: Program) -> Problem:
        """This problem's program on `prog`'s domains of the declared unknowns (and its
        declared and centred domains); a copy, this problem's program untouched."""
        slots = replace(self.program.slots, lo=self.program.slots.lo.copy(),
                        hi=self.program.slots.hi.copy())
        other = replace(self.program, slots=slots)
        pinned(lambda _: (self.model, other), prog)(self.inputs)
        return replace(self, program=other, fit=None)  # (a fit on other domains)

    def loader(self) -> Loader:
        """The model loaded with other inputs (`derive`); this problem itself for its own."""
        return self._reusing(lambda i: _pair(self.derive(i)))

    def pinned_loader(self) -> Loader:
        """The model loaded with other inputs on this program's domains (a proof about other
        rows must hold on the same box: outliers/proof.py's `pinned`); this problem itself
        for its own inputs."""
        return self._reusing(lambda i: _pair(self.derive(i, centre=False)
                                             .on_domains(self.program)))

    def _derived(self, inputs: Inputs) -> Model | None:
        """The elaborated model with `inputs`, derived from this one's: its rows `inputs`
        keep, or consts that are error bounds set; None when it must be elaborated anew."""
        keep = self._kept(inputs)
        if keep is not None:
            return rows_of(self.model, keep, _unrolled)
        values = self._bounds_set(inputs)
        model: Model | None = self.model
        for name, value in (values or {}).items():
            model = None if model is None else with_tolerance(model, name, value)
        return model if values else None

    def _bounds_set(self, inputs: Inputs) -> dict[str, Fraction] | None:
        """The consts `inputs` set otherwise than this problem's (as `-D` reads them), when
        nothing else differs; None otherwise."""
        mine = dict(self.inputs.consts)
        if not _same_but(inputs, self.inputs, "consts") or set(mine) - set(inputs.consts):
            return None
        try:
            return {k: Fraction(v.strip()) for k, v in inputs.consts.items()
                    if mine.get(k) != v}
        except (ValueError, ZeroDivisionError, AttributeError):
            return None

    def _kept(self, inputs: Inputs) -> list[int] | None:
        """The model rows (k, 1-based) of this problem's that `inputs` keep, when they differ
        from its own only in the selection of its table's rows and keep some of them (rows
        left out, or a set of them named); None otherwise."""
        if not derivable(self.model) or self.program.rows is None \
                or not _same_but(inputs, self.inputs, "rows"):
            return None
        table = self.model.tables[0]
        if set(inputs.rows) - {"", table.name}:
            return None
        gone = _left_out(_selection(self.inputs, table.name), _selection(inputs, table.name),
                         table.numbers)
        if gone is None:
            return None
        return [k for k, n in enumerate(table.numbers, 1) if n not in gone]

    def _reusing(self, load: Loader) -> Loader:
        """`load`, but this problem for its own inputs, and the last program loaded again for
        the same inputs (a solve with outliers asks for the rows without its certain
        outliers twice in a row); one program at a time is kept, as a large one is large."""
        last: list[tuple[Inputs, tuple[Model, Program]]] = []

        def run(inputs: Inputs) -> tuple[Model, Program]:
            if self.asks_for(inputs):
                return self.model, self.program
            if last and _same(last[0][0], inputs):
                return last[0][1]
            last[:] = [(inputs, load(inputs))]
            return last[0][1]

        return run


def _pair(p: Problem) -> tuple[Model, Program]:
    return p.model, p.program


def _selection(inputs: Inputs, table: str) -> Selection | None:
    """The command line's selection of the (one) table, as the elaborator reads it."""
    return inputs.rows.get(table) or inputs.rows.get("")


def _left_out(old: Selection | None, new: Selection | None,
              numbers: list[int]) -> set[int] | None:
    """The data row numbers of `numbers` (what `old` selects) that `new` leaves out, when
    `new` selects a subset of them: `old`'s ranges with more rows excluded, or rows named
    one by one (each among `numbers`); None otherwise."""
    if new is None:
        return None
    have = set(numbers)
    if new.ranges == (old.ranges if old is not None else ()):
        before = set(old.excluded) if old is not None else set()
        gone = set(new.excluded) - before
        return gone if before <= set(new.excluded) and gone <= have else None
    if new.excluded or not all(r.last == r.first for r in new.ranges):
        return None
    named = {r.first for r in new.ranges}
    return have - named if named <= have else None


def _same_but(a: Inputs, b: Inputs, name: str) -> bool:
    """Whether two requests agree in every field but `name` (a field added later counts)."""
    return all(_same(getattr(a, f.name), getattr(b, f.name)) for f in fields(a)
               if f.name != name)


def _same(a: object, b: object) -> bool:
    try:
        return bool(a == b)
    except (TypeError, ValueError):  # (cells given as arrays: compared by identity)
        return a is b
