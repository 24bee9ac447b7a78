"""A model loaded once: parsed, elaborated with its inputs, compiled (and its `lsq +- w`
domains centred on the data's least-squares estimate, the only least squares a load runs).

Everything a solve reports about the same model and data works on this one `Problem`: the
pipeline, the verdict's proofs, the conflict search, the solve with outliers and the
residuals ask it for programs (`loader`, `pinned_loader`), and it gives itself for its own
inputs instead of elaborating the model again. The same model with other inputs (some rows
left out, a const set) is elaborated anew, once per set of inputs asked for.
"""

from __future__ import annotations

import gc
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

from calib_dsl.analysis.priors import centre_on_least_squares
from calib_dsl.compile.group import compile_model
from calib_dsl.elaborate.elaborator import Inputs, elaborate
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program
from calib_dsl.outliers.proof import pinned

Loader = Callable[[Inputs], tuple[Model, Program]]


def load_model(model: str | Path, formulation: str = "matrix", data: str | Path | None = None,
               inputs: Inputs | None = None, centre: bool = True) -> tuple[Model, Program]:
    """Parse, elaborate and compile a `.cal` model, with the elaborated model (its tables and
    consts); `centre=False` leaves `lsq +- w` domains unbounded (for a caller that gives
    them another program's)."""
    # The DAG's nodes live as long as the program: the garbage collector would only rescan
    # them (about 0.5 s at 1000 configurations), so it pauses while they are built.
    gc.disable()
    try:
        elaborated = elaborate(model, formulation=formulation, data=data, inputs=inputs)
        prog = compile_model(elaborated)
    finally:
        gc.enable()
    if centre:
        centre_on_least_squares(prog)  # `param x in lsq +- w`: domains around the data's estimate
    return elaborated, prog


@dataclass(frozen=True, eq=False)  # (its program's arrays have no single truth value)
class Problem:
    """A model loaded: parsed, elaborated with its inputs, compiled."""

    path: str
    formulation: str
    inputs: Inputs
    model: Model  # the elaborated model: its tables, consts, DAG
    program: Program  # the flat program the solvers work on

    @classmethod
    def load(cls, path: str | Path, formulation: str = "matrix",
             inputs: Inputs | None = None) -> Problem:
        inputs = inputs or Inputs()
        model, prog = load_model(path, formulation, inputs=inputs)
        return cls(str(path), formulation, inputs, model, prog)

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

    def loader(self) -> Loader:
        """The model loaded with other inputs; this problem itself for its own."""
        return self._reusing(lambda i: load_model(self.path, self.formulation, inputs=i))

    def pinned_loader(self) -> Loader:
        """The model loaded with other inputs on this program's domains (a proof about other
        rows must hold on the same box: outliers/proof.py's `pinned`); this problem itself
        for its own inputs."""
        return self._reusing(pinned(lambda i: load_model(self.path, self.formulation,
                                                         inputs=i, centre=False),
                                    self.program))

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


def _same(a: Inputs, b: Inputs) -> bool:
    try:
        return bool(a == b)
    except (TypeError, ValueError):  # (cells given as arrays: compared by identity)
        return a is b
