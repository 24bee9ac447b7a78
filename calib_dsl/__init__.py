"""calibc: guaranteed robot calibration by interval constraint propagation.

The Python API (calib_dsl/api.py, docs/api.md) is re-exported here: `calib_dsl.load`,
`calib_dsl.solve`, ... It is imported on first use, so that `calibc` (which does not use it)
starts without loading the solvers.
"""

import os
from typing import Any

# numpy's and scipy's OpenBLAS, one thread unless the user says otherwise (before numpy is
# first imported, when OpenBLAS reads it). calibc shares the cores among its own chunk and LP
# threads already, and its linear algebra is on tall, thin matrices (rows by a few dozen
# unknowns: the fits' SVDs and steps) that one thread does in milliseconds; OpenBLAS's extra
# threads busy-wait for work, and on a busy host that wait costs each such call far more CPU
# than the call itself (docs/decisions/53). A threaded product also splits its sums by the
# thread count, so a result's last bits depended on the machine's cores: with one thread,
# they are the same on every machine, as CALIBC_CORES promises (settings.py).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"

_API = ("CalError", "Inconsistent", "Listing", "Parameter", "Problem", "Result", "identify",
        "listing", "load", "min_error", "predict", "solve")
__all__ = list(_API)


def __getattr__(name: str) -> Any:
    if name in _API:
        from calib_dsl import api

        return getattr(api, name)
    raise AttributeError(f"module 'calib_dsl' has no attribute {name!r}")
