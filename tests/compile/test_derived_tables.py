"""ir/program.derived: a table asked for by several threads at once is built once."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace

from calib_dsl.ir.program import derived


def test_threads_asking_at_once_share_one_build():
    prog = SimpleNamespace(derived_cache={}, groups=[])
    builds = []

    def build():
        builds.append(threading.get_ident())
        time.sleep(0.05)  # (long enough for every thread to ask while it builds)
        return object()

    got = []
    threads = [threading.Thread(target=lambda: got.append(derived(prog, "table", build)))
               for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(builds) == 1
    assert len(got) == 4 and all(g is got[0] for g in got)


def test_a_build_may_ask_for_another_table():
    prog = SimpleNamespace(derived_cache={}, groups=[])
    outer = derived(prog, "outer", lambda: ("outer", derived(prog, "inner", lambda: 1)))
    assert outer == ("outer", 1) and derived(prog, "inner", lambda: 2) == 1
