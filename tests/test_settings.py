"""The settings' groups (settings.py): each concern's constants in a frozen group, and the
flat names callers knew before the groups still set them (`Settings.tuned`)."""

from __future__ import annotations

import os
from dataclasses import fields

import pytest

from calib_dsl.settings import DEFAULT, GROUPS, Settings


def test_tuned_routes_each_name_to_its_group():
    s = DEFAULT.tuned(working_rows=6, stalled=0.5, verdict_share=0.0, wide_iterations=7,
                      outliers__max_rounds=3, unit_turns=5, plan_improvement=1e-3)
    assert s.sampling.working_rows == 6 and s.rounds.stalled == 0.5
    assert s.rounds.wide_iterations == 7 and s.verdict_share == 0.0
    assert s.outliers.max_rounds == 3 and s.outliers.unit_turns == 5
    assert s.plan_improvement == 1e-3
    # everything else as it was, and DEFAULT itself unchanged (frozen)
    assert s.rounds.max_rounds == DEFAULT.rounds.max_rounds
    assert s.sampling.working_passes == DEFAULT.sampling.working_passes
    assert DEFAULT.sampling.working_rows != 6 or DEFAULT.rounds.stalled != 0.5


def test_a_shared_name_goes_to_the_first_group():
    s = DEFAULT.tuned(max_rounds=7)
    assert s.rounds.max_rounds == 7 and s.outliers.max_rounds == DEFAULT.outliers.max_rounds


def test_an_unknown_name_is_refused():
    with pytest.raises(TypeError, match="no field 'nope'"):
        DEFAULT.tuned(nope=1)


def test_every_group_is_a_field_and_no_name_is_both_flat_and_grouped():
    flat = {f.name for f in fields(Settings)}
    assert set(GROUPS) <= flat
    for g in GROUPS:
        inner = {f.name for f in fields(getattr(DEFAULT, g))}
        assert not inner & flat, f"{g}: {inner & flat} is both a group's field and a flat one"


def test_a_groups_name_and_field_name_that_field():
    """`min_error_share` (a flat name before the min_error group) sets the group's share;
    a name no group's field ends refused all the same."""
    s = DEFAULT.tuned(min_error_share=3.0, chebyshev_lps=2)
    assert s.min_error.share == 3.0 and s.fits.chebyshev_lps == 2
    assert s.min_error.wide == DEFAULT.min_error.wide and s.rounds == DEFAULT.rounds
    assert DEFAULT.tuned(wide=0.5).min_error.wide == DEFAULT.min_error.wide  # the rounds'
    with pytest.raises(TypeError, match="no field 'min_error_nope'"):
        DEFAULT.tuned(min_error_nope=1)


def test_a_group_given_whole_keeps_its_fields_beside_a_field_of_it():
    from dataclasses import replace

    lp = replace(DEFAULT.lp, workers=DEFAULT.lp.workers + 3)
    first = fields(lp)[0].name if fields(lp)[0].name != "workers" else fields(lp)[1].name
    changed = {first: getattr(lp, first)}
    s = DEFAULT.tuned(lp=lp, **{f"lp__{first}": changed[first]})
    assert s.lp.workers == DEFAULT.lp.workers + 3


@pytest.mark.parametrize("value", ["abc", "0", "-1", "1.5", "²"])
def test_a_bad_cores_count_is_one_user_error(value):
    import subprocess
    import sys

    env = {**os.environ, "CALIBC_CORES": value}
    run = subprocess.run([sys.executable, "-c", "import calib_dsl.settings"], env=env,
                         capture_output=True, text=True)
    assert run.returncode == 2
    assert run.stderr.strip() == (f"error: CALIBC_CORES must be a whole number of cores, "
                                  f"1 or more (not {value!r})")
