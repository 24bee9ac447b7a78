"""The results file: one JSON object per line, a job per line, appended and flushed as each
job finishes, so a batch that is killed keeps every job it finished. A rerun reads it back to
skip the jobs it holds; a last line cut short (the kill came mid-write) is dropped and its
job runs again."""

from __future__ import annotations

import errno
import fcntl
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.report.strict_json import dumps

UNFINISHED = ("error", "failed")  # statuses --retry-errors runs again


def previous(path: str, retry_errors: bool) -> dict[str, dict[str, Any]]:
    """The result lines already in `path`, by job id (the last line of an id wins). Lines
    that do not parse (a cut-off last line), and with `retry_errors` the errors and failures,
    are removed from the file, which is rewritten whole, so that a job rerun has one line."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        return {}
    except (OSError, UnicodeDecodeError) as err:
        raise CalError(f"cannot read the results file '{path}': "
                       f"{getattr(err, 'strerror', None) or err}") from None
    kept: dict[str, str] = {}  # by id, the last line of each (a job run twice: one line)
    found = {}
    for line in text.splitlines():
        try:
            item = json.loads(line)
        except ValueError:
            continue
        if not (isinstance(item, dict) and isinstance(item.get("id"), str)):
            continue
        if retry_errors and item.get("status") in UNFINISHED:
            continue
        kept.pop(item["id"], None)  # the later line takes its place at the end
        kept[item["id"]] = line
        found[item["id"]] = item
    fresh = "".join(line + "\n" for line in kept.values())
    if fresh != text:
        _replace(path, fresh)
    return found


@contextmanager
def locked(path: str) -> Iterator[None]:
    """An exclusive lock on the results file `path` (on `path`.lock beside it, which a
    rewrite of the results does not replace) for the whole batch: a second batch on the
    same file fails at once, rather than running every job again and adding its lines."""
    lock = f"{path}.lock"
    try:
        handle = open(lock, "a", encoding="utf-8")  # noqa: SIM115
    except OSError as err:
        raise CalError(f"cannot lock the results file '{path}': cannot open '{lock}': "
                       f"{err.strerror or err}") from None
    with handle:
        try:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise CalError(f"the results file '{path}' is in use by another calibc batch "
                           f"(it holds the lock '{lock}'): wait for it to finish, or give "
                           "another -o") from None
        except OSError as err:  # a file system without locks: go on, as without fcntl
            if err.errno not in (errno.ENOLCK, errno.EOPNOTSUPP):
                raise
        yield  # (closing the file releases the lock, also when the process is killed)


class Results:
    """The results file opened to add lines (`force`: emptied first)."""

    def __init__(self, path: str, force: bool) -> None:
        self.path = path
        try:
            self.file: IO[str] = open(path, "w" if force else "a", encoding="utf-8")  # noqa: SIM115
        except OSError as err:
            raise CalError(f"cannot write '{path}': {err.strerror or err}") from None

    def add(self, line: dict[str, Any]) -> None:
        self.file.write(dumps(line) + "\n")
        self.file.flush()  # in the file now: a kill after this keeps it

    def close(self) -> None:
        self.file.close()

    def __enter__(self) -> Results:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _replace(path: str, text: str) -> None:
    """Write `text` to `path` whole or not at all (a kill mid-write keeps the old file)."""
    tmp = f"{path}.tmp{os.getpid()}"
    try:
        Path(tmp).write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    except OSError as err:
        raise CalError(f"cannot write '{path}': {err.strerror or err}") from None
