"""One job, run where Dask puts it: the steps of `calibc solve --json`, as one result line.

`solve_job` makes the call `calibc solve` makes (pipeline.solve_report) with the same
arguments, so a job's result is the `--json` document of the same solve run by hand (timing
aside). `run_job` never raises: a user error (a missing or malformed file, a bad const) is a
line of status "error" with the message the command line would print, a bug of ours one of
status "failed"; the batch goes on either way.
"""

from __future__ import annotations

import time
from typing import Any

from calib_dsl.batch.jobs import Job
from calib_dsl.elaborate.options import inputs_from_options
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.pipeline import SolveRequest, solve_report


def run_job(job: Job) -> dict[str, Any]:
    """The job's result line: id, status, seconds, the job, then its result or error."""
    start = time.perf_counter()
    outcome: dict[str, Any]
    try:
        result = solve_job(job)
        outcome = {"status": result["status"], "result": result}
    except CalError as err:
        outcome = {"status": "error", "error": err.render()}
    except RecursionError:  # as the command line says it
        outcome = {"status": "error", "error": "error: the model nests too deeply to elaborate"}
    except Exception as exc:  # a bug of ours: recorded, and the other jobs go on
        outcome = {"status": "failed", "error": f"internal error: {type(exc).__name__}: {exc}"}
    return {"id": job.id, "status": outcome.pop("status"),
            "seconds": time.perf_counter() - start, "job": job.spec(), **outcome}


def solve_job(job: Job) -> dict[str, Any]:
    """What `calibc solve` writes with --json for the job's arguments (`job.argv()`)."""
    inputs = inputs_from_options(job.data, job.rows, job.exclude, job.defines)
    return solve_report(SolveRequest(job.model, job.formulation, inputs, job.strategy, job.tol,
                                     job.max_sweeps, job.identify, job.lsq, job.inner,
                                     job.diagnose, job.outliers, job.shave)).as_json()
