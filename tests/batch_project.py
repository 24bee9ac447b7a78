"""A small batch for the batch tests: a line fit with an error bound `e`, its tables, and a
job file with a job of each kind (contracted, infeasible, a missing and a malformed file,
rows, consts, other strategies and formulations); and the same solves run directly."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from calib_dsl.elaborate.options import inputs_from_options
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.pipeline import load, solve

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "models" / "examples"

LINE = """const e = 0.01;
param p in [0, 1];
param q in [-1, 1];
table m = "a.csv" { x : +- 0; y : +- e; }
for k in 1..rows(m) { m.y[k] == p * m.x[k] + q; }
"""
FILES = {
    "line.cal": LINE,
    "a.csv": "x,y\n0,0.1\n1,0.6\n2,1.1\n3,1.605\n",
    "runs/b.csv": "x,y\n0,0.2\n1,0.5\n2,0.81\n",
    "runs/c.csv": "x,y\n0,-0.3\n1,0.2\n2,0.7\n3,1.2\n",
    "bad.csv": "x,y\n0,0.1\n1,nan\n",
}
# paths relative to the job file's folder; the examples by absolute path
JOBS = f"""# defaults for every job
model = "line.cal"

[[job]]
id = "a"
data = "a.csv"

[[job]]
id = "b-hc4"
data = "m=runs/b.csv"
strategy = "hc4"

[[job]]
id = "rows"
rows = "1..3"
exclude = ["m=2"]

[[job]]
id = "wide-e"
define = {{e = 0.05}}

[[job]]
id = "tight-e"
define = {{e = "0.001"}}

[[job]]
id = "missing"
data = "nope.csv"

[[job]]
id = "malformed"
data = ["bad.csv"]

[[job]]
id = "arm"
model = "{EXAMPLES / 'planar_arm.cal'}"
formulation = "rotation"

[[job]]
id = "circle"
model = "{EXAMPLES / 'circle_fit.cal'}"
identify = false
lsq = true
"""
STATUS = {"a": "contracted", "b-hc4": "contracted", "rows": "contracted",
          "wide-e": "contracted", "tight-e": "infeasible", "missing": "error",
          "malformed": "error", "arm": "contracted", "circle": "contracted"}


def write_project(folder: Path) -> Path:
    """The model, tables and job file in `folder`; the job file's path."""
    for name, text in {**FILES, "jobs.toml": JOBS}.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(text, encoding="utf-8")
    return folder / "jobs.toml"


def direct(job: dict[str, Any]) -> tuple[str, Any]:
    """The job's solve run here with the pipeline's functions: (status, {name: [lo, hi]}),
    or ("error", the rendered message)."""
    try:
        inputs = inputs_from_options(tuple(job["data"]), tuple(job["rows"]),
                                     tuple(job["exclude"]), tuple(job["defines"]))
        prog = load(job["model"], job["formulation"], inputs=inputs)
    except CalError as err:
        return "error", err.render()
    sol = solve(prog, job["strategy"], tol=job["tol"], max_sweeps=job["max_sweeps"])
    s = prog.slots
    boxes = {name: [float(sol.lo[slot]), float(sol.hi[slot])]
             for name, slot in zip(s.declared_names, s.declared, strict=True)}
    return sol.status, None if sol.status == "infeasible" else boxes


def intervals(result: dict[str, Any]) -> dict[str, list[float]] | None:
    """A result line's intervals as floats (JSON writes infinite ends as "-oo"/"+oo")."""
    if result["status"] == "infeasible":
        return None
    ends = {"-oo": -math.inf, "+oo": math.inf}
    return {name: [ends.get(x, x) for x in p["result"]]
            for name, p in result["parameters"].items()}
