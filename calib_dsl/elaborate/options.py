"""What the command line adds to a model, from its text: `--data [TABLE=]CSV`, `--rows`,
`--exclude`, `-D NAME=VALUE` become one `Inputs`. Here, below the command line, so that
`calibc batch` reads a job's entries with the very same code as `calibc solve` its options."""

from __future__ import annotations

from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.elaborate.rows import Selection, parse_numbers, parse_ranges
from calib_dsl.frontend.diagnostics import CalError


def inputs_from_options(data: tuple[str, ...], rows: tuple[str, ...],
                        exclude: tuple[str, ...], defines: tuple[str, ...]) -> Inputs:
    """The options' text as `Inputs`; a malformed value is a CalError naming the option."""
    files = dict(named(d, "--data") for d in data)
    selections: dict[str, Selection] = {}
    for option, values, parse in (("--rows", rows, parse_ranges),
                                  ("--exclude", exclude, parse_numbers)):
        for item in values:
            table, text = named(item, option)
            try:
                parsed = parse(text)
            except ValueError as err:
                raise CalError(f"{option} {item}: {err}") from None
            old = selections.get(table, Selection())
            selections[table] = (Selection(old.ranges + parsed, old.excluded)  # type: ignore[operator]
                                 if option == "--rows" else
                                 Selection(old.ranges, old.excluded + parsed))  # type: ignore[operator]
    return Inputs(files, selections, consts(defines))


def consts(defines: tuple[str, ...]) -> dict[str, str]:
    """`-D NAME=VALUE` items as {NAME: VALUE}."""
    out = {}
    for d in defines:
        name, eq, value = d.partition("=")
        if not eq or not name.strip().isidentifier():
            raise CalError(f"-D {d}: write NAME=VALUE, e.g. -D e=1.2")
        out[name.strip()] = value
    return out


def named(item: str, option: str) -> tuple[str, str]:
    """`TABLE=VALUE` -> (TABLE, VALUE); a bare VALUE is for the first table ("")."""
    name, eq, value = item.partition("=")
    if eq and name.isidentifier():
        if not value:
            raise CalError(f"{option} {item}: nothing after '='")
        return name, value
    return "", item
