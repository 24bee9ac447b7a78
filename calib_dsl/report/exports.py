"""`calibc export`: a solve's result (its JSON) in each format a controller or the next run
takes, one function per format in `FORMATS` (the registry docs/design.md names). The
robots are read from the model the result names; the values written are those of the
exported point (report/export_point.py)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from calib_dsl.analysis.robot_frames import RobotTable, robot_tables
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.report.dh_convert import CONVENTIONS, converted
from calib_dsl.report.export import dh_table, domains_cal, export_json, number, units_of
from calib_dsl.report.export_point import export_point
from calib_dsl.report.strict_json import dumps
from calib_dsl.report.ur_kinematics import ur_kinematics
from calib_dsl.report.urdf import cell, urdf


@dataclass(frozen=True)
class Request:
    fmt: str
    model: str | Path | None = None  # default: the model the result names
    point: str = "midpoint"  # midpoint | lsq | centre
    convention: str | None = None  # dh-table: the joints in mdh or dh (default: the model's)


Writer = Callable[[dict[str, Any], list[RobotTable], dict[str, str], dict[str, float]], str]

FORMATS: dict[str, Writer] = {
    "dh-table": lambda data, tables, units, point: dh_table(data, tables, units),
    "urdf": lambda data, tables, units, point: urdf(str(data.get("model")), tables, units),
    "cell": lambda data, tables, units, point: cell(str(data.get("model")), tables, units),
    "ur-kinematics": lambda data, tables, units, point: ur_kinematics(
        str(data.get("model")), tables, units),
    "json": lambda data, tables, units, point: dumps(
        export_json(data, tables, units, units_of(tables, units), point), indent=2) + "\n",
}


def export(data: dict[str, Any], request: Request) -> str:
    """The result of a solve (its JSON, `data`) in the format asked: `cal` (search domains
    for the next run), or a format of FORMATS (values with their guaranteed half-widths)."""
    if data.get("status") != "contracted" or not isinstance(data.get("parameters"), dict):
        raise CalError("the result holds no guaranteed box to export (calibc solve --json "
                       "writes one; an infeasible solve has none)")
    if request.fmt == "cal":
        return domains_cal(data)
    if request.fmt not in FORMATS:
        raise CalError(f"unknown export format '{request.fmt}' (one of cal, "
                       f"{', '.join(FORMATS)})")
    if request.convention is not None and request.convention not in CONVENTIONS:
        raise CalError(f"unknown convention '{request.convention}' (mdh or dh)")
    source = request.model or data.get("model")
    if not source:
        raise CalError("the result does not name its model: give it with --model")
    try:
        box = {name: (number(p["result"][0]), number(p["result"][1]))
               for name, p in data["parameters"].items()}
    except (KeyError, TypeError, ValueError, IndexError) as err:
        raise CalError(f"the result's parameters are malformed ({err!r})") from None
    point = export_point(data, request.point)
    tables, units = robot_tables(source, box, point)
    if request.convention is not None:
        tables = [converted(t, request.convention) for t in tables]
    if not tables and request.fmt != "json":
        raise CalError(f"{source} has no robot: a {request.fmt} export needs one (--format "
                       "json writes its parameters)")
    return FORMATS[request.fmt](data, tables, units, point)
