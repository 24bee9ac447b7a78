"""`calibc batch` cannot run twice on one results file nor hang on a scheduler address: the
results file's lock (two concurrent runs), a rerun's de-duplication by job id, and the
bounded connect and handshake against a silent listener and a garbage server on 127.0.0.1
(sockets opened here, loopback only)."""

from __future__ import annotations

import fcntl
import importlib.util
import json
import socket
import subprocess
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from batch_project import FILES
from click.testing import CliRunner

from calib_dsl import cli
from calib_dsl.batch import schedule
from calib_dsl.batch.output import previous

needs_dask = pytest.mark.skipif(importlib.util.find_spec("distributed") is None,
                                reason="calibc batch runs on Dask: pip install -e .[dev]")
JOB_IDS = ("a", "b", "c")


def project(tmp: Path) -> Path:
    for name in ("line.cal", "a.csv"):
        (tmp / name).write_text(FILES[name], encoding="utf-8")
    jobs = "".join(f'[[job]]\nid = "{i}"\nmodel = "line.cal"\ndata = "a.csv"\n'
                   f'strategy = "hc4"\n\n' for i in JOB_IDS)
    (tmp / "jobs.toml").write_text(jobs, encoding="utf-8")
    return tmp / "jobs.toml"


def invoke(*args: object):
    return CliRunner().invoke(cli.main, [str(a) for a in args], catch_exceptions=False)


def ids_in(path: Path) -> list[str]:
    return [json.loads(x)["id"] for x in path.read_text(encoding="utf-8").splitlines()]


# -- the lock -------------------------------------------------------------------------------
@needs_dask
def test_a_held_lock_fails_at_once(tmp_path):
    jobs, out = project(tmp_path), tmp_path / "out.jsonl"
    with open(f"{out}.lock", "a") as held:
        fcntl.flock(held.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)  # another batch's
        start = time.perf_counter()
        res = invoke("batch", jobs, "-o", out, "--workers", "1", "--quiet")
        took = time.perf_counter() - start
    assert res.exit_code == 2 and took < 10
    assert res.stderr.strip() == (f"error: the results file '{out}' is in use by another "
                                  f"calibc batch (it holds the lock '{out}.lock'): wait for "
                                  "it to finish, or give another -o")
    assert not out.exists()


@pytest.mark.slow
@needs_dask
def test_two_concurrent_runs_run_each_job_once(tmp_path, calibc):
    jobs, out = project(tmp_path), tmp_path / "out.jsonl"
    argv = [*calibc, "batch", str(jobs), "-o", str(out), "--workers", "1", "--quiet"]
    runs = [subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            for _ in range(2)]
    done = [(p.wait(timeout=240), p.stderr.read()) for p in runs]  # type: ignore[union-attr]
    codes = sorted(code for code, _ in done)
    # the second fails on the lock; or, if the first was done before it began, skips all
    assert codes in ([0, 0], [0, 2]), done
    if codes == [0, 2]:
        assert any("is in use by another calibc batch" in err for _, err in done)
    assert sorted(ids_in(out)) == sorted(JOB_IDS)


# -- de-duplication -------------------------------------------------------------------------
def test_a_rerun_keeps_one_line_per_id(tmp_path):
    out = tmp_path / "out.jsonl"
    lines = [{"id": "a", "status": "contracted", "n": 1}, {"id": "b", "status": "error"},
             {"id": "a", "status": "contracted", "n": 2}, {"id": "b", "status": "infeasible"}]
    out.write_text("".join(json.dumps(x) + "\n" for x in lines), encoding="utf-8")
    found = previous(str(out), retry_errors=False)
    assert found["a"]["n"] == 2 and found["b"]["status"] == "infeasible"
    assert sorted(ids_in(out)) == ["a", "b"]  # the file itself: one line each, the last
    again = [json.loads(x) for x in out.read_text(encoding="utf-8").splitlines()]
    assert {x["id"]: x for x in again} == found


@needs_dask
def test_a_rerun_on_a_file_with_duplicates_rewrites_it(tmp_path):
    jobs, out = project(tmp_path), tmp_path / "out.jsonl"
    assert invoke("batch", jobs, "-o", out, "--workers", "1", "--quiet").exit_code == 0
    out.write_text(out.read_text(encoding="utf-8") * 2, encoding="utf-8")  # a run twice
    res = invoke("batch", jobs, "-o", out)
    assert res.exit_code == 0 and "3 of 3 jobs already in" in res.stderr
    assert sorted(ids_in(out)) == sorted(JOB_IDS)


# -- the scheduler's address ----------------------------------------------------------------
@contextmanager
def listener(answer: bytes | None) -> Iterator[str]:
    """A TCP server on 127.0.0.1 that accepts and then says nothing (`answer` None) or
    sends `answer`; its address."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    server.settimeout(0.2)
    held: list[socket.socket] = []
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            held.append(conn)
            if answer is not None:
                try:
                    conn.sendall(answer)
                except OSError:
                    pass

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        thread.join(5)
        for conn in held:
            conn.close()
        server.close()


SECONDS = 2.0
GARBAGE = [b"SSH-2.0-OpenSSH_8.9p1 Ubuntu-3\r\n",  # read as a length: 2.8 EiB
           b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n",
           bytes(range(256)) * 4]


@needs_dask
@pytest.mark.parametrize("answer", [None, *GARBAGE], ids=["silent", "ssh", "http", "bytes"])
def test_a_scheduler_address_that_is_not_dask(tmp_path, monkeypatch, answer):
    monkeypatch.setattr(schedule, "CONNECT_SECONDS", SECONDS)
    jobs, out = project(tmp_path), tmp_path / "out.jsonl"
    with listener(answer) as address:
        start = time.perf_counter()
        res = invoke("batch", jobs, "-o", out, "--scheduler", address, "--quiet")
        took = time.perf_counter() - start
    assert res.exit_code == 2, res.output
    assert took < SECONDS + schedule.HANDSHAKE_GRACE + 5
    first = res.stderr.strip()
    assert first.startswith(f"error: --scheduler {address}: ") and "\n" not in first
    if answer is None:
        assert f"no Dask scheduler answered within {SECONDS:g} s" in first


@needs_dask
def test_a_closed_port_is_an_error_too(tmp_path, monkeypatch):
    monkeypatch.setattr(schedule, "CONNECT_SECONDS", SECONDS)
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()  # nothing listens there now
    res = invoke("batch", project(tmp_path), "-o", tmp_path / "o.jsonl",
                 "--scheduler", f"tcp://127.0.0.1:{port}", "--quiet")
    assert res.exit_code == 2 and "no Dask scheduler answered" in res.stderr

