"""A `calibc solve` elaborates its model once (calib_dsl/problem.py): every part of the report
(the verdict, the conflict search, the solve with outliers, the residuals) asks the loaded
problem for programs, which gives itself for its own inputs; the same model with other
inputs (rows left out) is elaborated once per set of inputs."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

import calib_dsl.problem as problem_module
from calib_dsl.cli import main
from calib_dsl.elaborate.elaborator import Inputs

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


def distinct(seen: list[Inputs]) -> bool:
    return all(a != b for i, a in enumerate(seen) for b in seen[i + 1:])


def test_a_solve_with_every_section_elaborates_once(monkeypatch):
    code, seen = elaborations(monkeypatch, [str(ARM), "--residuals", "--lsq", "--inner"])
    assert code == 0 and len(seen) == 1


def faulty(tmp_path: Path) -> Path:
    """RX90's data with one coordinate of row 17 moved by 1 cm: proven inconsistent."""
    lines = (ROOT / "models" / "data" / "rx90_50.csv").read_text().splitlines()
    j = lines[0].split(",").index("a1x")
    cells = lines[17].split(",")
    cells[j] = repr(float(cells[j]) + 0.01)
    lines[17] = ",".join(cells)
    out = tmp_path / "faulty.csv"
    out.write_text("\n".join(lines) + "\n")
    return out


@pytest.mark.slow
@pytest.mark.parametrize("more", [[], ["--outliers", "1"]])
def test_the_diagnosis_and_the_outliers_load_the_model_once(tmp_path, monkeypatch, more):
    """Inconsistent data, diagnosed (the rows at fault named) or solved with an outlier: the
    model with the command's inputs is elaborated once; the diagnosis elaborates no other
    set of inputs twice (the solve with outliers may: the rows without its certain outlier
    are one of its sets, and its final solve, and only the last program is kept)."""
    data = faulty(tmp_path)
    code, seen = elaborations(monkeypatch, [str(RX90), "--data", str(data), *more])
    assert code == (1 if not more else 0)
    given = seen[0]
    assert [s == given for s in seen].count(True) == 1
    assert len(seen) > 1  # (the rows left out: other inputs)
    assert distinct(seen) or more
