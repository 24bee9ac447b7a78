"""`.cal` text to AST: the Lark LALR parser, a Transformer building `ast` nodes, and syntax
errors turned into `CalError`s that say what was expected, in words."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path
from typing import Any

from lark import Token, Transformer_NonRecursive, v_args
from lark.exceptions import UnexpectedCharacters, UnexpectedInput, UnexpectedToken, VisitError

from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.frontend.files import MAX_MODEL_BYTES, NotUtf8, TooLarge, read_capped
from calib_dsl.frontend.grammar import cal_parser

MAX_EXPONENT = 400  # of a decimal literal: floats span about 1e-324 .. 1e308
MAX_DIGITS = 4000  # of a decimal literal: far past a float's 17, and cheap to read exactly


def parse(text: str, filename: str) -> tuple[ast.Stmt, ...]:
    """The statements of a `.cal` source; `filename` goes into every location."""
    try:
        tree = cal_parser().parse(text)
    except UnexpectedInput as err:
        raise _syntax_error(err, text, filename) from None
    try:
        return _Builder(filename).transform(tree)  # type: ignore[no-any-return]
    except VisitError as err:  # a CalError raised while building the AST
        if isinstance(err.orig_exc, CalError):
            raise err.orig_exc from None
        raise
    except RecursionError:
        raise CalError("the model nests too deeply", Loc(filename, 1, 1)) from None


def parse_file(path: str | Path) -> tuple[ast.Stmt, ...]:
    """Read and parse a model file; an unreadable file is a user error."""
    name = str(path)
    try:
        text = read_capped(path, MAX_MODEL_BYTES)
    except TooLarge as err:
        raise CalError(f"model file '{name}' is {err}: not a model (data belong in a table)"
                       ) from None
    except FileNotFoundError:
        raise CalError(f"model file '{name}' not found") from None
    except IsADirectoryError:
        raise CalError(f"model file '{name}' is a directory: give a .cal file") from None
    except NotUtf8 as err:
        raise CalError(f"model file '{name}' is not UTF-8 text ({err.reason}: byte "
                       f"{err.object[err.start]:#04x}; save it as UTF-8)",
                       Loc(name, err.line, err.col)) from None
    except OSError as err:
        raise CalError(f"cannot read model file '{name}': {err.strerror}") from None
    return parse(text, name)


# -- AST building ---------------------------------------------------------------------------
def _name(tok: Token, filename: str) -> ast.Ident:
    return ast.Ident(str(tok), Loc(filename, tok.line or 1, tok.column or 1))


@v_args(meta=True)
class _Builder(Transformer_NonRecursive):
    """One method per grammar rule/alias; `meta` gives the rule's first line and column."""

    def __init__(self, filename: str) -> None:
        super().__init__()
        self.file = filename

    def _loc(self, meta: Any) -> Loc:
        return Loc(self.file, getattr(meta, "line", 1), getattr(meta, "column", 1))

    def _id(self, tok: Token) -> ast.Ident:
        return _name(tok, self.file)

    # -- statements
    def start(self, meta: Any, c: list) -> tuple[ast.Stmt, ...]:
        return tuple(c)

    def const_stmt(self, meta: Any, c: list) -> ast.Const:
        return ast.Const(self._id(c[0]), c[1], self._loc(meta))

    def let_stmt(self, meta: Any, c: list) -> ast.Let:
        return ast.Let(self._id(c[0]), c[1], self._loc(meta))

    def def_stmt(self, meta: Any, c: list) -> ast.Def:
        return ast.Def(self._id(c[0]), c[1] or (), c[2], self._loc(meta))

    def param_stmt(self, meta: Any, c: list) -> ast.Decl:
        return ast.Decl("param", c[0], c[1], c[2], self._loc(meta))

    def var_stmt(self, meta: Any, c: list) -> ast.Decl:
        return ast.Decl("var", c[0], c[1], c[2], self._loc(meta))

    def decl_names(self, meta: Any, c: list) -> tuple[ast.DeclName, ...]:
        return tuple(c)

    def decl_name(self, meta: Any, c: list) -> ast.DeclName:
        return ast.DeclName(self._id(c[0]), tuple(c[1:]))

    def dim(self, meta: Any, c: list) -> ast.Range:
        return ast.Range(c[0], c[1], self._loc(meta))

    def for_stmt(self, meta: Any, c: list) -> ast.For:
        var, lo, hi, body = c
        rng = ast.Range(lo, hi, lo.loc)
        return ast.For(self._id(var), rng, body, self._loc(meta))

    def block(self, meta: Any, c: list) -> tuple[ast.Stmt, ...]:
        return tuple(c)

    def include_stmt(self, meta: Any, c: list) -> ast.Include:
        return ast.Include(str(c[0])[1:-1], self._loc(meta))

    def constraint(self, meta: Any, c: list) -> ast.Constraint:
        lhs, rel, rhs = c
        return ast.Constraint(lhs, str(rel), rhs, self._loc(meta), self._tok_loc(rel))

    bad_assign = constraint

    def _tok_loc(self, tok: Token) -> Loc:
        return Loc(self.file, tok.line or 1, tok.column or 1)

    def robot_stmt(self, meta: Any, c: list) -> ast.Robot:
        convention = self._id(c[2]) if c[2] is not None else None
        joints = c[1] or ()
        return ast.Robot(self._id(c[0]), tuple(j[0] for j in joints), tuple(c[3:]),
                         self._loc(meta), convention, tuple(j[1] for j in joints))

    def joints(self, meta: Any, c: list) -> tuple[tuple[ast.Ident, Any], ...]:
        return tuple(c)

    def joint(self, meta: Any, c: list) -> tuple[ast.Ident, Any]:
        return self._id(c[0]), c[1]

    def base_frame(self, meta: Any, c: list) -> ast.FrameDecl:
        return ast.FrameDecl("base", tuple(c), self._loc(meta))

    def joint_frame(self, meta: Any, c: list) -> ast.FrameDecl:
        return ast.FrameDecl("joint", tuple(c), self._loc(meta))

    def tool_frame(self, meta: Any, c: list) -> ast.FrameDecl:
        return ast.FrameDecl("tool", tuple(c), self._loc(meta))

    def entry(self, meta: Any, c: list) -> ast.Entry:
        return ast.Entry(self._id(c[0]), c[1])

    def table_stmt(self, meta: Any, c: list) -> ast.TableDecl:
        name, path, options = c[0], c[1], c[2] or ()
        return ast.TableDecl(self._id(name), str(path)[1:-1], self._tok_loc(path), tuple(c[3:]),
                             self._loc(meta), options)

    def table_options(self, meta: Any, c: list) -> tuple[ast.TableOption, ...]:
        return tuple(c)

    def table_option(self, meta: Any, c: list) -> ast.TableOption:
        value = c[1]
        if isinstance(value, Token):  # a STRING
            value = str(value)[1:-1]
        return ast.TableOption(self._id(c[0]), value, self._loc(meta))

    def row_range(self, meta: Any, c: list) -> ast.RowRange:
        first, _, last, step = c
        return ast.RowRange(first, last, step, self._loc(meta))

    def column_group(self, meta: Any, c: list) -> ast.ColumnGroup:
        *columns, tol, simulate = c
        return ast.ColumnGroup(tuple(n for n, _, _ in columns), tol, simulate, self._loc(meta),
                               tuple(h for _, h, _ in columns), tuple(u for _, _, u in columns))

    def column(self, meta: Any, c: list) -> tuple[ast.Ident, str | None, ast.Ident | None]:
        name, header, unit = c
        return (self._id(name), None if header is None else str(header)[1:-1],
                None if unit is None else self._id(unit))

    def units_stmt(self, meta: Any, c: list) -> ast.Units:
        return ast.Units(c[0], self._loc(meta))

    def names(self, meta: Any, c: list) -> tuple[ast.Ident, ...]:
        return tuple(self._id(t) for t in c)

    # -- expressions
    def number(self, meta: Any, c: list) -> ast.Number:
        text = str(c[0])
        mantissa, _, exponent = text.lower().partition("e")
        if len(mantissa) > MAX_DIGITS:
            raise CalError(f"number literal of {len(mantissa)} digits: at most {MAX_DIGITS} "
                           "(a float keeps 17)", self._loc(meta))
        # beyond floats, and costly exactly (a long exponent is out of range unread)
        if exponent and (len(exponent) > 6 or abs(int(exponent)) > MAX_EXPONENT):
            raise CalError(f"number {text} is out of range (exponent beyond "
                           f"+-{MAX_EXPONENT})", self._loc(meta))
        return ast.Number(Fraction(text), text, self._loc(meta))

    def name(self, meta: Any, c: list) -> ast.Name:
        return ast.Name(str(c[0]), self._loc(meta))

    def pi(self, meta: Any, c: list) -> ast.Pi:
        return ast.Pi(self._loc(meta))

    def inf(self, meta: Any, c: list) -> ast.Infinity:
        return ast.Infinity(self._loc(meta))

    def _bin(self, op: str, meta: Any, c: list) -> ast.BinOp:
        return ast.BinOp(op, c[0], c[1], self._loc(meta))

    def plusminus(self, meta: Any, c: list) -> ast.BinOp:
        return self._bin("+-", meta, c)

    def add(self, meta: Any, c: list) -> ast.BinOp:
        return self._bin("+", meta, c)

    def sub(self, meta: Any, c: list) -> ast.BinOp:
        return self._bin("-", meta, c)

    def mul(self, meta: Any, c: list) -> ast.BinOp:
        return self._bin("*", meta, c)

    def div(self, meta: Any, c: list) -> ast.BinOp:
        return self._bin("/", meta, c)

    def pow(self, meta: Any, c: list) -> ast.BinOp:
        return self._bin("^", meta, c)

    def neg(self, meta: Any, c: list) -> ast.Neg:
        return ast.Neg(c[0], self._loc(meta))

    def pos(self, meta: Any, c: list) -> ast.Expr:
        return c[0]  # type: ignore[no-any-return]

    def index(self, meta: Any, c: list) -> ast.Index:
        return ast.Index(c[0], c[1], self._loc(meta))

    def field(self, meta: Any, c: list) -> ast.Field:
        return ast.Field(c[0], str(c[1]), self._loc(meta))

    def call(self, meta: Any, c: list) -> ast.Call:
        return ast.Call(str(c[0]), c[1] or (), self._loc(meta))

    def robot_at(self, meta: Any, c: list) -> ast.RobotAt:
        return ast.RobotAt(str(c[0]), c[1] or (), c[2], self._loc(meta))

    def robot_axes(self, meta: Any, c: list) -> ast.RobotAxes:
        return ast.RobotAxes(str(c[0]), c[1] or (), self._loc(meta))

    def sum_over(self, meta: Any, c: list) -> ast.SumOver:
        var, lo, hi, body = c
        return ast.SumOver(self._id(var), ast.Range(lo, hi, lo.loc), body, self._loc(meta))

    def args(self, meta: Any, c: list) -> tuple[ast.Expr, ...]:
        return tuple(c)

    def tuple(self, meta: Any, c: list) -> ast.TupleLit:
        return ast.TupleLit(tuple(c), self._loc(meta))

    def interval(self, meta: Any, c: list) -> ast.IntervalLit:
        return ast.IntervalLit(c[0], c[1], self._loc(meta))

    def __default__(self, data: Any, children: list, meta: Any) -> Any:
        raise AssertionError(f"grammar rule {data!r} has no AST builder")  # a bug of ours


