"""The README's example is what the tool does: its listing of paper_cse.cal is the output of
`calibc compile models/examples/paper_cse.cal`, byte for byte, and the model it shows is the
file's own statements (so neither can drift from the other)."""

from __future__ import annotations

import os
import re
from pathlib import Path

from click.testing import CliRunner

from calib_dsl import cli

ROOT = Path(__file__).resolve().parents[1]
COMMAND = "calibc compile models/examples/paper_cse.cal"


def fenced_after(text: str, marker: str) -> str:
    """The first fenced block after the line that mentions `marker`."""
    at = text.index(marker)
    m = re.compile(r"^```\w*\n(.*?)^```", re.S | re.M).search(text, at)
    assert m, f"no fenced block after {marker!r}"
    return m.group(1)


def test_the_readme_listing_is_the_tools_output():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    shown = fenced_after(readme, f"`{COMMAND}` prints")
    old = Path.cwd()
    os.chdir(ROOT)  # the listing names the model as the command was given it
    try:
        res = CliRunner().invoke(cli.main, COMMAND.split()[1:], catch_exceptions=False)
    finally:
        os.chdir(old)
    assert res.exit_code == 0
    assert shown == res.stdout


def test_the_readme_model_is_the_files_statements():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    shown = fenced_after(readme, "`models/examples/paper_cse.cal` is the paper's")
    source = (ROOT / "models" / "examples" / "paper_cse.cal").read_text(encoding="utf-8")
    statements = [ln for ln in source.splitlines() if ln.strip() and not ln.startswith("#")]
    assert shown.splitlines() == statements
