"""`--examples-share` (tests/conftest.py, `make test-fast`): each hypothesis property runs on
that share of its examples, at least one, scaled once however many items share the function;
without the option every example runs."""

from __future__ import annotations

from types import SimpleNamespace

from hypothesis import given, settings
from hypothesis import strategies as st

from tests.conftest import pytest_collection_modifyitems


def _property(max_examples: int):
    seen: list[int] = []

    @settings(max_examples=max_examples, database=None)
    @given(st.integers())
    def prop(x: int) -> None:
        seen.append(x)

    return prop, seen


def _collect(share: float, *objs) -> None:
    config = SimpleNamespace(getoption=lambda name: share)
    pytest_collection_modifyitems(config, [SimpleNamespace(obj=o) for o in objs])


def test_a_quarter_of_the_examples_once_for_items_sharing_a_function():
    prop, seen = _property(40)
    _collect(0.25, prop, prop, lambda: None)
    prop()
    assert len(seen) == 10


def test_at_least_one_example():
    prop, seen = _property(3)
    _collect(0.25, prop)
    prop()
    assert len(seen) == 1


def test_every_example_without_the_option():
    prop, seen = _property(12)
    _collect(1.0, prop)
    prop()
    assert len(seen) == 12
