"""The jobs of a batch: a TOML job file, or one model over the data files a pattern matches.

    model = "arm.cal"            # keys before the first [[job]]: every job's default
    [[job]]
    id = "arm-a"
    data = "runs/a.csv"          # or a list: ["m=runs/a.csv", "n=b.csv"], as --data
    define = {e = "1.2"}         # as -D e=1.2
    [[job]]
    id = "arm-b"
    data = "runs/b.csv"
    rows = "1..100"              # as --rows; exclude = "7,9" as --exclude
    strategy = "hc4"

Paths are relative to the job file's folder and are made absolute here, so a worker of a
cluster started elsewhere finds the same files (on a file system it shares). A mistake in the
file is a CalError at its line: nothing runs until every job is well formed.
"""

from __future__ import annotations

import glob
import os
import re
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from fractions import Fraction
from pathlib import Path
from typing import Any

from calib_dsl.elaborate.chains import FORMULATIONS
from calib_dsl.elaborate.options import consts, named
from calib_dsl.elaborate.rows import parse_numbers, parse_ranges
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.strategy.tight import STRATEGIES


@dataclass(frozen=True)
class Job:
    """One solve, in the command line's terms (see `argv`); plain data, so Dask can send it."""

    id: str
    model: str
    data: tuple[str, ...] = ()  # [TABLE=]CSV, as --data
    rows: tuple[str, ...] = ()  # [TABLE=]RANGES, as --rows
    exclude: tuple[str, ...] = ()  # [TABLE=]ROWS, as --exclude
    defines: tuple[str, ...] = ()  # NAME=VALUE, as -D
    strategy: str = STRATEGIES[0]
    formulation: str = FORMULATIONS[0]
    tol: float = 1e-5  # calibc solve's defaults
    max_sweeps: int = 1000
    identify: bool = True
    lsq: bool = False
    inner: bool | None = None  # None: calibc solve's default
    diagnose: bool = True
    outliers: int = 0  # as --outliers K: all rows but at most K (0: every row holds)
    shave: int | None = None  # as --shave N (None: calibc solve's default)

    def argv(self) -> list[str]:
        """The `calibc solve` arguments that run the same solve."""
        out = [self.model, "--strategy", self.strategy, "--formulation", self.formulation,
               "--tol", repr(self.tol), "--max-sweeps", str(self.max_sweeps)]
        for option, values in (("--data", self.data), ("--rows", self.rows),
                               ("--exclude", self.exclude), ("-D", self.defines)):
            for v in values:
                out += [option, v]
        out.append("--identify" if self.identify else "--no-identify")
        if self.inner is not None:
            out.append("--inner" if self.inner else "--no-inner")
        out.append("--diagnose" if self.diagnose else "--no-diagnose")
        out += ["--outliers", str(self.outliers)] if self.outliers else []
        out += ["--shave", str(self.shave)] if self.shave is not None else []
        return out + (["--lsq"] if self.lsq else [])

    def spec(self) -> dict[str, Any]:
        """The job as JSON data (a result line says what ran)."""
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
                for f in fields(self)}


Fail = Callable[[str, str], CalError]  # (key, message) -> the error, at the key's line

# the file's keys -> Job's fields; `define` is a TOML table, the others a value or a list
KEYS = {"id": "id", "model": "model", "data": "data", "rows": "rows", "exclude": "exclude",
        "define": "defines", "strategy": "strategy", "formulation": "formulation",
        "tol": "tol", "max-sweeps": "max_sweeps", "identify": "identify", "lsq": "lsq",
        "inner": "inner", "diagnose": "diagnose", "outliers": "outliers", "shave": "shave"}


