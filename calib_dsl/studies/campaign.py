"""How a simulated campaign is measured: the poses and an unmodelled, pose-dependent error.

A tracker campaign's poses are drawn uniformly (`random`), laid on a grid (`grid`: each
input column at the centres of L equal cells of its range, L the least with L^d >= rows,
and `rows` distinct grid points drawn without replacement), or a few poses measured again
and again (`repeated`: rows / repeats distinct random poses, each measured `repeats` times,
with fresh noise each time).

Real robots' errors are mostly systematic: gear and compliance errors are smooth periodic
functions of the joint angles, the same at the same pose. `systematic(A)` adds to each
measured (output) column such a function of the table's true inputs,

    A * sum_k a_k sin(w_k . q + phi_k) / sum_k a_k,

with integer frequency vectors w_k (periodic in every angle), phases phi_k and weights a_k
drawn from the seed. Its size never exceeds A: the sum of the |sin| terms is at most the sum
of the weights (the result is also clipped to [-A, A], so rounding cannot pass it).

The campaign's draws come from their own stream of the seed: a campaign of random poses
without systematic error is the file the seed always gave.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib_dsl.frontend.diagnostics import CalError

POSES = ("random", "grid", "repeated")
TERMS = 4  # sinusoids per measured column: a few, as a smooth error has few harmonics
MAX_FREQUENCY = 2  # |w_k| per joint: slow variations (a gear's once- or twice-per-turn)


@dataclass(frozen=True)
class Campaign:
    """`poses`: one of POSES; `repeats`: measurements per pose for `repeated`;
    `systematic`: the amplitude A of the pose-dependent error (0: none); `noise`: whether
    the measured columns also get independent uniform noise within their tolerance."""

    poses: str = "random"
    repeats: int = 5
    systematic: float = 0.0
    noise: bool = True

    def __post_init__(self) -> None:
        if self.poses not in POSES:
            raise CalError(f"unknown pose shape '{self.poses}' (one of {', '.join(POSES)})")
        if self.repeats < 1:
            raise CalError("repeats must be at least 1")
        if not (math.isfinite(self.systematic) and self.systematic >= 0):
            raise CalError("the systematic error's amplitude must be finite and >= 0")


def poses(campaign: Campaign, ranges: list[tuple[float, float]], rows: int,
          rng: np.random.Generator) -> np.ndarray:
    """(rows, inputs) poses for the input columns' `ranges`, drawn from `rng`."""
    d = len(ranges)
    lo = np.array([a for a, _ in ranges], dtype=float).reshape(1, d)
    hi = np.array([b for _, b in ranges], dtype=float).reshape(1, d)
    if campaign.poses == "random" or d == 0:
        # column by column, as the seed has always drawn them
        return np.column_stack([rng.uniform(a, b, size=rows) for a, b in ranges]
                               ) if d else np.zeros((rows, 0))
    if campaign.poses == "grid":
        levels = 1
        while levels ** d < rows:
            levels += 1
        picked = rng.choice(levels ** d, size=rows, replace=False)
        index = np.stack(np.unravel_index(picked, (levels,) * d), axis=1)
        return lo + (index + 0.5) / levels * (hi - lo)
    distinct = max(1, math.ceil(rows / campaign.repeats))
    base = lo + rng.uniform(size=(distinct, d)) * (hi - lo)
    return base[np.arange(rows) % distinct]


@dataclass(frozen=True)
class Systematic:
    """One measured column's error: amplitude * sum_k a_k sin(w_k . q + phi_k) / sum a_k."""

    amplitude: float
    weights: np.ndarray  # (TERMS,)
    frequencies: np.ndarray  # (TERMS, inputs), integers
    phases: np.ndarray  # (TERMS,)

    def __call__(self, q: np.ndarray) -> np.ndarray:
        """The error at the poses q (rows, inputs): never beyond +-amplitude."""
        if self.amplitude == 0:
            return np.zeros(len(q))
        terms = np.sin(q @ self.frequencies.T + self.phases) @ self.weights
        err = self.amplitude * terms / self.weights.sum()
        return np.clip(err, -self.amplitude, self.amplitude)


def systematic(amplitude: float, inputs: int, rng: np.random.Generator) -> Systematic:
    """A smooth periodic error of the `inputs` angles, drawn from `rng`."""
    freq = rng.integers(-MAX_FREQUENCY, MAX_FREQUENCY + 1, size=(TERMS, inputs))
    if inputs:
        still = ~np.any(freq != 0, axis=1)  # a constant term is an offset, not a pose error
        freq[still, rng.integers(0, inputs, size=int(still.sum()))] = 1
    return Systematic(float(amplitude), rng.uniform(0.5, 1.0, size=TERMS),
                      freq.astype(float), rng.uniform(0.0, 2 * math.pi, size=TERMS))


PLAIN = Campaign()  # random poses, independent noise, no systematic error
