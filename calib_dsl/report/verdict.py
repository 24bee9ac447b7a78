"""The verdict at the top of a solve's report: consistent, inconsistent, or, loudly, undecided
(strategy/verdict.py)."""

from __future__ import annotations

from calib_dsl.strategy.verdict import UNDECIDED, Verdict

# What the table's marks must not be read as where nothing is decided
UNDECIDED_TABLE = ("# undecided: the result encloses every solution, but none is proven to "
                   "exist; `true in box` says only that the box holds the stated value")


def render_verdict(v: Verdict) -> list[str]:
    """The report's first lines (then a blank one)."""
    lines = [v.headline()]
    if v.budget is not None:
        lines.append(f"  {'tried' if v.verdict == UNDECIDED else 'decided'} in {v.seconds:.2f} s "
                     f"beyond the solve (its budget {v.budget:.2f} s: the solve's time times "
                     "settings.verdict_share; a step started within it runs to its end)")
    lines += [f"  - {t}" for t in v.tried]
    if v.next_step is not None:
        lines.append(f"  next: {v.next_step}")
    return [*lines, ""]


def stderr_line(v: Verdict) -> str | None:
    """The line standard error gets (undecided only: the other two verdicts are the exit
    code's)."""
    if v.verdict != UNDECIDED:
        return None
    more = f"; next: {v.next_step}" if v.next_step else ""
    return f"calibc: UNDECIDED: {v.reason}{more}"
