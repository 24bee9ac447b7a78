"""The export formats by name (`calibc export --format NAME`, `solve --export-domains`): each
an `Export` that writes a result's JSON, with the model's robots as frames where it reads
them. A new format is a writer (export.py, urdf.py) and an entry here."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from calib_dsl.report.export import dh_table, domains_cal, export_json, units_of
from calib_dsl.report.strict_json import dumps
from calib_dsl.report.urdf import urdf
from calib_dsl.studies.robot_frames import RobotTable


@dataclass(frozen=True)
class Exported:
    """What a writer reads: the result's JSON, and the model's robots as frames of
    guaranteed entries (empty for a format that reads none) with their units."""

    data: dict[str, Any]
    model: str = ""
    tables: list[RobotTable] = field(default_factory=list)
    units: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Export:
    write: Callable[[Exported], str]
    reads_robots: bool  # the model's robots are read for it (from the model file)
    needs_robot: bool  # a model without a robot has nothing to write in it


def _json(e: Exported) -> str:
    return dumps(export_json(e.data, e.tables, e.units, units_of(e.tables, e.units)),
                 indent=2) + "\n"


EXPORTS: dict[str, Export] = {
    "dh-table": Export(lambda e: dh_table(e.data, e.tables, e.units), True, True),
    "urdf": Export(lambda e: urdf(e.model, e.tables, e.units), True, True),
    "json": Export(_json, True, False),
    "cal": Export(lambda e: domains_cal(e.data), False, False),
}
