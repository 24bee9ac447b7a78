"""Measurements at given configurations (`calibc simulate --at`): the model's true values,
its error model and a seed, at the poses of a file instead of drawn ones; the measured table
written in the table's own dialect."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from calib_dsl.elaborate.elaborator import Inputs, elaborate
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.model import Model
from calib_dsl.outliers.beyond_limits import outside_limits
from calib_dsl.plan.configs import Configurations, read_configurations, table_of
from calib_dsl.studies.campaign import PLAIN, Campaign
from calib_dsl.studies.simulate import simulate_model, write_csv


def measured_at(model_path: str | Path, configs: Configurations, seed: int,
                formulation: str = "matrix", campaign: Campaign = PLAIN,
                consts: Mapping[str, str] | None = None) -> tuple[Model, np.ndarray]:
    """The model elaborated for the configurations, and its table measured at them: (rows,
    columns) in the model's units (the inputs too, with their noise, as `simulate`)."""
    model = elaborate(str(model_path), formulation=formulation, simulate_rows=len(configs),
                      inputs=Inputs(consts=dict(consts or {})))
    if len(model.tables) != 1:
        raise CalError(f"the model has {len(model.tables)} tables; simulate --at measures "
                       "one", model.tables[-1].loc if model.tables else None)
    t = table_of(model, configs.table)
    return model, simulate_model(model, seed, campaign, {t.name: configs.q})[t.name]


def simulate_at(model_path: str | Path, at: str | Path, seed: int, out: str | Path,
                formulation: str = "matrix", campaign: Campaign = PLAIN,
                consts: Mapping[str, str] | None = None, table: str = ""
                ) -> tuple[int, list[str]]:
    """Measure the model's table at the configurations of the file `at` (in the table's
    dialect; its measured columns may be absent) and write it to `out`; the row count, and
    a warning per column beyond its joint's limits (beyond_limits_at)."""
    first = elaborate(str(model_path), formulation=formulation, simulate_rows=1,
                      inputs=Inputs(consts=dict(consts or {})))
    configs = read_configurations(table_of(first, table), at)
    model, data = measured_at(model_path, configs, seed, formulation, campaign, consts)
    write_csv(Path(out), table_of(model, configs.table), data)
    return len(configs), beyond_limits_at(first, configs)


def beyond_limits_at(model: Model, configs: Configurations) -> list[str]:
    """A warning per input column of the configurations (read with `model`'s table) whose
    values leave the limits of the joint the column feeds: simulated there, the table
    measures poses the robot cannot take (a column in degrees read as radians, a typo) and
    nothing else would say so."""
    out = []
    for j, name in enumerate(configs.columns):
        limits = model.joint_limits.get((configs.table, name))
        if limits is None:
            continue
        q = configs.q[:, j]
        bad = np.flatnonzero((q < limits[0]) | (q > limits[1]))
        if len(bad):
            out.append(outside_limits(
                f"{configs.table}.{name}", limits, bad, q,
                lambda k: f"{configs.path}:{configs.line[k]}"
                if k < len(configs.line) else f"row {k + 1}"))
    return out
