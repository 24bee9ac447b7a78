"""The export formats by name (`calibc export --format NAME`, `solve --export-domains`): each
an `Export` that writes a result's JSON, with the model's robots as frames where it reads
them, at the exported point (report/export_point.py). A new format is a writer (export.py,
urdf.py, ur_kinematics.py) and an entry here. The frames are the caller's to build
(`asked` says over which box and at which point): rendering never elaborates a model."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.status import Status
from calib_dsl.report.dh_convert import CONVENTIONS, converted
from calib_dsl.report.export import (
    RobotTable,
    dh_table,
    domains_cal,
    export_json,
    number,
    units_of,
)
from calib_dsl.report.export_point import export_point
from calib_dsl.report.strict_json import dumps
from calib_dsl.report.ur_kinematics import ur_kinematics
from calib_dsl.report.urdf import cell, urdf


@dataclass(frozen=True)
class Exported:
    """What a writer reads: the result's JSON, and the model's robots as frames of
    guaranteed entries (empty for a format that reads none) with their units, and the
    parameter vector written."""

    data: dict[str, Any]
    model: str = ""
    tables: list[RobotTable] = field(default_factory=list)
    units: dict[str, str] = field(default_factory=dict)
    point: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Export:
    write: Callable[[Exported], str]
    reads_robots: bool  # the model's robots are read for it (from the model file)
    needs_robot: bool  # a model without a robot has nothing to write in it


def _json(e: Exported) -> str:
    return dumps(export_json(e.data, e.tables, e.units, units_of(e.tables, e.units), e.point),
                 indent=2) + "\n"


EXPORTS: dict[str, Export] = {
    "dh-table": Export(lambda e: dh_table(e.data, e.tables, e.units), True, True),
    "urdf": Export(lambda e: urdf(e.model, e.tables, e.units), True, True),
    "cell": Export(lambda e: cell(e.model, e.tables, e.units), True, True),
    "ur-kinematics": Export(lambda e: ur_kinematics(e.model, e.tables, e.units), True, True),
    "json": Export(_json, True, False),
    "cal": Export(lambda e: domains_cal(e.data), False, False),
}


@dataclass(frozen=True)
class Request:
    fmt: str
    model: str | Path | None = None  # default: the model the result names
    point: str = "midpoint"  # midpoint | lsq | centre
    convention: str | None = None  # the joints in mdh or dh (default: the model's)


def _why_none(data: dict[str, Any]) -> str:
    found = data.get("min_error")
    if isinstance(found, dict):
        bracket = found.get("bracket") or [None, None]
        hi = bracket[1] if len(bracket) == 2 and bracket[1] is not None else "UPPER"
        return ("it is a --min-error result: export a solve at a bound the bracket proves "
                f"consistent, calibc solve --json FILE -D {found.get('name', 'NAME')}={hi}")
    if data.get("status") == Status.INFEASIBLE:
        return "the solve proved the data inconsistent: there is no box"
    return "calibc solve --json FILE writes one"


@dataclass(frozen=True)
class Asked:
    """An export asked of a result: its format, and the frames it reads (the model's robots
    over the result's box, at the point written), which the caller builds from `source`."""

    data: dict[str, Any]
    request: Request
    kind: Export
    source: str = ""  # the model whose robots it reads ("": it reads none)
    box: dict[str, tuple[float, float]] = field(default_factory=dict)
    point: dict[str, float] = field(default_factory=dict)


def asked(data: dict[str, Any], request: Request) -> Asked:
    """What the result of a solve (its JSON, `data`) in the format asked needs: checked."""
    if data.get("status") != Status.CONTRACTED or not isinstance(data.get("parameters"), dict):
        raise CalError(f"the result holds no guaranteed box to export ({_why_none(data)})")
    kind = EXPORTS.get(request.fmt)
    if kind is None:
        raise CalError(f"unknown export format '{request.fmt}' (one of {', '.join(EXPORTS)})")
    box = _box(data["parameters"])  # (checked for every format: each writes the box)
    if not kind.reads_robots:
        return Asked(data, request, kind)
    if request.convention is not None and request.convention not in CONVENTIONS:
        raise CalError(f"unknown convention '{request.convention}' (mdh or dh)")
    source = request.model or data.get("model")
    if not source:
        raise CalError("the result does not name its model: give it with --model")
    return Asked(data, request, kind, str(source), box, export_point(data, request.point))


def _box(parameters: dict[str, Any]) -> dict[str, tuple[float, float]]:
    """Each parameter's result as numbers, checked to be an interval (a NaN end or ends in
    the wrong order are a damaged file: no export of it would be guaranteed)."""
    try:
        box = {name: (number(p["result"][0]), number(p["result"][1]))
               for name, p in parameters.items()}
    except (KeyError, TypeError, ValueError, IndexError) as err:
        raise CalError(f"the result's parameters are malformed ({err!r})") from None
    for name, (lo, hi) in box.items():
        if not lo <= hi:  # (False for a NaN end too)
            raise CalError(f"the result's parameters are malformed ({name}: [{lo}, {hi}] "
                           "is not an interval)")
    return box


def export(job: Asked, tables: list[RobotTable], units: dict[str, str]) -> str:
    """The export asked, with the model's robots as frames (`tables`, and the model's
    `units`; none when `job.source` is empty)."""
    if not job.kind.reads_robots:
        return job.kind.write(Exported(job.data))
    if job.request.convention is not None:
        tables = [converted(t, job.request.convention) for t in tables]
    if job.kind.needs_robot and not tables:
        raise CalError(f"{job.source} has no robot: a {job.request.fmt} export needs one "
                       "(--format json writes its parameters)")
    return job.kind.write(Exported(job.data, job.source, tables, units, job.point))
