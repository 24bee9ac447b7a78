"""The one JSON writer of calibc: every document it writes parses with a strict parser
(JavaScript's, Go's, jq's), which reject the `NaN` and `Infinity` Python's json writes.

The convention (docs/json.md): an infinite number is the string "+oo" or "-oo" (as an
unbounded end of an interval is written everywhere), a NaN is `null` (no value); numpy's
scalars and arrays are written as the plain numbers and lists they hold. The document is
then written with `allow_nan=False`, so a non-finite number that slipped through is an
error here, never an invalid file."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np


def plain(x: Any) -> Any:
    """`x` with every non-finite number replaced by the convention above, every numpy
    value by a Python one, every tuple by a list (the rest is left as it is)."""
    if isinstance(x, dict):
        return {k: plain(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return [plain(v) for v in x.tolist()]
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None if math.isnan(x) else ("+oo" if x > 0 else "-oo")
    return x


def dumps(data: Any, indent: int | None = None) -> str:
    """`data` as strict JSON (`indent` as json.dumps's)."""
    return json.dumps(plain(data), indent=indent, allow_nan=False)


def strict_loads(text: str) -> Any:
    """Parse `text` as a strict parser does: NaN, Infinity and -Infinity are errors."""
    def refuse(name: str) -> Any:
        raise ValueError(f"not JSON: {name}")

    return json.loads(text, parse_constant=refuse)