def read_job_file(path: str) -> list[Job]:
    """The jobs of the TOML file at `path` (CalError at the place of the first mistake)."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        reason = getattr(err, "strerror", None) or err
        raise CalError(f"cannot read the job file '{path}': {reason}") from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise _toml_error(path, str(err)) from None
    where = Places(path, text)
    entries = doc.pop("job", None)
    if not isinstance(entries, list) or not entries or not all(
            isinstance(e, dict) for e in entries):
        raise CalError("no jobs: write one [[job]] table per job (see docs/batch.md)",
                       where.at(-1, "job"))
    if "id" in doc:
        raise CalError("'id' belongs to each [[job]], not to the defaults at the top",
                       where.at(-1, "id"))
    folder = Path(path).parent
    jobs = [_job({**doc, **entry}, folder, where, k, set(entry))
            for k, entry in enumerate(entries)]
    seen: dict[str, int] = {}
    for k, job in enumerate(jobs):
        if job.id in seen:
            raise CalError(f"job id '{job.id}' is used twice (by jobs {seen[job.id] + 1} and "
                           f"{k + 1}): an id names one result line", where.at(k, "id"))
        seen[job.id] = k
    return jobs


def glob_jobs(model: str, pattern: str, template: Job) -> list[Job]:
    """One job per file matching `[TABLE=]PATTERN` (relative to the current folder, as
    --data), each as `template` (its id and model aside) with that file as the table's
    data; the id is the file's path as matched."""
    table, files = named(pattern, "--data-glob")
    found = sorted(f for f in glob.glob(files, recursive=True) if Path(f).is_file())
    if not found:
        raise CalError(f"--data-glob {pattern}: no file matches")
    here = Path.cwd()
    # the options are checked once here, not found wrong by every job
    for key in ("--rows", "--exclude"):
        _listed(key, list(getattr(template, key[2:])), here, _option_error)
    consts(template.defines)
    data = _listed("--data", list(template.data), here, _option_error)
    prefix = f"{table}=" if table else ""
    return [replace(template, id=f, model=_resolve(here, model),
                    data=(*data, prefix + _resolve(here, f)))
            for f in found]


def _option_error(key: str, message: str) -> CalError:
    return CalError(f"{key} {message}")


def _job(entry: dict[str, Any], folder: Path, where: Places, k: int,
         own: set[str]) -> Job:
    """Job number k from its keys (`own`: those the job set itself, the rest are defaults)."""
    for key in entry:
        if key not in KEYS:
            raise CalError(f"unknown key '{key}' (a job's keys: {', '.join(KEYS)})",
                           where.at(k if key in own else -1, key))

    def fail(key: str, message: str) -> CalError:
        return CalError(f"{key}: {message}", where.at(k if key in own else -1, key))

    if "id" not in entry or "model" not in entry:
        missing = "id" if "id" not in entry else "model"
        raise CalError(f"job {k + 1} has no '{missing}'", where.at(k, None))
    values: dict[str, Any] = {}
    for key, value in entry.items():
        values[KEYS[key]] = _value(key, value, folder, fail)
    return Job(**values)


def _value(key: str, value: Any, folder: Path, fail: Fail) -> Any:
    if key in ("id", "model", "strategy", "formulation"):
        if not isinstance(value, str) or not value.strip() or "\n" in value:
            raise fail(key, "must be a non-empty string on one line")
        if key == "model":
            return _resolve(folder, value)
        choices = {"strategy": STRATEGIES, "formulation": FORMULATIONS}.get(key)
        if choices and value not in choices:
            raise fail(key, f"'{value}' is not one of {', '.join(choices)}")
        return value
    if key == "define":
        return _defines(value, fail)
    if key in ("data", "rows", "exclude"):
        return _listed(key, value, folder, fail)
    if key in ("identify", "lsq", "inner", "diagnose"):
        if not isinstance(value, bool):
            raise fail(key, "must be true or false")
        return value
    if key == "tol":
        if isinstance(value, bool) or not isinstance(value, int | float) or not (
                0 <= value < float("inf")):
            raise fail(key, "must be a finite number >= 0")
        return float(value)
    if key in ("outliers", "shave"):
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise fail(key, "must be an integer >= 0")
        return value
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:  # max-sweeps
        raise fail(key, "must be an integer >= 1")
    return value


