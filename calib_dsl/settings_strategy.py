"""The tuning constants of the split of a loose result (strategy/split.py, `split_loose`): a
group of `Settings` (settings.py), kept apart so that settings.py stays a size a reader can
hold. Every field says why it has its value."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class LooseSettings:
    """When shaving leaves an unknown loose, the unknowns the solve left (nearly) their whole
    domain are cut in halves and the halves contracted (strategy/split.py)."""

    # An unknown whose result is still wider than `above` times its certified inner interval
    # after shaving is loose: the enclosure is farther from the hull the data hold than the
    # product promises for every parameter (outer/inner at most 1.2; 1 is the best
    # possible). A result within the promise is left as shaving made it: a cut costs about two
    # shaving ends, often the solve's own time again.
    above: float = 1.2
    # An unknown whose result spans more than `whole` of its search domain kept (nearly) its
    # whole domain: the data barely see it, and every relaxation's remainder grows with its
    # width, which neither the rounds nor shaving's slices of another unknown reduce.
    whole: float = 0.5
    # Of those, at most `tried` are cut (one after the other, each from the box the one
    # before left), the one whose halves' relaxations lose most remainder first.
    tried: int = 2
    # A cut after the first starts only if, at the mean cost of those before, it ends
    # within `share` of the solve's time (the first always starts: the result is beyond the
    # promise, which the user is told otherwise).
    share: float = 0.5


@dataclass(frozen=True)
class BlockSettings:
    """Rows per block of the passes over every row of a large program whose whole-size
    temporaries would set the peak memory (a 12,000-row campaign's row models hold some
    200 bytes per unknown and row). Results do not depend on them: each block's arithmetic
    is the whole array's, row by row."""

    # The row screen's coefficient sizes (analysis/row_screen.py): each block's temporary
    # holds the models' coefficients of this many rows (some 4 KB a row).
    size_rows: int = 4096
    # The LP row generation's check of a point (lp/highs.py, RowCheck): each block's
    # products and excesses hold this many rows (a few hundred bytes a row with its indices).
    check_rows: int = 16384
