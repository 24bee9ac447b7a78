"""`make bench-checks`: the checks too heavy for `make test` (whole solves on the public UR10
file, campaigns of thousands of rows), run by pytest so that each asserts its property and a
failure fails the run loudly. The suite's fixtures and hypothesis profile are shared."""

from tests.conftest import calibc, untimed, write_model  # noqa: F401  (fixtures)
