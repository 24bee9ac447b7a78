"""`python -m calib_dsl` is the `calibc` command (where its script is not on the path)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_python_m_runs_the_command_line(tmp_path):
    model = tmp_path / "m.cal"
    model.write_text("param x in [0, 10];\nx * x <= 4;\n")
    ok = subprocess.run([sys.executable, "-m", "calib_dsl", "solve", str(model), "-q"],
                        capture_output=True, text=True, cwd=ROOT)
    assert ok.returncode == 0 and "x" in ok.stdout and "2" in ok.stdout, ok.stderr
    bad = subprocess.run([sys.executable, "-m", "calib_dsl", "solve", str(model), "--tol",
                          "x"], capture_output=True, text=True, cwd=ROOT)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "error:" in bad.stderr
    assert "calibc solve --help" in bad.stderr  # the command's own name
