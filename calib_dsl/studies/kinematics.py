"""Numeric forward kinematics with plain 4x4 homogeneous matrices (numpy, vectorized).

Independent of the DAG and of the interval code: the reference that tests and the data
simulation are checked against. Every function works on N configurations at once; a scalar
argument is broadcast.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]
FrameValues = tuple[ArrayLike, ArrayLike, ArrayLike, ArrayLike]  # (alpha, d, theta, r)


def dh_matrix(alpha: ArrayLike, d: ArrayLike, theta: ArrayLike, r: ArrayLike) -> Array:
    """Rx(alpha) Tx(d) Rz(theta) Tz(r) as an (N,4,4) array (modified DH)."""
    a, dd, t, rr = (np.atleast_1d(np.asarray(v, dtype=float))
                    for v in np.broadcast_arrays(alpha, d, theta, r))
    ca, sa, ct, st = np.cos(a), np.sin(a), np.cos(t), np.sin(t)
    m = np.zeros(a.shape + (4, 4))
    m[:, 0, 0], m[:, 0, 1], m[:, 0, 3] = ct, -st, dd
    m[:, 1, 0], m[:, 1, 1], m[:, 1, 2], m[:, 1, 3] = ca * st, ca * ct, -sa, -sa * rr
    m[:, 2, 0], m[:, 2, 1], m[:, 2, 2], m[:, 2, 3] = sa * st, sa * ct, ca, ca * rr
    m[:, 3, 3] = 1.0
    return m


def chain(frames_values: Sequence[FrameValues]) -> Array:
    """T0 T1 ... Tn as (N,4,4)."""
    m = np.eye(4)[None]
    for fv in frames_values:
        m = m @ dh_matrix(*fv)
    return m


def forward(frames_values: Sequence[FrameValues], point: ArrayLike) -> Array:
    """Workshop coordinates (N,3) of `point` ((3,) or (N,3), in the last frame)."""
    m = chain(frames_values)
    p = np.asarray(point, dtype=float)
    return (m[:, :3, :3] @ p[..., None])[..., 0] + m[:, :3, 3]


# -- the Staubli RX90 of the paper (PAPER_NOTES tables 1 and 2) -----------------------------
RX90_PARAMS: dict[str, float] = {
    "theta0": np.pi / 2, "r0": 0.5,
    **{f"{p}{j}": 0.0 for j in range(1, 6) for p in ("alpha", "d", "theta", "r")},
    "alpha6": np.pi / 2, "d6": 0.0,
}
RX90_PARAMS.update(alpha1=0.1, alpha2=-np.pi / 2, d3=0.5, alpha4=np.pi / 2, r4=0.5,
                   alpha5=-np.pi / 2)
RX90_TOOL: tuple[tuple[float, float, float], ...] = (
    (0.1, 0.2, 0.1), (0.1, 0.1, 0.2), (0.2, 0.1, 0.1))


def rx90_frames(q: ArrayLike, params: Mapping[str, float] | None = None) -> list[FrameValues]:
    """The 7 frames (base + 6 joints) for joint angles q of shape (N,6) or (6,).

    theta_j = theta_j° + q_j; joint 6 has no offset and no r6 (paper, algorithm g).
    `params` overrides entries of RX90_PARAMS.
    """
    p = {**RX90_PARAMS, **(params or {})}
    qa = np.atleast_2d(np.asarray(q, dtype=float))
    frames: list[FrameValues] = [(0.0, 0.0, p["theta0"], p["r0"])]
    for j in range(1, 6):
        frames.append((p[f"alpha{j}"], p[f"d{j}"], p[f"theta{j}"] + qa[:, j - 1], p[f"r{j}"]))
    frames.append((p["alpha6"], p["d6"], qa[:, 5], 0.0))
    return frames


def rx90_forward(q: ArrayLike, params: Mapping[str, float] | None = None,
                 tool: Sequence[Sequence[float]] = RX90_TOOL) -> Array:
    """Workshop coordinates (N, len(tool), 3) of the tool points of the RX90."""
    m = chain(rx90_frames(q, params))
    b = np.asarray(tool, dtype=float)  # (P,3)
    return np.einsum("nij,pj->npi", m[:, :3, :3], b) + m[:, None, :3, 3]
