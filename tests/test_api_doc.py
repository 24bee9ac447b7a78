"""docs/api.md runs: every example of the Python API's guide is a doctest, run from the
repository's root (as `python -m doctest docs/api.md` runs them), so the guide cannot drift
from the code."""

from __future__ import annotations

import doctest
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_the_api_guide_runs_as_doctests(monkeypatch):
    monkeypatch.chdir(ROOT)  # the guide's paths are the repository's
    result = doctest.testfile(str(ROOT / "docs" / "api.md"), module_relative=False,
                              report=True)
    assert result.attempted >= 40  # the examples were found and run
    assert result.failed == 0
