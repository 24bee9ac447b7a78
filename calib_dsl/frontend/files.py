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


class NotUtf8(UnicodeDecodeError):
    """A UnicodeDecodeError that knows where in the file: `line` and `col` (1-based; the
    column counts bytes, as the decoder saw them)."""

    def __init__(self, err: UnicodeDecodeError, line: int, col: int) -> None:
        super().__init__(err.encoding, err.object, err.start, err.end, err.reason)
        self.line, self.col = line, col

    @classmethod
    def at(cls, err: UnicodeDecodeError, lines_before: int = 0) -> NotUtf8:
        """`err` located in its bytes, after `lines_before` lines that decoded."""
        head = bytes(err.object[:err.start])
        return cls(err, lines_before + head.count(b"\n") + 1, err.start - head.rfind(b"\n"))


def capped_lines(path: str | Path, limit: int) -> Iterator[str]:
    """The file's lines (UTF-8, a leading byte-order mark dropped), read one at a time:
    TooLarge past `limit` bytes, NotUtf8 on a line that is not UTF-8; a line never holds
    more than the cap (a file without a newline, as /dev/zero, is said so)."""
    size, first, lines = 0, True, 0
    with open(path, "rb") as f:
        while size <= limit:
            raw = f.readline(limit + 1 - size)
            if not raw:
                return
            size += len(raw)
            if size > limit:
                break
            try:
                text = raw.decode("utf-8-sig" if first else "utf-8")
            except UnicodeDecodeError as err:
                raise NotUtf8.at(err, lines) from None
            first = False
            lines += 1
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
    data = b"".join(chunks)
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as err:
        raise NotUtf8.at(err) from None
