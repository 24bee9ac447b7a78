"""The model elaborated once by a solve that diagnoses inconsistent data or proves an outlier,
on a model of the paper's size (Test A, 50 rows): too heavy for `make test`, where
tests/test_problem.py counts the elaborations of the same commands on the planar arm."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.table_cells import moved_cell
from tests.test_problem import ROOT, RX90, elaborations


def faulty(tmp_path: Path) -> Path:
    """RX90's data with one coordinate of row 17 moved by 1 cm: proven inconsistent."""
    out = tmp_path / "faulty.csv"
    out.write_text(moved_cell((ROOT / "models" / "data" / "rx90_50.csv").read_text(), 17,
                              "a1x", 0.01))
    return out


@pytest.mark.parametrize("more", [[], ["--outliers", "1"]])
def test_the_diagnosis_and_the_outliers_load_the_model_once(tmp_path, monkeypatch, more):
    """Inconsistent data, diagnosed (the rows at fault named) or solved with an outlier: the
    model is elaborated once, with the command's inputs; every set of rows the diagnosis, the
    proofs and the solve ask for is derived."""
    data = faulty(tmp_path)
    code, seen = elaborations(monkeypatch, [str(RX90), "--data", str(data), *more])
    assert code == (1 if not more else 0)
    assert len(seen) == 1 and seen[0].data == {"": str(data)}