# -- syntax errors ----------------------------------------------------------------------------
_EXPR_START = {"NAME", "NUMBER", "PI", "INF", "LPAR", "LSQB", "MINUS", "PLUS", "SUM"}
_STMT_START = {"CONST", "LET", "DEF", "PARAM", "VAR", "FOR", "INCLUDE", "ROBOT", "TABLE",
               "UNITS"}
_OPERATORS = {"PLUS", "MINUS", "STAR", "SLASH", "CIRCUMFLEX", "DOT", "LSQB", "PM"}
_WORDS = {"NAME": "a name", "NUMBER": "a number", "STRING": 'a "string"', "$END": "end of file"}


def _syntax_error(err: UnexpectedInput, text: str, filename: str) -> CalError:
    if isinstance(err, UnexpectedCharacters):
        return _bad_character(err, text, filename)
    assert isinstance(err, UnexpectedToken)
    tok = err.token
    try:
        expected = set(err.interactive_parser.accepts())
    except Exception:  # noqa: BLE001 - fall back to the parser's own (coarser) set
        expected = set(err.expected)
    if expected - {"$END"}:
        expected.discard("$END")
    prev = _previous_token(text, tok)
    loc = Loc(filename, tok.line or 1, tok.column or 1)
    if tok.type == "$END":
        loc = _end_of(prev, filename) if prev is not None else Loc(filename, 1, 1)
    hint = _hint(tok, expected)
    if "SEMICOLON" in expected and prev is not None \
            and (tok.type == "$END" or (tok.line or 0) > (prev.end_line or 0)):
        return CalError(f"missing ';' after {_show_token(prev)}", _end_of(prev, filename))
    found = "end of file" if tok.type == "$END" else _show_token(tok)
    message = f"unexpected {found}: expected {_describe(expected)}"
    return CalError(message + (f" ({hint})" if hint else ""), loc)


