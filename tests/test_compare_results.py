"""scripts/compare_results.py's comparison: what counts as a difference, what as a field
added since the base, and the base CI compares against."""

from __future__ import annotations

import importlib.util
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _script():
    spec = importlib.util.spec_from_file_location("compare_results",
                                                  ROOT / "scripts" / "compare_results.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_added_fields_are_listed_not_counted():
    c = _script()
    base = {"a": 1, "p": [{"x": 1.0}], "gone": 2}
    mine = {"a": 1, "p": [{"x": 1.0, "new": 3}], "extra": {"y": 0}}
    assert c.differences(base, mine) == [".extra: only in one", ".gone: only in one",
                                         ".p[0].new: only in one"]
    added: list[str] = []
    assert c.differences(base, mine, "", added) == [".gone: only in one"]
    assert added == [".extra", ".p[0].new"]
    assert c.differences({"a": 1.0}, {"a": 1.0 + 2**-52}, "", []) != []  # bit for bit


def test_the_shipped_ur5_models_are_compared():
    c = _script()
    assert {"ur5_tracker", "ur5_simulated"} <= set(c.CASES)
    for args in c.CASES.values():
        model = next(a for a in args if a.endswith(".cal"))
        assert (ROOT / model).is_file(), model


def test_the_ci_base_is_a_revision_or_a_reason():
    c = _script()
    base, why = c.auto_base()
    parent = subprocess.run(["git", "rev-parse", "--verify", "-q", "HEAD~1"], cwd=ROOT,
                            capture_output=True, text=True).returncode == 0
    if base is None:
        assert not parent and why
    else:
        assert subprocess.run(["git", "cat-file", "-e", base], cwd=ROOT).returncode == 0
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                              text=True).stdout.strip()
        assert base != head and why
