"""The suite's soundness properties at their full example counts: tests/ runs each on a share
of its examples (quick enough for `make test-fast`), these run the same test bodies on the
same strategies with the counts they had in the suite before (a different seed, so the
suite's examples add to these). A failure here is a lost solution."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings

from tests.propagate import test_soundness_propagation as props

SLOW = [HealthCheck.too_slow]


@settings(max_examples=1200, deadline=None, suppress_health_check=SLOW)
@given(**props.CASES)
def test_propagation_keeps_the_point(trees, point, widths, relations, tol):
    props.test_propagation_keeps_the_point.hypothesis.inner_test(trees, point, widths,
                                                                 relations, tol)


@settings(max_examples=250, deadline=None, suppress_health_check=SLOW)
@given(**props.CASES)
def test_tight_strategy_keeps_the_point(trees, point, widths, relations, tol):
    props.test_tight_strategy_keeps_the_point.hypothesis.inner_test(trees, point, widths,
                                                                    relations, tol)


@settings(max_examples=300, deadline=None, suppress_health_check=SLOW)
@given(**props.BOXES)
def test_propagation_from_a_smaller_box(trees, point, widths, relations, box):
    props.test_propagation_from_a_smaller_box.hypothesis.inner_test(trees, point, widths,
                                                                    relations, box)


@settings(max_examples=300, deadline=None,
          suppress_health_check=[*SLOW, HealthCheck.filter_too_much])
@given(**props.LANGUAGE)
def test_language_models_keep_the_point(trees, point, widths, relations):
    props.test_language_models_keep_the_point.hypothesis.inner_test(trees, point, widths,
                                                                    relations)
