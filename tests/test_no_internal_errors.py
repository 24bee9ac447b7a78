"""User data never end in exit 3 (an internal error): a model whose rows cannot be evaluated
at the middle of its domains (sqrt of a negative) through every command."""

from __future__ import annotations

from click.testing import CliRunner

from calib_dsl import cli

SQRT = """param p in [-4, 2];
table m = "s.csv" { y : +- 0.1; }
for k in 1..rows(m) { sqrt(p) == m.y[k]; }
"""
DATA = {"s.csv": "y\n1.0\n1.1\n0.9\n1.05\n"}


def _run(*args: str) -> tuple[int, str]:
    res = CliRunner().invoke(cli.main, list(args))
    return res.exit_code, res.output


def test_identify_says_where_the_model_is_undefined(write_model) -> None:
    code, out = _run("identify", str(write_model(SQRT, files=DATA)))
    assert code == 2, out
    assert "cannot be differentiated" in out and "narrow the search domains" in out


def test_every_command_ends_in_a_verdict_or_a_user_error(write_model) -> None:
    path = str(write_model(SQRT, files=DATA))
    at = str(path).replace("m.cal", "s.csv")
    for args in (["solve", path, "-q"], ["solve", path, "-q", "--outliers", "1"],
                 ["predict", path, "--at", at, "-q"], ["validate", path, "--at", at, "-q"]):
        code, out = _run(*args)
        assert code in (0, 1, 2, 4), (args, out)  # a verdict (4: undecided) or a user error
        assert "internal error" not in out, (args, out)
