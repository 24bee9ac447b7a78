"""Independent calls run in child interpreters (`python -m calib_dsl.strategy.workers`).

Threads cannot share out work that is bound by Python (the GIL), so the tight strategy runs
the pieces of a split box in child processes. They are started as plain interpreters, not
through multiprocessing: its spawn method re-runs the caller's main script in each child (a
script that calls the solver without an `if __name__ == "__main__"` guard would recurse),
and fork would copy a process whose HiGHS threads the child lacks. Each child reads one
pickled (function, calls) pair on stdin and writes the pickled results on stdout; the
function must be importable by name (its module, named on the child's command line, is
imported first, while the other children start). The children compute what the caller
would, with the same code on the same inputs: the same results, bit for bit.
"""

from __future__ import annotations

import importlib
import os
import pickle
import subprocess
import sys
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any


class Children:
    """`processes` child interpreters, started now (they import `module` while the caller goes
    on) and given their calls later by `map`, once; `close` stops any that is left. Where a
    child cannot start, `map` returns None."""

    def __init__(self, processes: int, module: str) -> None:
        self.procs: list[subprocess.Popen] = []
        if not sys.executable:  # an embedded interpreter: no command to start a child with
            return
        env = dict(os.environ)
        # the child imports this package from where the parent did, installed or not
        root = str(Path(__file__).resolve().parent.parent)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
        try:
            for _ in range(processes):
                self.procs.append(subprocess.Popen(
                    [sys.executable, "-m", "calib_dsl.strategy.workers", module],
                    stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                    stderr=subprocess.DEVNULL, env=env))
        except (OSError, ValueError):
            self.close()

    def map(self, fn: Callable[..., Any], calls: list[tuple]) -> list[Any] | None:
        """[fn(*args) for args in calls], call k to child k mod processes, in the calls'
        order; None if a child could not start or failed (the caller then makes the calls
        itself)."""
        n = len(self.procs)
        if n == 0:
            return None
        shares = [calls[w::n] for w in range(n)]
        try:
            # all are fed at once: writing to one blocks until it has read its input, after
            # its own start-up
            inputs = [pickle.dumps((fn, share), pickle.HIGHEST_PROTOCOL) for share in shares]
            with ThreadPoolExecutor(n) as pool:
                list(pool.map(_feed, self.procs, inputs))
            results = []
            for child in self.procs:
                assert child.stdout is not None
                data = child.stdout.read()
                if child.wait() != 0:
                    return None
                results.append(pickle.loads(data))
        except (OSError, ValueError, pickle.PickleError, EOFError):
            return None
        finally:
            self.close()
        out: list[Any] = [None] * len(calls)
        for w, share in enumerate(results):
            out[w::n] = share
        return out

    def close(self) -> None:
        for child in self.procs:
            if child.poll() is None:
                child.kill()
                child.wait()
            for pipe in (child.stdin, child.stdout):
                if pipe is not None:
                    pipe.close()
        self.procs = []


def map_in_processes(fn: Callable[..., Any], calls: list[tuple],
                     processes: int) -> list[Any] | None:
    """Children started for these calls alone (see Children.map)."""
    return Children(processes, getattr(fn, "__module__", None) or "builtins").map(fn, calls)


def _feed(child: subprocess.Popen, data: bytes) -> None:
    assert child.stdin is not None
    child.stdin.write(data)
    child.stdin.close()


def _main() -> None:
    # the function's module first: its imports (numpy, the package) while the parent is
    # still starting the other children
    if len(sys.argv) > 1:
        importlib.import_module(sys.argv[1])
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
