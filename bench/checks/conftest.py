"""`make bench-checks`: the checks too heavy for `make test` (whole solves on the public UR10
file, campaigns of hundreds to thousands of rows), run by pytest so that each asserts its
property and a failure fails the run loudly. The suite's fixtures, helpers and hypothesis
profile are shared."""

import sys
from pathlib import Path

# the suite's helper modules import one another by their bare names (tests/ on the path, as
# pytest puts it there for the suite)
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

from tests.conftest import calibc, untimed, write_model  # noqa: E402, F401  (fixtures)
