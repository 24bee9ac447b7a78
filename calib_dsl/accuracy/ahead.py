"""The predictions' certified points sought beside their LPs, not after them.

The certified-point search towards the predictions' extremes (the pipeline's `certify`,
accuracy/extremes.py) has two parts: the corrected optima of the calibration linearized at
its certified centre, which need only the predictions' gradients, and the prediction LPs'
own optima pulled back towards the centre, which need the LPs. The gradients are known
before the LPs start (accuracy/second_order.py, predict.py's first-order form), so the
first part runs in a thread of its own while the LPs run in theirs: the command keeps both
cores busy through the search's point checks, which run on one thread. Nothing is certified
here: it only reorders work whose results are the same (both parts' points, in the same
order: the first part's, then the second's); where the directions the search was started
on are not those the caller ends with (some rows' first-order LPs added directions after a
second-order LP stopped), the early search is discarded and the whole one run as before.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from types import TracebackType

import numpy as np

# (the predictions' gradients, the LPs' optima; each a row in the box's order) -> points
Certify = Callable[[np.ndarray, np.ndarray], list]


class Ahead:
    """The search's first part started on the first gradients handed to `start` (in its own
    thread where `threads` allows one), and `points` for the whole search's points.
    `order`: where each gradient's column goes in the box's order (`width` columns)."""

    def __init__(self, certify: Certify | None, order: np.ndarray, width: int,
                 threads: int) -> None:
        self.certify, self.order, self.width = certify, order, width
        self.pool = ThreadPoolExecutor(1) if certify is not None and threads > 1 else None
        self.started: tuple[np.ndarray, Future] | None = None

    def __enter__(self) -> Ahead:
        return self

    def __exit__(self, kind: type[BaseException] | None, err: BaseException | None,
                 tb: TracebackType | None) -> None:
        if self.pool is not None:  # (an unfinished search is waited for: it holds a model)
            self.pool.shutdown(wait=True, cancel_futures=True)

    def directions(self, gradient: np.ndarray) -> np.ndarray:
        """The gradients (columns in the independents' order) in the box's order."""
        out = np.zeros((len(gradient), self.width))
        out[:, self.order] = gradient
        return out

    def start(self, gradient: np.ndarray) -> None:
        """The first part on these gradients (independents' order), once."""
        if self.pool is None or self.started is not None or self.certify is None:
            return
        directions = self.directions(gradient)
        none = np.zeros((0, self.width))
        self.started = (directions, self.pool.submit(self.certify, directions, none))

    def points(self, directions: np.ndarray, optima: np.ndarray) -> list:
        """The search's points for `directions` and `optima`, as `certify(directions,
        optima)` finds them."""
        if self.certify is None:
            return []
        if self.started is None or not np.array_equal(self.started[0], directions):
            return self.certify(directions, optima)
        near = self.started[1].result()
        return [*near, *self.certify(np.zeros((0, self.width)), optima)]
