"""Where the `.cal` grammar lives, and the one LALR parser built from it.

In a source checkout the grammar is `<repo>/grammars/cal.lark`; a wheel ships the same folder
inside the package as `calib_dsl/grammars/` (pyproject's force-include). Both are looked for.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

from lark import Lark

GRAMMAR_NAME = "cal.lark"
_HERE = Path(__file__).resolve().parent
CANDIDATES = (
    _HERE.parent / "grammars" / GRAMMAR_NAME,  # installed: calib_dsl/grammars/cal.lark
    _HERE.parent.parent / "grammars" / GRAMMAR_NAME,  # source checkout: <repo>/grammars/cal.lark
)


def grammar_path() -> Path:
    """The grammar file, installed copy first; FileNotFoundError names the places looked at."""
    for path in CANDIDATES:
        if path.is_file():
            return path
    looked = ", ".join(str(p) for p in CANDIDATES)
    raise FileNotFoundError(f"the .cal grammar {GRAMMAR_NAME} is missing (looked at {looked})")


def grammar_text() -> str:
    return grammar_path().read_text(encoding="utf-8")


@cache
def cal_parser() -> Lark:
    """The LALR(1) parser (built once): the tree keeps line/column positions."""
    # cache=True: Lark keeps the built LALR tables in the temp directory (keyed by the
    # grammar's hash), so no command after the first builds them again
    return Lark(grammar_text(), parser="lalr", lexer="basic", propagate_positions=True,
                maybe_placeholders=True, cache=True)
