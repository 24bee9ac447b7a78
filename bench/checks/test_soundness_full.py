"""The suite's soundness properties at their full example counts: tests/ runs each on a share
of its examples (quick enough for `make test-fast`), these run the same test bodies on the
same strategies with the counts they had in the suite before (a different seed, so the
suite's examples add to these). A failure here is a lost solution."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.accuracy import test_batch_lp as batch_lp
from tests.accuracy import test_corrections as corrections
from tests.accuracy import test_second_order as second_order
from tests.accuracy.test_second_order import spy  # noqa: F401, F811  (a fixture)
from tests.arith import test_projections as projections
from tests.compile import test_rows as rows_once
from tests.inner import test_inner_bounds as inner
from tests.inner import test_shave as shave
from tests.lp import test_lpbound as lpbound
from tests.plan import test_plan as planning
from tests.propagate import test_soundness_propagation as props
from tests.relax import test_linearize as linearize
from tests.relax import test_taylor as taylor
from tests.strategy import test_verdict_redundant as redundant
from tests.studies import test_campaign as campaigns

SLOW = [HealthCheck.too_slow]


@settings(max_examples=1200, deadline=None, suppress_health_check=SLOW)
@given(**props.CASES)
def test_propagation_keeps_the_point(trees, point, widths, relations, tol):
    props.test_propagation_keeps_the_point.hypothesis.inner_test(
        trees, point, widths, relations, tol
    )


@settings(max_examples=250, deadline=None, suppress_health_check=SLOW)
@given(**props.CASES)
def test_tight_strategy_keeps_the_point(trees, point, widths, relations, tol):
    props.test_tight_strategy_keeps_the_point.hypothesis.inner_test(
        trees, point, widths, relations, tol
    )


@settings(max_examples=300, deadline=None, suppress_health_check=SLOW)
@given(**props.BOXES)
def test_propagation_from_a_smaller_box(trees, point, widths, relations, box):
    props.test_propagation_from_a_smaller_box.hypothesis.inner_test(
        trees, point, widths, relations, box
    )


@settings(
    max_examples=300, deadline=None, suppress_health_check=[*SLOW, HealthCheck.filter_too_much]
)
@given(**props.LANGUAGE)
def test_language_models_keep_the_point(trees, point, widths, relations):
    props.test_language_models_keep_the_point.hypothesis.inner_test(trees, point, widths, relations)


@pytest.mark.parametrize("op", projections.ALL_OPS)
@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_sound(op, seed):
    projections.test_sound.hypothesis.inner_test(op, seed)


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_atan2_near_optimal(seed):
    projections.test_atan2_near_optimal.hypothesis.inner_test(seed)


@lpbound.SETTINGS
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 5),
    m=st.integers(0, 7),
    unbounded=st.booleans(),
    nuisance=st.integers(0, 2),
    solver=lpbound.SOLVERS,
)
def test_lp_bounds_bracket_known_optimum_and_feasible_points(
    seed, n, m, unbounded, nuisance, solver
):
    lpbound.test_lp_bounds_bracket_known_optimum_and_feasible_points.hypothesis.inner_test(
        seed, n, m, unbounded, nuisance, solver
    )


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), m=st.integers(1, 8), infinite=st.booleans()
)
def test_certified_max_random_float_lps(seed, n, m, infinite):
    lpbound.test_certified_max_random_float_lps.hypothesis.inner_test(seed, n, m, infinite)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 5),
    m=st.integers(1, 7),
    infinite=st.booleans(),
    solver=lpbound.SOLVERS,
)
def test_lp_bounds_bracket_random_feasible_points(seed, n, m, infinite, solver):
    lpbound.test_lp_bounds_bracket_random_feasible_points.hypothesis.inner_test(
        seed, n, m, infinite, solver
    )


@settings(
    max_examples=120,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(8, 14), m=st.integers(1, 10))
def test_probe_points_change_no_bound(seed, n, m, monkeypatch):
    lpbound.test_probe_points_change_no_bound.hypothesis.inner_test(seed, n, m, monkeypatch)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), m=st.integers(1, 8), solver=lpbound.SOLVERS
)
def test_two_sided_rows_certify_with_signed_multipliers(seed, n, m, solver):
    lpbound.test_two_sided_rows_certify_with_signed_multipliers.hypothesis.inner_test(
        seed, n, m, solver
    )


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), m=st.integers(1, 8), solver=lpbound.SOLVERS
)
def test_reused_multipliers_bound_every_feasible_point_of_another_box(seed, n, m, solver):
    lpbound.test_reused_multipliers_bound_every_feasible_point_of_another_box.hypothesis.inner_test(
        seed, n, m, solver
    )


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 5),
    m=st.integers(10, 120),
    two_sided=st.booleans(),
    solver=lpbound.SOLVERS,
    primal=st.booleans(),
)
def test_row_generation_gives_the_full_lps_bounds(seed, n, m, two_sided, solver, primal):
    lpbound.test_row_generation_gives_the_full_lps_bounds.hypothesis.inner_test(
        seed, n, m, two_sided, solver, primal
    )


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), m=st.integers(10, 80), primal=st.booleans()
)
def test_row_generation_from_the_last_rounds_binding_rows(seed, n, m, primal):
    lpbound.test_row_generation_from_the_last_rounds_binding_rows.hypothesis.inner_test(
        seed, n, m, primal
    )


@settings(
    max_examples=70,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_p=st.integers(1, 4),
    n_cfg=st.integers(0, 3),
    n_col=st.integers(1, 3),
    n_con=st.integers(1, 5),
    depth=st.integers(1, 4),
    shrink=st.booleans(),
    models=st.integers(1, 10),
)
def test_relaxation_holds_at_solutions_of_random_expression_models(
    seed, n_p, n_cfg, n_col, n_con, depth, shrink, models
):
    linearize.test_relaxation_holds_at_solutions_of_random_expression_models.hypothesis.inner_test(
        seed, n_p, n_cfg, n_col, n_con, depth, shrink, models
    )


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    n_p=st.integers(2, 5),
    n_cfg=st.integers(1, 4),
    n_con=st.integers(2, 8),
    models=st.integers(1, 6),
)
def test_relaxation_holds_on_linear_and_polynomial_models(seed, n_p, n_cfg, n_con, models):
    linearize.test_relaxation_holds_on_linear_and_polynomial_models.hypothesis.inner_test(
        seed, n_p, n_cfg, n_con, models
    )


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**31 - 1),
    joints=st.integers(1, 3),
    rows=st.integers(1, 6),
    spatial=st.booleans(),
    formulation=st.sampled_from(["matrix", "rotation"]),
    tol_q=st.sampled_from([1e-6, 1e-4, 0.01]),
    tol_x=st.sampled_from([1e-5, 1e-3]),
)
def test_relaxation_holds_on_random_robots(
    tmp_path_factory, seed, joints, rows, spatial, formulation, tol_q, tol_x
):
    linearize.test_relaxation_holds_on_random_robots.hypothesis.inner_test(
        tmp_path_factory, seed, joints, rows, spatial, formulation, tol_q, tol_x
    )


@settings(max_examples=1000, deadline=None)
@given(
    data=st.data(),
    rows=st.integers(1, 4),
    cols=st.integers(1, 3),
    args=st.integers(1, 3),
    mixed=st.booleans(),
)
def test_chain_rule_products_enclose_every_product_of_members(data, rows, cols, args, mixed):
    linearize.test_chain_rule_products_enclose_every_product_of_members.hypothesis.inner_test(
        data, rows, cols, args, mixed
    )


@settings(max_examples=1000, deadline=None)
@given(
    data=st.data(),
    rows=st.integers(1, 4),
    cols=st.integers(1, 3),
    signs=st.lists(st.sampled_from([1.0, -1.0]), min_size=1, max_size=3),
)
def test_signed_sums_enclose_every_sum_of_members(data, rows, cols, signs):
    linearize.test_signed_sums_enclose_every_sum_of_members.hypothesis.inner_test(
        data, rows, cols, signs
    )


@settings(max_examples=12, deadline=None,
          suppress_health_check=[*SLOW, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), joints=st.integers(1, 3), rows=st.integers(3, 9),
       formulation=st.sampled_from(["matrix", "rotation"]))
def test_a_loop_compiled_once_is_the_unrolled_program(tmp_path_factory, seed, joints, rows,
                                                      formulation):
    rows_once.test_a_loop_compiled_once_is_the_unrolled_program.hypothesis.inner_test(
        tmp_path_factory, seed, joints, rows, formulation
    )


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(robot=st.sampled_from(["arm4_dh.cal", "arm5_mdh.cal"]),
       poses=st.sampled_from(["random", "grid", "repeated"]),
       rows=st.integers(8, 24), seed=st.integers(0, 10**6))
def test_consistent_campaigns_of_other_robots_are_never_refuted(tmp_path_factory, robot, poses,
                                                                rows, seed):
    redundant.test_consistent_campaigns_of_other_robots_are_never_refuted.hypothesis.inner_test(
        tmp_path_factory, robot, poses, rows, seed
    )


@settings(max_examples=4, deadline=None)
@given(amplitude=st.floats(0.2, 1.5), noise=st.sampled_from([0.0, 0.05]),
       shape=st.sampled_from(campaigns.POSES), seed=st.integers(0, 1000),
       margin=st.floats(1.0, 1.3))
def test_the_truth_lies_inside_a_solve_of_systematic_data(tmp_path_factory, amplitude, noise,
                                                          shape, seed, margin):
    campaigns.test_the_truth_lies_inside_a_solve_of_systematic_data.hypothesis.inner_test(
        tmp_path_factory, amplitude, noise, shape, seed, margin
    )


@given(st.integers(0, 10_000), st.integers(3, 8))
@settings(max_examples=8, deadline=None, suppress_health_check=list(HealthCheck))
def test_the_truth_lies_inside_every_simulated_solve(tmp_path_factory, seed, count):
    planning.test_the_truth_lies_inside_every_simulated_solve.hypothesis.inner_test(
        tmp_path_factory, seed, count
    )


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2 ** 31), st.integers(12, 60))
def test_bounds_hold_the_relaxations_points(seed, n):
    batch_lp.test_bounds_hold_the_relaxations_points.hypothesis.inner_test(seed, n)


@settings(max_examples=4, deadline=None)
@given(st.integers(0, 2 ** 31))
def test_the_path_bounds_are_lp_bounds(seed):
    batch_lp.test_the_path_bounds_are_lp_bounds.hypothesis.inner_test(seed)


@settings(max_examples=4, deadline=None)
@given(st.integers(0, 2 ** 31), st.integers(0, 3), st.integers(3, 12))
def test_the_working_rows_bounds_are_the_all_rows_lps(seed, keep, added):
    batch_lp.test_the_working_rows_bounds_are_the_all_rows_lps.hypothesis.inner_test(
        seed, keep, added)


@settings(max_examples=8, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.floats(8.0, 30.0), st.floats(-0.6, 0.6), st.floats(-1.0, 1.0),
       st.integers(0, 2**31))
def test_predictions_on_an_arc_keep_the_truth_and_name_certified_points(
        tmp_path, radius, a, noise, seed):
    corrections.test_predictions_on_an_arc_keep_the_truth_and_name_certified_points.hypothesis.\
        inner_test(tmp_path, radius, a, noise, seed)


@settings(max_examples=6, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(**linearize.robot_draws(st.integers(6, 14)), refine=st.sampled_from([1e-4, 1e-2]),
       at_once=st.sampled_from([3, 10, 2000]))
def test_ends_sought_again_are_certified_on_random_robots(tmp_path_factory, seed, joints, rows,
                                                          formulation, refine, at_once):
    inner.test_ends_sought_again_are_certified_on_random_robots.hypothesis.inner_test(
        tmp_path_factory, seed, joints, rows, formulation, refine, at_once
    )


@settings(max_examples=8, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.floats(0.85, 1.15), st.floats(0.35, 0.65), st.floats(-0.2, 0.2),
       st.integers(0, 2 ** 31))
def test_every_consistent_vectors_prediction_lies_in_its_box(tmp_path, spy, l1, l2, o, seed):  # noqa: F811
    second_order.test_every_consistent_vectors_prediction_lies_in_its_box.hypothesis.inner_test(
        tmp_path, spy, l1, l2, o, seed
    )


@settings(max_examples=1000, deadline=None)
@given(data=st.data(), n=st.integers(1, 5))
def test_narrowed_product_columns_hold_every_product(data, n) -> None:
    taylor.test_narrowed_product_columns_hold_every_product.hypothesis.inner_test(data, n)


@settings(max_examples=15, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), points=st.integers(4, 7),
       noise=st.floats(0.005, 0.045), e=st.sampled_from([0.05, 0.08]))
def test_shaving_keeps_every_point_that_satisfies_the_rows(tmp_path_factory, seed, points,
                                                           noise, e):
    shave.test_shaving_keeps_every_point_that_satisfies_the_rows.hypothesis.inner_test(
        tmp_path_factory, seed, points, noise, e
    )


@settings(max_examples=8, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(**linearize.robot_draws(st.integers(6, 14)))
def test_shaved_random_robots_hold_the_truth(tmp_path_factory, seed, joints, rows, formulation):
    shave.test_shaved_random_robots_hold_the_truth.hypothesis.inner_test(
        tmp_path_factory, seed, joints, rows, formulation
    )
