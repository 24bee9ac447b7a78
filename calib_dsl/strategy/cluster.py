"""The pieces of a split box on the Dask cluster a `calibc batch --scheduler` job runs on.

A job of a batch on a running cluster is a Dask task. Where its solve splits a box, the pieces
are refined as tasks of the same cluster (any worker: the same inputs, so the same results,
bit for bit), instead of child processes of the job's own worker. The job's task secedes from
its worker's thread pool while it waits, so the pieces can use that thread too. Without a
cluster (a plain solve, or a batch on its local cluster) this is never used.
"""

from __future__ import annotations

import contextvars
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

_ON_CLUSTER = contextvars.ContextVar("calibc_pieces_on_cluster", default=False)
EVENT = "calibc-pieces"  # the workers' event topic: how many pieces went to the cluster


@contextmanager
def pieces_on_cluster(enabled: bool = True) -> Iterator[None]:
    """Within this block, a split's pieces go to the cluster (when running in a Dask task)."""
    token = _ON_CLUSTER.set(enabled)
    try:
        yield
    finally:
        _ON_CLUSTER.reset(token)


class ClusterPieces:
    """`map` as workers.Children's, on the cluster's workers."""

    def __init__(self, client: Any, worker: Any) -> None:
        self.client, self.worker = client, worker

    def map(self, fn: Callable[..., Any], calls: list[tuple]) -> list[Any] | None:
        from distributed import rejoin, secede

        futures = self.client.map(fn, *zip(*calls, strict=True), pure=False)
        self.worker.log_event(EVENT, {"pieces": len(calls)})
        secede()  # the job's thread is free for the pieces while it waits
        try:
            return list(self.client.gather(futures))
        finally:
            rejoin()

    def close(self) -> None:
        """Nothing to stop: the cluster outlives the solve."""


def cluster_pieces() -> ClusterPieces | None:
    """The cluster's workers, when asked for and running in a Dask task; else None."""
    if not _ON_CLUSTER.get():
        return None
    try:
        from distributed import get_client, get_worker

        worker = get_worker()
        return ClusterPieces(get_client(), worker)
    except (ImportError, ValueError):  # not in a Dask task after all
        return None
