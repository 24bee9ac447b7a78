"""The command line's progress: one line on standard error, redrawn in place as the work
goes (`calibc: solving  LP round 3, widths 12.3 % of the domains, 2.4 s`), on a terminal only.

It is click's progress bar, drawn without its bar (the work has no known length): click is
the command line's library already, so this costs no dependency, and it handles what a hand-
written line gets wrong (clearing a longer line, the cursor, terminal width). Where standard
error is not a terminal (a pipe, a log file, a test) or with --quiet, nothing is drawn and the
work gets no callback at all.
"""

from __future__ import annotations

import itertools
import math
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO

import click

from calib_dsl.progress import Progress


def describe(label: str, width: float | None, seconds: float) -> str:
    """`LP round 3, widths 12.3 % of the domains, 2.4 s` (`width`: the mean fraction of
    the unknowns' search domains, calib_dsl/progress.py)."""
    parts = [label]
    if width is not None:
        shown = "+oo" if math.isinf(width) else f"{100 * width:.3g} %"
        parts.append(f"widths {shown} of the domains")
    parts.append(f"{seconds:.1f} s")
    return ", ".join(parts)


@contextmanager
def progress_line(title: str, quiet: bool = False,
                  file: TextIO | None = None) -> Iterator[Progress | None]:
    """A `Progress` that redraws one line of `file` (standard error by default) under
    `title`, or None when quiet or when `file` is not a terminal. The last state stays on
    screen, followed by a new line, when the block ends (an error message starts afresh)."""
    out = file if file is not None else sys.stderr
    if quiet or not out.isatty():
        yield None
        return
    bar = click.progressbar(itertools.repeat(""), label=f"calibc: {title}", file=out,
                            bar_template="%(label)s  %(info)s", show_eta=False,
                            show_percent=False, item_show_func=lambda text: text)
    with bar:
        yield lambda label, width, seconds: bar.update(1, describe(label, width, seconds))