def _listed(key: str, value: Any, folder: Path, fail: Fail) -> tuple[str, ...]:
    """data, rows, exclude: one string or a list of them, each `[TABLE=]TEXT`; data paths
    made absolute, rows and exclude checked here (where the line is known)."""
    items = [value] if isinstance(value, str) else value
    if not isinstance(items, list) or not all(isinstance(v, str) for v in items):
        raise fail(key, "must be a string or a list of strings")
    out = []
    kind = key.lstrip("-")  # a job file's key, or the option (--data-glob's jobs)
    for item in items:
        table, text = named(item, key)
        if kind == "data":
            text = _resolve(folder, text)
        else:
            try:
                (parse_ranges if kind == "rows" else parse_numbers)(text)
            except ValueError as err:
                raise fail(key, f"'{item}': {err}") from None
        out.append(f"{table}={text}" if table else text)
    return tuple(out)


def _defines(value: Any, fail: Fail) -> tuple[str, ...]:
    if not isinstance(value, dict):
        raise fail("define", "must be a table of const values, e.g. define = {e = \"1.2\"}")
    out = []
    for name, v in value.items():
        if not name.isidentifier():
            raise fail("define", f"'{name}' is not a const name")
        if isinstance(v, bool) or not isinstance(v, str | int | float):
            raise fail("define", f"{name}: the value must be a number or a string")
        text = v if isinstance(v, str) else repr(v)
        try:
            Fraction(text.strip())
        except (ValueError, ZeroDivisionError, OverflowError):
            raise fail("define", f"{name} = {text}: the value must be a number (as 1.2, "
                       "-3e-4 or 1/3)") from None
        out.append(f"{name}={text}")
    return tuple(out)


def _resolve(folder: Path, path: str) -> str:
    return os.path.abspath(os.path.join(folder, os.path.expanduser(path)))


def _toml_error(path: str, message: str) -> CalError:
    """tomllib's "... (at line 3, column 5)" as a CalError at that place."""
    m = re.search(r"\s*\(at line (\d+), column (\d+)\)\s*$", message)
    if m is None:
        return CalError(f"not a valid TOML file: {message}", Loc(path, 1, 1))
    return CalError(f"not valid TOML: {message[:m.start()]}",
                    Loc(path, int(m.group(1)), int(m.group(2))))


class Places:
    """Where each [[job]] and each `key =` line is: tomllib gives values, not lines."""

    _HEADER = re.compile(r"\s*\[\[\s*job\s*\]\]")
    _KEY = re.compile(r"\s*([A-Za-z0-9_-]+|\"[^\"]*\"|'[^']*')\s*=")

    def __init__(self, file: str, text: str) -> None:
        self.file = file
        self.headers: list[int] = []
        self.keys: dict[tuple[int, str], Loc] = {}
        job: int | None = -1  # -1: the top, before any table; None: another table
        for n, line in enumerate(text.splitlines(), 1):
            if self._HEADER.match(line):
                self.headers.append(n)
                job = len(self.headers) - 1
            elif line.lstrip().startswith("["):
                job = None
            elif (m := self._KEY.match(line)) and job is not None:
                key = m.group(1).strip("\"'")
                self.keys.setdefault((job, key), Loc(self.file, n, m.start(1) + 1))

    def at(self, job: int, key: str | None) -> Loc:
        """The line of `key` in job number `job` (-1: the defaults), else the job's header,
        else the top of the file."""
        if key is not None and (job, key) in self.keys:
            return self.keys[(job, key)]
        if 0 <= job < len(self.headers):
            return Loc(self.file, self.headers[job], 1)
        return self.keys.get((-1, "job"), Loc(self.file, 1, 1))


# the per-job options of the command line, as named there (only with --data-glob)
OPTIONS = {"strategy": "--strategy", "formulation": "--formulation", "data": "--data",
           "rows": "--rows", "exclude": "--exclude", "defines": "-D"}


def batch_jobs(source: str, data_glob: str | None, **options: Any) -> list[Job]:
    """`calibc batch SOURCE`'s jobs: the job file SOURCE, or with `data_glob` the model
    SOURCE once per matching file, with the command line's per-job `options` (OPTIONS;
    None or empty: not given), which a job file sets itself."""
    given = {k: v for k, v in options.items() if v}
    if data_glob is None:
        if given:
            raise CalError(f"{OPTIONS[next(iter(given))]} goes with --data-glob; a job file "
                           "sets it for each job (or for all at its top)")
        return read_job_file(source)
    return glob_jobs(source, data_glob, Job("", source, **given))
