"""`calibc batch --scheduler` on a real Dask cluster: a scheduler and two workers started
as separate processes with Dask's own `dask scheduler` / `dask worker` commands, the batch
run by the installed `calibc` command, every result line checked against the same solve
run here."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from batch_project import STATUS, direct, intervals, write_project


@pytest.fixture(scope="module")
def distributed():
    """Imported by the cluster tests, not at collection (Dask's import is heavy)."""
    return pytest.importorskip(
        "distributed", reason="the cluster test needs Dask (pip install -e .[dev])")


START_GUARD = 120  # s: a cluster not up by then is broken, not slow (no result depends on it)


def dask_command() -> str:
    here = Path(sys.executable).parent / "dask"
    if not here.exists():
        pytest.skip("the `dask` command is not beside this interpreter")
    return str(here)


@pytest.fixture
def cluster(tmp_path, distributed):
    """(scheduler address, the two workers' addresses); every process killed at the end."""
    dask = dask_command()
    logs = tmp_path / "dask-logs"
    logs.mkdir()
    info = tmp_path / "scheduler.json"
    procs: list[subprocess.Popen] = []

    def start(name: str, *args: str) -> None:
        with open(logs / f"{name}.log", "wb") as log:
            # a session of its own: the worker's nanny and its child die with one signal
            procs.append(subprocess.Popen([dask, *args], cwd=tmp_path, stdout=log,
                                          stderr=subprocess.STDOUT, start_new_session=True))

    try:
        # port 0: the scheduler picks a free port and writes its address to the file
        start("scheduler", "scheduler", "--host", "127.0.0.1", "--port", "0",
              "--no-dashboard", "--scheduler-file", str(info))
        deadline = time.monotonic() + START_GUARD
        while not info.exists() or not info.read_text(encoding="utf-8").strip():
            assert procs[0].poll() is None, (logs / "scheduler.log").read_text()
            assert time.monotonic() < deadline, "the scheduler did not start"
            time.sleep(0.2)
        address = json.loads(info.read_text(encoding="utf-8"))["address"]
        for k in (1, 2):
            start(f"worker{k}", "worker", "--scheduler-file", str(info), "--nworkers", "1",
                  "--nthreads", "1", "--no-dashboard", "--local-directory",
                  str(tmp_path / f"w{k}"))
        with distributed.Client(address, timeout="60s") as client:
            client.wait_for_workers(2, timeout=START_GUARD)
            workers = set(client.scheduler_info()["workers"])
        yield address, workers
    finally:
        # killed outright: nothing of theirs is kept, and a graceful close of the workers
        # took 8 s per test
        for p in reversed(procs):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGKILL)
        for p in procs:
            p.wait()


@pytest.mark.slow
def test_batch_on_a_dask_cluster(cluster, calibc, tmp_path):
    address, workers = cluster
    assert len(workers) == 2
    jobs = write_project(tmp_path / "project")
    out = tmp_path / "results.jsonl"
    res = subprocess.run([*calibc, "batch", str(jobs), "-o", str(out), "--scheduler", address],
                         capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert res.returncode == 1, res.stderr  # the missing and the malformed file
    assert "Traceback" not in res.stderr
    assert f"{len(STATUS)} jobs to run on the Dask scheduler at {address}" in res.stderr
    lines = [json.loads(x) for x in out.read_text(encoding="utf-8").splitlines()]
    assert sorted(x["id"] for x in lines) == sorted(STATUS)  # each job once
    for line in lines:
        status, found = direct(line["job"])  # the same solve, here
        assert line["status"] == status == STATUS[line["id"]], line["id"]
        if status == "error":
            assert line["error"] == found
        else:  # the same intervals, bit for bit
            assert intervals(line["result"]) == found, line["id"]
    # they ran on the cluster's two workers, not here
    assert {x["worker"] for x in lines} == workers
    table = res.stdout.splitlines()
    assert table[-1] == f"{len(STATUS)} jobs: 6 contracted, 2 error, 1 infeasible"


@pytest.mark.slow
def test_a_jobs_split_pieces_are_tasks_of_the_cluster(cluster, distributed):
    """From a task on one worker (one thread: the job seceded while it waits, or the pieces
    would wait for it), the pieces run on the cluster; the workers' events count them."""
    from calib_dsl.strategy.cluster import EVENT

    def pieces_in_a_task(n: int) -> list[int]:  # nested: Dask sends it by value
        from calib_dsl.strategy.cluster import cluster_pieces, pieces_on_cluster

        with pieces_on_cluster():
            pieces = cluster_pieces()
            assert pieces is not None
            out = pieces.map(abs, [(-k,) for k in range(n)])
            pieces.close()
        return out or []

    address, _ = cluster
    with distributed.Client(address, timeout="60s") as client:
        assert client.submit(pieces_in_a_task, 6, pure=False).result(timeout=120) == \
            list(range(6))
        assert sum(msg["pieces"] for _, msg in client.get_events(EVENT)) == 6
