"""A `calibc solve` elaborates its model once (calib_dsl/problem.py): every part of the report
(the verdict, the conflict search, the solve with outliers, the residuals) asks the loaded
problem for programs, which gives itself for its own inputs and derives the same model
without some rows from the elaborated one (elaborate/subset.py) where the model allows:
the derived program is the one elaborating anew would give, array for array."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import calib_dsl.problem as problem_module
from calib_dsl.cli import main
from calib_dsl.elaborate.elaborator import Elaborator, Inputs
from calib_dsl.elaborate.subset import derivable
from calib_dsl.outliers.proof import only
from calib_dsl.outliers.rows import Row, excluding
from calib_dsl.problem import Problem, load_model
from tests.table_cells import moved_cell

ROOT = Path(__file__).resolve().parent.parent
ARM = ROOT / "models" / "examples" / "planar_arm.cal"
RX90 = ROOT / "models" / "rx90_lengths.cal"


def elaborations(monkeypatch, args: list[str]) -> tuple[int, list[Inputs]]:
    """The exit code of `calibc solve ARGS` and the inputs of every elaboration it made."""
    seen: list[Inputs] = []
    real = problem_module.elaborate

    def counted(path, **kwargs):
        seen.append(kwargs.get("inputs") or Inputs())
        return real(path, **kwargs)

    monkeypatch.setattr(problem_module, "elaborate", counted)
    out = CliRunner().invoke(main, ["solve", "-q", "--shave", "0", *args])
    assert out.exception is None or isinstance(out.exception, SystemExit), out.output
    return out.exit_code, seen


def test_a_solve_with_every_section_elaborates_once(monkeypatch):
    code, seen = elaborations(monkeypatch, [str(ARM), "--residuals", "--lsq", "--inner"])
    assert code == 0 and len(seen) == 1


def arm_with_a_faulty_row(tmp_path: Path) -> Path:
    """The planar arm's data with row 3's x moved by 1 cm: proven inconsistent."""
    out = tmp_path / "faulty_arm.csv"
    out.write_text(moved_cell((ARM.parent / "planar_arm.csv").read_text(), 3, "x", 0.01))
    return out


def counting(monkeypatch) -> list[int]:
    """A counter of the elaborations from now on (every one is an `Elaborator`), wherever
    they come from."""
    count = [0]
    real = Elaborator.__init__

    def counted(self, *args, **kwargs):
        count[0] += 1
        real(self, *args, **kwargs)

    monkeypatch.setattr(Elaborator, "__init__", counted)
    return count


def every_elaboration(monkeypatch, args: list[str]) -> tuple[int, int]:
    """The exit code of `calibc solve ARGS` and how many times any model was elaborated."""
    count = counting(monkeypatch)
    out = CliRunner().invoke(main, ["solve", "-q", "--shave", "0", *args])
    assert out.exception is None or isinstance(out.exception, SystemExit), out.output
    return out.exit_code, count[0]


@pytest.mark.parametrize("more, code", [
    ([], 0),
    (["--residuals"], 0),
    (["--min-error", "e"], 0),  # every trial's bound set on the cells
    (["FAULTY"], 1),  # inconsistent: diagnosed, the rows at fault named
    (["FAULTY", "--outliers", "1"], 0),  # a row proven an outlier, then the solve without it
])
def test_a_solve_elaborates_its_model_once(tmp_path, monkeypatch, more, code):
    args = [str(ARM)] + [a for a in more if a != "FAULTY"]
    if "FAULTY" in more:
        args += ["--data", str(arm_with_a_faulty_row(tmp_path))]
    assert every_elaboration(monkeypatch, args) == (code, 1)


def same_program(a, b) -> None:
    sa, sb = a.slots, b.slots
    assert list(sa.names) == list(sb.names) and list(sa.kinds) == list(sb.kinds)
    assert np.array_equal(sa.lo, sb.lo) and np.array_equal(sa.hi, sb.hi)
    assert sa.row_keys == sb.row_keys and sa.col_keys == sb.col_keys
    assert np.array_equal(sa.cell_row, sb.cell_row) and np.array_equal(sa.cell_col, sb.cell_col)
    assert sa.measured_sides == sb.measured_sides and sa.declared == sb.declared
    assert list(a.primitives) == list(b.primitives) and len(a.groups) == len(b.groups)
    for g, h in zip(a.groups, b.groups, strict=True):
        assert (g.op, g.level) == (h.op, h.level)
        assert all(np.array_equal(getattr(g, f), getattr(h, f)) for f in ("out", "args", "prim"))
    assert (a.tables, a.centred, a.domains) == (b.tables, b.centred, b.domains)
    assert (a.rows is None) == (b.rows is None)
    assert a.rows is None or np.array_equal(a.rows.rows, b.rows.rows)


@pytest.mark.parametrize("path", [ARM, RX90, pytest.param(ROOT / "models" / "rx90_full.cal",
                                                         marks=pytest.mark.slow)])
def test_rows_left_out_are_derived_as_elaborating_anew_gives(monkeypatch, path):
    """Rows left out (as --exclude does), or named (as the outlier proofs do), of the first
    rows, the last, every other: the derived program is the elaborated one, array for array,
    and no elaboration ran for it."""
    problem = Problem.load(path)
    assert derivable(problem.model)
    t = problem.model.tables[0]
    n = len(t.numbers)
    asked = [excluding(problem.inputs, [Row(t.name, t.path, 0, 1)], t.name),
             excluding(problem.inputs, [Row(t.name, t.path, 0, r) for r in (2, n)], t.name),
             only(problem.inputs, problem.model, [1, 3, 4, n]),
             only(problem.inputs, problem.model,
                  [k for k in range(1, n + 1) if k % 2 == 0 or k == n])]
    for inputs in asked:
        expected = load_model(path, inputs=inputs)
        count = counting(monkeypatch)
        derived = problem.derive(inputs)
        monkeypatch.undo()
        assert count == [0]
        same_program(derived.program, expected[1])
        assert derived.model.tables[0].numbers == expected[0].tables[0].numbers
        assert derived.model.tables[0].lines == expected[0].tables[0].lines
        again = excluding(inputs, [Row(t.name, t.path, 0, derived.model.tables[0].numbers[-1])],
                          t.name)  # a derived problem derives in turn
        same_program(derived.derive(again).program, load_model(path, inputs=again)[1])


def test_what_the_model_does_not_allow_is_elaborated_anew(tmp_path):
    """rows(t) read beside the loop, or fewer rows than a loop compiled once needs: the
    model is elaborated again (and the result is still what elaborating gives)."""
    text = ARM.read_text().replace("p[3] == 0;", "p[3] == 0 * rows(m);")
    (tmp_path / "arm.cal").write_text(text)
    for name in ("planar_arm_robot.cal", "planar_arm.csv"):
        (tmp_path / name).write_text((ARM.parent / name).read_text())
    assert not derivable(Problem.load(tmp_path / "arm.cal").model)
    problem = Problem.load(ARM)
    two = only(problem.inputs, problem.model, [1, 2])
    derived = problem.derive(two)
    assert derived.program.rows is None and len(derived.model.tables[0].numbers) == 2


@pytest.mark.parametrize("path", [ARM, pytest.param(ROOT / "models" / "ur10_tracker.cal",
                                                  marks=pytest.mark.slow)])
def test_an_error_bound_set_is_derived_as_elaborating_anew_gives(monkeypatch, path):
    """A const read only as columns' error bound (`x, y : +- e`), set to other values (as
    --min-error's trials do): the cells' bounds change, and the program is the elaborated
    one, with no elaboration."""
    problem = Problem.load(path)
    assert "e" in problem.model.tolerances
    # three values on the small arm; the UR10's three elaborations cost as much as the rest of
    # the file, so it checks the value with the least exact float only
    values = ("1/3000", "2e-3", "12345/10000000000") if path == ARM else ("12345/10000000000",)
    for value in values:
        model, prog = load_model(path, inputs=replace(problem.inputs, consts={"e": value}))
        count = counting(monkeypatch)
        derived = problem.with_const(e=value)
        monkeypatch.undo()
        assert count == [0]
        same_program(derived.program, prog)
        assert derived.model.consts == model.consts
        for mine, theirs in zip(derived.model.tables, model.tables, strict=True):
            assert [c.tol for c in mine.columns] == [c.tol for c in theirs.columns]
            for c, (lo, hi) in theirs.bounds.items():
                assert np.array_equal(mine.bounds[c][0], lo)
                assert np.array_equal(mine.bounds[c][1], hi)


def test_a_const_read_elsewhere_is_elaborated_anew(monkeypatch):
    """RX90's `known` sets parameters' domains: setting it elaborates the model again."""
    problem = Problem.load(RX90)
    assert "known" in problem.model.consts and "known" not in problem.model.tolerances
    count = counting(monkeypatch)
    derived = problem.with_const(known="2e-5")
    monkeypatch.undo()
    assert count == [1]
    same_program(derived.program,
                 load_model(RX90, inputs=Inputs(consts={"known": "2e-5"}))[1])


def held_out(tmp_path: Path, measured: bool) -> Path:
    """Planar-arm configurations the calibration did not use (its own rows' joints, moved),
    with or without the measured columns (a prediction needs none)."""
    lines = (ARM.parent / "planar_arm.csv").read_text().splitlines()
    out = ["q1,q2,x,y" if measured else "q1,q2"]
    for k, line in enumerate(lines[1:9]):
        q1, q2, x, y = line.split(",")
        q = f"{float(q1) + 0.01 * k!r},{float(q2) - 0.02 * k!r}"
        out.append(f"{q},{x},{y}" if measured else q)
    path = tmp_path / ("held.csv" if measured else "joints.csv")
    path.write_text("\n".join(out) + "\n")
    return path


@pytest.mark.parametrize("measured", [True, False])
def test_a_table_read_from_another_file_is_derived_as_elaborating_gives(tmp_path, monkeypatch,
                                                                        measured):
    """Another file's rows as the table's (held-out configurations, their measurements
    absent or not): the derived program is the one the model elaborated with the file
    gives, array for array (the absent columns read as 0), with no elaboration."""
    from calib_dsl.accuracy.predict import Source, _derived, _present

    problem = Problem.load(ARM)
    at = held_out(tmp_path, measured)
    t = problem.model.tables[0]
    source = Source(problem.path, problem.formulation, problem.inputs, problem.model,
                    problem.with_table)
    _, present = _present(at, t)
    count = counting(monkeypatch)
    derived = _derived(source, at, t, present, None)
    monkeypatch.undo()
    assert count == [0] and derived is not None
    model, prog = derived
    if not measured:  # the file the elaborator reads: the same, its measurements 0
        text = at.read_text().splitlines()
        at.write_text("\n".join([text[0] + ",x,y", *(f"{ln},0,0" for ln in text[1:])]) + "\n")
    expected = load_model(ARM, inputs=Inputs(data={"m": str(at)}), centre=False)
    same_program(prog, expected[1])
    assert model.tables[0].numbers == expected[0].tables[0].numbers
    assert model.tables[0].lines == expected[0].tables[0].lines


def test_predict_elaborates_its_model_once(tmp_path, monkeypatch):
    """`calibc predict --at`: the calibration's model is elaborated once, and the held-out
    configurations' model derived from it."""
    count = counting(monkeypatch)
    at = held_out(tmp_path, measured=False)
    out = CliRunner().invoke(main, ["predict", "-q", str(ARM), "--at", str(at), "--json",
                                    str(tmp_path / "p.json")])
    assert out.exit_code == 0, out.output
    assert count == [1]


def test_a_problem_keeps_the_fit_that_centred_its_lsq_domains():
    """`Problem.load` keeps the least-squares estimate that centred its `lsq +- w` domains
    with its rows: the program's own at that point, bit for bit (the accuracy statement
    starts there without evaluating them again), inside the centred domains; a problem on
    another's domains, or without `lsq +- w` parameters, keeps none."""
    from calib_dsl.analysis.lsq import linearized
    from calib_dsl.relax.layout import independents

    problem = Problem.load(ROOT / "models" / "ur10_simulated.cal")
    prog, fit = problem.program, problem.fit
    assert fit is not None and fit.converged and fit.rows is not None
    ind = independents(prog)
    assert np.all((prog.slots.lo[ind] <= fit.values) & (fit.values <= prog.slots.hi[ind]))
    for name, (v, _) in prog.centred.items():
        assert fit.values[fit.names.index(name)] == v
    lin = linearized(prog, fit.values, owners=False)
    assert np.array_equal(lin.d, fit.rows.d) and np.array_equal(lin.jac, fit.rows.jac)
    assert problem.keeping_priors().fit is fit
    assert problem.on_domains(prog).fit is None
    assert Problem.load(ARM).fit is None
