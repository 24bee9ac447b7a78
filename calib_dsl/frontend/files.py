"""Reading a user's files with a cap on their size: a model or a table past it is a mistake
(a device such as /dev/zero, a wrong path), and is said so before memory runs out."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

MAX_MODEL_BYTES = 16 * 2**20  # a model's text; data belong in tables
MAX_TABLE_BYTES = 256 * 2**20  # a table: about a million rows of a tracker's export
_CHUNK = 2**20


class TooLarge(Exception):
    """The file holds more than the cap."""


def capped_lines(path: str | Path, limit: int) -> Iterator[str]:
    """The file's lines (UTF-8, a leading byte-order mark dropped), read one at a time:
    TooLarge past `limit` bytes, UnicodeDecodeError on a line that is not UTF-8; a line never
    holds more than the cap (a file without a newline, as /dev/zero, is said so)."""
    size, first = 0, True
    with open(path, "rb") as f:
        while size <= limit:
            raw = f.readline(limit + 1 - size)
            if not raw:
                return
            size += len(raw)
            if size > limit:
                break
            text = raw.decode("utf-8-sig" if first else "utf-8")
            first = False
            yield from text.splitlines()  # (also splits a lone \r, as old files end lines)
    raise TooLarge(f"over {limit // 2**20} MiB")


def read_capped(path: str | Path, limit: int, encoding: str = "utf-8") -> str:
    """The file's text; TooLarge past `limit` bytes (read no further than that)."""
    chunks, size = [], 0
    with open(path, "rb") as f:  # in chunks: f.read(limit + 1) would allocate the cap
        while size <= limit:
            chunk = f.read(min(_CHUNK, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    if size > limit:
        raise TooLarge(f"over {limit // 2**20} MiB")
    return b"".join(chunks).decode(encoding)
