"""The command line run in this process (click's runner) from a given folder: the tests that
check what calibc prints and exits with, with relative paths as a user types them."""

from __future__ import annotations

import os
from pathlib import Path

from click.testing import CliRunner, Result

from calib_dsl import cli


def run(*args: object, cwd: Path | None = None) -> Result:
    """`calibc ARGS` from `cwd` (this folder if None); an exception that escapes is raised."""
    old = Path.cwd()
    os.chdir(cwd or old)
    try:
        return CliRunner().invoke(cli.main, [str(a) for a in args], catch_exceptions=False)
    finally:
        os.chdir(old)
