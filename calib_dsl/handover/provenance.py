"""Where a result came from: calibc's version, the command, the date and the machine, and
every file read with its SHA-256 (the model's text too: a report outlives the checkout).
`calibc solve` writes it into its JSON as `provenance` (docs/json.md)."""

from __future__ import annotations

import hashlib
import importlib.metadata
import os
import platform
import shlex
import time
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from calib_dsl.ir.program import Program

STARTED = time.perf_counter()  # the command's start: `calibc solve` imports this first


def provenance(prog: Program, argv: Sequence[str]) -> dict[str, Any]:
    """The provenance of a solve of `prog` run as `calibc ARGV`."""
    return {
        "calibc": version(),
        "command": shlex.join(["calibc", *argv]),
        "directory": os.getcwd(),
        "date": datetime.now(UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "seconds": time.perf_counter() - STARTED,
        "model": [source(p, text=True) for p in prog.sources],
        "data": [{"table": name, **source(path), "rows": rows}
                 for name, (path, rows) in prog.tables.items()],
    }


def version() -> str:
    try:
        return importlib.metadata.version("calibc")
    except importlib.metadata.PackageNotFoundError:  # run from a checkout, not installed
        return "unknown"


def machine() -> dict[str, Any]:
    return {"host": platform.node(), "system": platform.platform(),
            "processor": platform.machine(), "cpus": os.cpu_count(),
            "python": platform.python_version()}


def source(path: str, text: bool = False) -> dict[str, Any]:
    """A file read: its path as given, its SHA-256 and, for a model file, its text (None
    where it cannot be read again, e.g. a table given as values through the Python API)."""
    try:
        raw = Path(path).read_bytes()
    except OSError:
        return {"path": path, "sha256": None, **({"text": None} if text else {})}
    out: dict[str, Any] = {"path": path, "sha256": hashlib.sha256(raw).hexdigest()}
    if text:
        out["text"] = raw.decode("utf-8", errors="replace")
    return out
