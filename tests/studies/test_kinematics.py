"""kinematics.py against an independent reference: algorithm g with explicit 2-D rotations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.studies.kinematics import (
    RX90_PARAMS,
    RX90_TOOL,
    chain,
    dh_matrix,
    forward,
    rx90_forward,
    rx90_frames,
)


def rot(beta: float, u: float, v: float) -> tuple[float, float]:
    return u * math.cos(beta) - v * math.sin(beta), u * math.sin(beta) + v * math.cos(beta)


def algorithm_g(frames: list[tuple[float, float, float, float]], point) -> tuple:
    """PAPER_NOTES algorithm g, innermost frame first, plain floats."""
    c1, c2, c3 = (float(x) for x in point)
    for alpha, d, theta, r in reversed(frames):
        c3 += r
        c1, c2 = rot(theta, c1, c2)
        c1 += d
        c2, c3 = rot(alpha, c2, c3)
    return c1, c2, c3


angle = st.floats(-math.pi, math.pi)
length = st.floats(-1.0, 1.0)
frame = st.tuples(angle, length, angle, length)
coord = st.floats(-0.5, 0.5)


@settings(max_examples=300, deadline=None)
@given(st.lists(frame, min_size=0, max_size=9), st.tuples(coord, coord, coord))
def test_forward_matches_algorithm_g(frames, point):
    got = forward(frames, point)
    assert got.shape == (1, 3)
    np.testing.assert_allclose(got[0], algorithm_g(frames, point), atol=1e-12)


def test_vectorized_over_configurations():
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, (200, 6))
    got = rx90_forward(q)
    assert got.shape == (200, 3, 3)
    p = RX90_PARAMS
    for n in range(0, 200, 17):
        frames = [(0.0, 0.0, p["theta0"], p["r0"])]
        frames += [(p[f"alpha{j}"], p[f"d{j}"], p[f"theta{j}"] + q[n, j - 1], p[f"r{j}"])
                   for j in range(1, 6)]
        frames.append((p["alpha6"], p["d6"], q[n, 5], 0.0))
        for k, b in enumerate(RX90_TOOL):
            np.testing.assert_allclose(got[n, k], algorithm_g(frames, b), atol=1e-12)
            np.testing.assert_allclose(forward(rx90_frames(q[n]), b)[0], got[n, k],
                                       atol=1e-15)


def test_rx90_at_zero_by_hand():
    # q = 0, b1 = (0.1, 0.2, 0.1), worked through algorithm g on paper:
    # alpha6 = pi/2 -> (0.1, -0.1, 0.2); alpha5 = -pi/2 -> (0.1, 0.2, 0.1);
    # r4 = 0.5, alpha4 = pi/2 -> (0.1, -0.6, 0.2); d3 = 0.5 -> (0.6, -0.6, 0.2);
    # alpha2 = -pi/2 -> (0.6, 0.2, 0.6); alpha1 = 0.1 rotates (y, z); r0, theta0 = pi/2.
    s, c = math.sin(0.1), math.cos(0.1)
    expected = (0.6 * s - 0.2 * c, 0.6, 0.5 + 0.6 * c + 0.2 * s)
    np.testing.assert_allclose(rx90_forward(np.zeros(6))[0, 0], expected, atol=1e-15)


def test_pure_translation_chain():
    # Zero angles: the d's add along x, the r's along z.
    frames = [(0.0, 0.3, 0.0, 0.2), (0.0, -0.1, 0.0, 0.4)]
    np.testing.assert_allclose(forward(frames, (1.0, 2.0, 3.0))[0], (1.2, 2.0, 3.6))


def test_dh_matrix_is_a_rigid_transform():
    rng = np.random.default_rng(1)
    a, d, t, r = rng.uniform(-3, 3, (4, 50))
    m = dh_matrix(a, d, t, r)
    assert m.shape == (50, 4, 4)
    rotation = m[:, :3, :3]
    np.testing.assert_allclose(rotation @ rotation.transpose(0, 2, 1),
                               np.broadcast_to(np.eye(3), (50, 3, 3)), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(rotation), 1.0, atol=1e-14)
    np.testing.assert_array_equal(m[:, 3], np.broadcast_to([0, 0, 0, 1.0], (50, 4)))


def test_scalars_broadcast_and_empty_chain():
    assert dh_matrix(0.0, 0.0, 0.0, 0.0).shape == (1, 4, 4)
    np.testing.assert_array_equal(chain([])[0], np.eye(4))
    np.testing.assert_array_equal(forward([], (1.0, 2.0, 3.0))[0], (1.0, 2.0, 3.0))


@pytest.mark.parametrize("j", range(6))
def test_each_joint_alone_by_reference(j):
    # Each joint moved alone, compared with algorithm g on the same frames.
    q = np.zeros(6)
    q[j] = 0.7
    frames = [tuple(float(np.asarray(v).reshape(-1)[0]) for v in f) for f in rx90_frames(q)]
    np.testing.assert_allclose(rx90_forward(q)[0, 2], algorithm_g(frames, RX90_TOOL[2]),
                               atol=1e-14)
