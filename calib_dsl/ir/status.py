"""The words a solve answers with, as str-valued enums: each member is its own text (they
compare equal to it and are written as it in the JSON), so a typo is an AttributeError
instead of a comparison that is silently never true."""

from __future__ import annotations

from enum import StrEnum


class Status(StrEnum):
    """A solve's result: a box that holds every solution, or the proof there is none."""

    CONTRACTED = "contracted"
    INFEASIBLE = "infeasible"


class Stop(StrEnum):
    """Why the last step of a solve stopped."""

    NONE = ""  # (no propagation ran: the step says nothing)
    FIXED_POINT = "fixed point"
    TOLERANCE = "tolerance"  # a sweep contracted every unknown by less than the tolerance
    MAX_SWEEPS = "max sweeps"
    EMPTY = "empty"  # a domain emptied: the proof of infeasibility
    SETS_OF_ROWS = "sets of rows"  # --outliers: the tight solves of sets of rows decided
    OUTLIER_LPS = "outlier LPs"  # --outliers: rounds of LPs over the relaxations with outliers


class Consistency(StrEnum):
    """The verdict on the data: proven consistent, proven inconsistent, or neither."""

    CONSISTENT = "consistent"
    INCONSISTENT = "inconsistent"
    UNDECIDED = "undecided"


class SlotKind(StrEnum):
    """What a slot of the program holds."""

    PARAM = "param"  # a parameter to calibrate
    VAR = "var"  # an unknown of the model that is not a parameter
    DATA = "data"  # a measured value
    CONST = "const"  # a constant
    TEMP = "temp"  # an intermediate result of a primitive


# the kinds of the declared unknowns (what a solve bounds and reports), the others being
# measured values, constants and intermediate results
UNKNOWNS = (SlotKind.PARAM, SlotKind.VAR)
