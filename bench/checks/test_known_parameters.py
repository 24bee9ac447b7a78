"""Test A's 19 parameters known to +-1e-5 named on one line of the solve's table (two whole
solves of the RX90): too heavy for `make test`, where tests/test_cli.py keeps the same
naming on a line fit with one known curvature
(test_known_parameters_are_named_not_listed_unless_all)."""

from __future__ import annotations

import re

from tests.test_cli import ROOT, run, table_row


def test_test_a_s_known_parameters_are_named_not_listed_unless_all():
    """Test A's 19 parameters known to +-1e-5: the data cannot improve them, so the table
    names them on one line (--all lists them); those not identifiable alone stay listed."""
    model = ROOT / "models" / "rx90_lengths.cal"
    short = run("solve", model, "--no-inner")
    every = run("solve", model, "--no-inner", "--all")
    assert short.exit_code == every.exit_code == 0
    assert table_row(every.stdout, "theta0")[0] == "[1.570786327, 1.570806327]"
    assert not re.search(r"^theta0\s", short.stdout, re.M)
    assert re.search(r"^\(17 more kept their whole search domain, not shown: theta0 ", short.stdout,
                     re.M)
    for name in ("r0", "b3z", "r2", "r3"):  # narrowed, or not identifiable alone
        table_row(short.stdout, name)
    assert short.stdout.startswith("verdict: consistent: ")
    assert "\n\n# result: proven to hold every consistent value" in short.stdout
