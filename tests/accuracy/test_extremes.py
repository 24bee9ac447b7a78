"""The pull-back's points stay between the certified centre and the candidate: a share of 1
computed as start + 1 (end - start) can round an ulp past the end, outside the domains
certify_point requires (which raised in the certified-point search)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.accuracy.extremes import _between

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(finite, finite), min_size=1, max_size=8), st.floats(0.0, 1.0))
def test_points_stay_between_their_ends(pairs, share):
    start = np.array([a for a, _ in pairs])
    ends = np.array([[b for _, b in pairs]])
    got = _between(start, ends, np.array([share]))
    assert np.all(got >= np.minimum(start, ends)) and np.all(got <= np.maximum(start, ends))
    if share == 1.0:
        assert np.all(np.abs(got - ends) <= 1e-12 * (1 + np.abs(ends)))


def test_a_full_share_that_rounds_past_the_end_is_kept_at_it():
    start, end = np.array([5.219248898251512]), np.array([[0.00030318594544552594]])
    assert start[0] + (end[0, 0] - start[0]) < end[0, 0]  # (the rounding this guards against)
    assert _between(start, end, np.array([1.0]))[0, 0] == end[0, 0]
