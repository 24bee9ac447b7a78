"""Shared fixtures for the compiler back-half, propagator and CLI tests: write a small `.cal`
model into a temporary directory, compile it, find the installed `calibc` command."""

from __future__ import annotations

import math
import os
import shutil
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import settings

# Each pytest-xdist worker takes a core: the solver's own threads and piece processes (two
# each on two cores) would only contend with the other worker's (results do not depend on
# them). Set before calib_dsl is imported (settings.CORES); `calibc` subprocesses inherit it.
if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ.setdefault("CALIBC_CORES", "1")

from calib_dsl.compile.group import compile_model  # noqa: E402
from calib_dsl.elaborate.elaborator import elaborate  # noqa: E402
from calib_dsl.ir.program import Program  # noqa: E402

# `make test` (and so CI) draws the same pseudo-random cases on every run and machine, so a run
# that passed here passes there; `make test-random` (HYPOTHESIS_PROFILE=random) draws fresh ones.
settings.register_profile("fixed", derandomize=True, print_blob=True)
settings.register_profile("random", print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "fixed"))


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--examples-share", type=float, default=1.0, metavar="S",
        help="run each property on this share of its examples (at least one): `make "
             "test-fast` runs a quarter, `make test` every example")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The editing loop's share of every property's examples: its cost is the examples,
    not the test's count. Each function is scaled once (parametrized items share it)."""
    share = config.getoption("examples_share")
    if share >= 1:
        return
    for item in items:
        test = getattr(getattr(item, "obj", None), "__func__", getattr(item, "obj", None))
        if not getattr(test, "is_hypothesis_test", False) or getattr(test, "_calibc_share", 0):
            continue
        full = test._hypothesis_internal_use_settings
        test._hypothesis_internal_use_settings = settings(
            full, max_examples=max(1, math.ceil(full.max_examples * share)))
        test._calibc_share = share


@pytest.fixture
def write_model(tmp_path: Path) -> Callable[..., Path]:
    """write_model(source, name="m.cal", files={"d.csv": text}) -> the model's path; `files`
    are written beside it."""

    def write(source: str, name: str = "m.cal", files: dict[str, str] | None = None) -> Path:
        for fname, text in (files or {}).items():
            (tmp_path / fname).write_text(text, encoding="utf-8")
        path = tmp_path / name
        path.write_text(source, encoding="utf-8")
        return path

    return write


@pytest.fixture
def compile_src(write_model: Callable[..., Path]) -> Callable[..., Program]:
    """compile_src(source, formulation="matrix", files=None) -> the flat program."""

    def run(source: str, formulation: str = "matrix",
            files: dict[str, str] | None = None) -> Program:
        return compile_model(elaborate(write_model(source, files=files), formulation=formulation))

    return run


@pytest.fixture(scope="session")
def calibc() -> list[str]:
    """The installed `calibc` console script: the one beside this interpreter (a venv's),
    else the one on PATH."""
    here = Path(sys.executable).parent / "calibc"
    if here.exists():
        return [str(here)]
    found = shutil.which("calibc")
    if found is None:
        pytest.fail("the `calibc` command is not installed (pip install -e .)")
    return [found]


def _untimed(doc):
    """A result document without its timings (every "seconds" key, at any depth) and its
    provenance (the command line, the date, the machine), which differ from run to run."""
    if isinstance(doc, dict):
        return {k: _untimed(v) for k, v in doc.items() if k not in ("seconds", "provenance")}
    if isinstance(doc, list):
        return [_untimed(v) for v in doc]
    return doc


@pytest.fixture
def untimed():
    return _untimed