def _bad_character(err: UnexpectedCharacters, text: str, filename: str) -> CalError:
    loc = Loc(filename, err.line, err.column)
    pos = err.pos_in_stream
    char = text[pos] if pos is not None and 0 <= pos < len(text) else "?"
    if char == '"':
        return CalError('unterminated string: a "string" must end on the same line', loc)
    return CalError(f"unexpected character {char!r}", loc)


def _hint(tok: Token, expected: set[str]) -> str:
    if tok.type == "ASSIGN" and "EQ" in expected:
        return "'=' defines a name; a constraint is stated with '=='"
    if tok.type == "EQ" and ("ASSIGN" in expected or expected == {"SEMICOLON"}):
        return "'==' states a constraint; a definition uses '='"
    if tok.type == "DOT" and "NUMBER" in expected:
        return "a number starts with a digit: write 0.5, not .5"
    if tok.type == "SUM" and "NUMBER" in expected:  # after `*`, `/`, `^` or a unary `-`
        return "a sum(...) is a term of its own: in a product, put it in parentheses, as in " \
            "2 * (sum(k in 1..n) x[k])"
    if "NAME" in expected and str(tok).isidentifier() and tok.type != "NAME":
        return f"'{tok}' is a reserved word"
    return ""


def _describe(expected: set[str]) -> str:
    words: list[str] = []
    rest = set(expected)
    if _STMT_START <= rest:
        words.append("a statement")
        rest -= _STMT_START | _EXPR_START
    if {"NAME", "NUMBER", "LPAR"} <= rest:
        words.append("an expression")
        rest -= _EXPR_START
    if {"PLUS", "STAR", "SLASH"} <= rest:
        words.append("an operator")
        rest -= _OPERATORS
    words += sorted(_show_terminal(t) for t in rest)
    if not words:
        return "nothing more"
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]


def _show_terminal(name: str) -> str:
    if name in _WORDS:
        return _WORDS[name]
    try:
        term = cal_parser().get_terminal(name)
    except KeyError:
        return name
    if term.pattern.type == "str":
        return repr(term.pattern.value)
    return name.lower()


def _show_token(tok: Token) -> str:
    if tok.type in ("NAME", "NUMBER"):
        return f"{tok.type.lower()} '{tok}'"
    return repr(str(tok))


def _previous_token(text: str, tok: Token) -> Token | None:
    """The token just before `tok` (re-lexed: the text up to `tok` lexes cleanly)."""
    end = tok.start_pos if tok.type != "$END" and tok.start_pos is not None else len(text)
    prev = None
    try:
        for t in cal_parser().lex(text[:end]):
            prev = t
    except UnexpectedInput:
        return None
    return prev


def _end_of(tok: Token, filename: str) -> Loc:
    return Loc(filename, tok.end_line or tok.line or 1, tok.end_column or tok.column or 1)

