"""calibc: guaranteed robot calibration by interval constraint propagation.

The Python API (calib_dsl/api.py, docs/api.md) is re-exported here: `calib_dsl.load`,
`calib_dsl.solve`, ... It is imported on first use, so that `calibc` (which does not use it)
starts without loading the solvers.
"""

from typing import Any

__version__ = "0.1.0"

_API = ("CalError", "Inconsistent", "Listing", "Parameter", "Problem", "Result", "identify",
        "listing", "load", "min_error", "predict", "solve")
__all__ = list(_API)


def __getattr__(name: str) -> Any:
    if name in _API:
        from calib_dsl import api

        return getattr(api, name)
    raise AttributeError(f"module 'calib_dsl' has no attribute {name!r}")
