"""Independent calls run in child interpreters (`python -m calib_dsl.workers`).

Threads cannot share out work that is bound by Python (the GIL), so the tight strategy runs
the pieces of a split box in child processes. They are started as plain interpreters, not
through multiprocessing: its spawn method re-runs the caller's main script in each child (a
script that calls the solver without an `if __name__ == "__main__"` guard would recurse),
and fork would copy a process whose HiGHS threads the child lacks. Each child reads one
pickled (function, calls) pair on stdin and writes the pickled results on stdout; the
function must be importable by name. The children compute what the caller would, with the
same code on the same inputs: the same results, bit for bit.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any


def map_in_processes(fn: Callable[..., Any], calls: list[tuple],
                     processes: int) -> list[Any] | None:
    """[fn(*args) for args in calls], shared out over `processes` children (call k to child
    k mod processes), in the calls' order; None if a child could not start or failed (the
    caller then makes the calls itself)."""
    if not sys.executable:  # an embedded interpreter: no command to start a child with
        return None
    shares = [calls[w::processes] for w in range(processes)]
    env = dict(os.environ)
    # the child imports this package from where the parent did, installed or not
    root = str(Path(__file__).resolve().parent.parent)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
    children = []
    try:
        for share in shares:
            child = subprocess.Popen([sys.executable, "-m", "calib_dsl.workers"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, env=env)
            children.append(child)
            assert child.stdin is not None
            child.stdin.write(pickle.dumps((fn, share), pickle.HIGHEST_PROTOCOL))
            child.stdin.close()
        results = []
        for child in children:
            assert child.stdout is not None
            data = child.stdout.read()
            if child.wait() != 0:
                return None
            results.append(pickle.loads(data))
    except (OSError, ValueError, pickle.PickleError, EOFError):
        return None
    finally:
        for child in children:
            if child.poll() is None:
                child.kill()
                child.wait()
    out: list[Any] = [None] * len(calls)
    for w, share in enumerate(results):
        out[w::processes] = share
    return out


def _main() -> None:
    # the results go to the real stdout; whatever a library prints there meanwhile (C or
    # Python) goes to stderr, which the parent discards
    results_out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    fn, calls = pickle.load(sys.stdin.buffer)
    results = [fn(*args) for args in calls]
    results_out.write(pickle.dumps(results, pickle.HIGHEST_PROTOCOL))
    results_out.close()


if __name__ == "__main__":
    _main()
