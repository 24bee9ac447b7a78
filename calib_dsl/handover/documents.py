"""The JSON documents a report is made from, read strictly: a solve's result (required), a
validation and an identification (optional). A file that is not such a document is a user
error naming the file, line and column."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.report.as_json import check_intervals


@dataclass(frozen=True)
class Documents:
    result: dict[str, Any]  # `calibc solve --json`
    validation: dict[str, Any] | None = None  # `calibc validate --json`
    identify: dict[str, Any] | None = None  # `calibc identify --json`
    names: tuple[str, ...] = ()  # the files read, for the report's provenance
    min_error: dict[str, Any] | None = None  # `calibc solve --min-error NAME --json`


def read(result: str, validation: str | None = None, identify: str | None = None,
         min_error: str | None = None) -> Documents:
    found = _read(result, "a solve's result", ("parameters", "verdict"))
    check_intervals(result, found)
    val = None if validation is None else _read(validation, "a validation", ("coverage",))
    ident = None if identify is None else _read(identify, "an identification", ("rank",))
    bracket = None if min_error is None else _read(min_error, "a --min-error bracket",
                                                   ("min_error",))["min_error"]
    names = tuple(p for p in (result, validation, identify, min_error) if p is not None)
    return Documents(found, val, ident, names, bracket)


def _read(path: str, what: str, keys: tuple[str, ...]) -> dict[str, Any]:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise CalError(f"cannot read '{path}': no such file") from None
    except (OSError, UnicodeDecodeError) as err:
        raise CalError(f"cannot read '{path}': {getattr(err, 'strerror', None) or err}") \
            from None
    try:
        data = json.loads(text, parse_constant=_no_constant)
    except json.JSONDecodeError as err:
        raise CalError(f"not JSON: {err.msg}", Loc(path, err.lineno, err.colno)) from None
    except ValueError as err:
        raise CalError(str(err), Loc(path, 1, 1)) from None
    missing = [k for k in keys if not isinstance(data, dict) or k not in data]
    if missing:
        raise CalError(f"'{path}' is not {what}'s JSON (no '{missing[0]}')", Loc(path, 1, 1))
    return data


def _no_constant(name: str) -> Any:
    raise ValueError(f"not strict JSON: {name} (calibc writes '+oo', '-oo' or null)")
