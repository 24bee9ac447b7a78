"""The jobs on Dask: submitted as futures, their lines written as they complete.

Dask's scheduler, workers and futures do the distribution: by default an in-process local
cluster (`LocalCluster`), or a running cluster at `--scheduler ADDRESS` (started with
`dask scheduler` and `dask worker`). The local cluster's workers are processes of one thread
each: a solve is Python bound, so threads would queue on the GIL, and a process per worker
keeps a job that exhausts memory or crashes from taking the batch down with it.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from calib_dsl.batch.jobs import Job
from calib_dsl.batch.output import Results, locked, previous
from calib_dsl.batch.run import run_job
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.strategy.cluster import pieces_on_cluster

CONNECT_SECONDS = 20.0  # --scheduler: a wrong address fails after this, not never


def run_batch(jobs: list[Job], output: str, *, scheduler: str | None, workers: int,
              force: bool, retry_errors: bool, say: Callable[[str], None]) -> list[dict]:
    """Run the jobs not yet in `output` (all with `force`), adding a line for each as it
    finishes; `say` gets the progress. The lines of all the jobs, in the jobs' order."""
    distributed = dask()
    with locked(output):
        return _run(distributed, jobs, output, scheduler=scheduler, workers=workers,
                    force=force, retry_errors=retry_errors, say=say)


def _run(distributed: Any, jobs: list[Job], output: str, *, scheduler: str | None,
         workers: int, force: bool, retry_errors: bool, say: Callable[[str], None]
         ) -> list[dict]:
    done = {} if force else previous(output, retry_errors)
    todo = [job for job in jobs if job.id not in done]
    if len(todo) < len(jobs):
        say(f"{len(jobs) - len(todo)} of {len(jobs)} jobs already in {output}: skipped "
            "(--force runs them again)")
    changed = [job.id for job in jobs if job.id in done and done[job.id].get("job") not in
               (None, job.spec())]
    if changed:  # the id is what a rerun goes by: say when the job is no longer the same
        say(f"warning: the line of {', '.join(changed)} records another job than the job "
            "file's now (--force runs every job again)")
    if not todo:
        return [done[job.id] for job in jobs]
    # the file is opened (emptied by --force) once the cluster is there, not before
    with _client(distributed, scheduler, workers) as (client, where), \
            Results(output, force) as results:
        say(f"{len(todo)} job{'s' if len(todo) > 1 else ''} to run on {where}")
        for k, line in enumerate(_completed(distributed, client, todo, scheduler is not None),
                                 1):
            results.add(line)
            done[line["id"]] = line
            say(f"[{k}/{len(todo)}] {line['id']}: {line['status']} ({line['seconds']:.2f} s)")
    return [done[job.id] for job in jobs]


def dask() -> Any:
    """The `distributed` module, or the one-line advice to install it."""
    try:
        import distributed
    except ImportError:
        raise CalError("calibc batch runs its jobs on Dask, which is not installed: "
                       "pip install calibc[batch]") from None
    return distributed


@contextmanager
def _client(distributed: Any, scheduler: str | None,
            workers: int) -> Iterator[tuple[Any, str]]:
    """A Dask client, and where its jobs run (said in the progress)."""
    if scheduler is None:
        # no dashboard; the scheduler's HTTP server (always there) on a free port, not on
        # 8787, which another cluster may hold (Dask then warns on stderr)
        with distributed.LocalCluster(n_workers=workers, threads_per_worker=1,
                                      processes=True, dashboard_address=None,
                                      scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                                      silence_logs=logging.ERROR) as cluster, \
                distributed.Client(cluster) as client:
            yield client, f"a local cluster of {workers} worker process(es)"
        return
    client = connect(distributed, scheduler, CONNECT_SECONDS)
    with client:
        yield client, f"the Dask scheduler at {scheduler}"


def connect(distributed: Any, scheduler: str, seconds: float) -> Any:
    """A client of the scheduler at `scheduler`, or a user error within about `seconds`.
    Dask bounds the TCP connect but not the handshake after it: a service that accepts and
    never answers would hold the batch for ever, one that answers other bytes makes Dask
    read a length from them (an allocation of exbibytes). So the client is made in a thread
    waited on for at most `seconds`, and whatever it raises is said in one line."""
    box: dict[str, Any] = {}

    def make() -> None:
        try:
            box["client"] = distributed.Client(scheduler, timeout=f"{seconds}s")
        except BaseException as exc:  # noqa: BLE001 (said to the user below, in one line)
            box["error"] = exc

    thread = threading.Thread(target=make, name="calibc-connect", daemon=True)
    thread.start()
    thread.join(seconds + HANDSHAKE_GRACE)
    if "client" in box:
        return box["client"]
    err = box.get("error")
    if err is None:
        raise CalError(f"--scheduler {scheduler}: no Dask scheduler answered within "
                       f"{seconds:g} s (something accepted the connection, but said nothing)")
    if isinstance(err, OSError | TimeoutError):
        raise CalError(f"--scheduler {scheduler}: no Dask scheduler answered there "
                       f"({type(err).__name__}: {err})")
    raise CalError(f"--scheduler {scheduler}: what answered there is not a Dask scheduler "
                   f"({type(err).__name__}: {err})")


HANDSHAKE_GRACE = 1.0  # seconds past Dask's own connect timeout (its message is the clearer)


def _completed(distributed: Any, client: Any, todo: list[Job],
               cluster: bool = False) -> Iterator[dict]:
    """The result lines in the order the jobs finish (with `cluster`, a split's pieces go to
    the cluster too: strategy/cluster.py)."""
    futures = {client.submit(on_worker, job, cluster, pure=False): job for job in todo}
    for future in distributed.as_completed(futures):
        job = futures.pop(future)
        try:
            line = future.result()
        except (Exception, asyncio.CancelledError) as exc:  # the worker died under it
            line = {"id": job.id, "status": "failed", "seconds": 0.0, "job": job.spec(),
                    "error": f"the job did not complete on Dask: {type(exc).__name__}: {exc}"}
        future.release()
        yield line


def on_worker(job: Job, cluster: bool = False) -> dict[str, Any]:
    """run_job on a Dask worker (with `cluster`, its split pieces on the cluster too), and
    which worker it was."""
    from distributed import get_worker

    with pieces_on_cluster(cluster):
        line = run_job(job)
    line["worker"] = get_worker().address
    return line
