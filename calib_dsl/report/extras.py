"""Optional sections of a solve's report, as computed (calib_dsl/sections.py):
identifiability, a least-squares estimate, certified inner bounds, and the result shaved
towards them."""

from __future__ import annotations

import math
from typing import Any

from calib_dsl.accuracy.statement import Accuracy
from calib_dsl.analysis.leverage import Leverage
from calib_dsl.inner.bounds import Inner
from calib_dsl.inner.shave import Shaved
from calib_dsl.outliers.rows import Row


class Extras:
    """Optional sections of the report: identifiability, a least-squares estimate, and
    certified inner bounds."""

    def __init__(self) -> None:
        self.info: Any = None  # identify.Identifiability
        self.combinations: list[tuple[str, float, float]] = []
        self.estimate: Any = None  # lsq.Estimate
        self.inner: Inner | None = None
        self.shaved: Shaved | None = None
        self.seconds = 0.0
        self.skipped: list[str] = []  # a line each: a section not computed, and why
        # parameters one data row carries (a warning names them), with those rows
        self.heavy: list[tuple[Leverage, Row]] = []
        self.accuracy: Accuracy | None = None
        self.length_unit: str | None = None  # the model's, where it states one
        self.accuracy_seconds = 0.0

    def inner_of(self, name: str) -> tuple[float, float] | None:
        """The certified inner interval of an unknown (None: none certified, or not asked)."""
        if self.inner is None or name not in self.inner.names:
            return None
        k = self.inner.names.index(name)
        a, b = float(self.inner.lo[k]), float(self.inner.hi[k])
        return None if math.isnan(a) else (a, b)

    def certified_of(self, name: str) -> float | None:
        """An unknown's value at the certified centre (inner/bounds.py `Inner.centre`)."""
        if self.inner is None or name not in self.inner.names:
            return None
        centre = self.inner.centre  # (found once, for every unknown)
        return None if centre is None else float(centre.point[self.inner.names.index(name)])

    def not_identifiable(self) -> set[str]:
        if self.info is None:
            return set()
        return {n for members, _ in self.info.groups for n in members}

    def lsq_value(self, name: str) -> float | None:
        if self.estimate is None or name not in self.estimate.names:
            return None
        return float(self.estimate.values[self.estimate.names.index(name)])
