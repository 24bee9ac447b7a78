"""A model's robots as tables of frames with guaranteed values (`calibc export --format
dh-table|urdf|json`).

The model is elaborated again (in simulation mode: no data file is read), each robot's
frames are built with its joint variables as unknowns of their own, and each frame entry
(alpha, d, theta, r; or x, y, z, rx, ry, rz; or a standard-DH joint's theta, d, a, alpha) is
evaluated with the joint variables at 0: in interval arithmetic over the result box (every
value consistent with the data lies in it, rounded outward) and at the box's midpoint. The
joint variable q must enter one entry as +-q plus an offset (theta for a revolute joint, r or
d for a prismatic one): the entry at q = 0 is then the offset a controller adds q to.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from calib_dsl.arith.projections import forward
from calib_dsl.elaborate import chains
from calib_dsl.elaborate.elaborator import Elaborator, Inputs
from calib_dsl.elaborate.scope import RobotDef
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.dag import Dag

ANGLES = ("alpha", "theta", "rx", "ry", "rz")  # the other entries are lengths
SIX_DOF = {"Tx": "x", "Ty": "y", "Tz": "z", "Rx": "rx", "Ry": "ry", "Rz": "rz"}
STANDARD_DH = ("theta", "d", "a", "alpha")  # Rz(theta) Tz(d) Tx(a) Rx(alpha)
MOVES = {"mdh": {"theta": "revolute", "r": "prismatic"},
         "dh": {"theta": "revolute", "d": "prismatic"}}


@dataclass(frozen=True)
class Entry:
    name: str  # as the robot statement writes it: alpha, d, theta, r, x, ..., a
    lo: float  # every value consistent with the data, at q = 0, lies in [lo, hi]
    hi: float
    mid: float  # its value at the point exported (the box's midpoint by default; q = 0)
    reads: tuple[str, ...] = ()  # the declared unknowns it depends on

    @property
    def dimension(self) -> str:
        return "angle" if self.name in ANGLES else "length"


@dataclass(frozen=True)
class FrameRow:
    part: str  # "base" | "joint" | "tool"
    number: int  # from 1 within its part
    convention: str  # "mdh": Rx Tx Rz Tz; "dh": Rz Tz Tx Rx; "xyz": T(x, y, z) Rx Ry Rz
    entries: tuple[Entry, ...]
    motion: str = "fixed"  # or "revolute", "prismatic"
    axis: float = 1.0  # q's coefficient in its entry: +1 or -1
    joint: str | None = None  # the joint variable's name (the robot statement's)

    def entry(self, name: str) -> Entry:
        return next(e for e in self.entries if e.name == name)


@dataclass(frozen=True)
class RobotTable:
    name: str
    frames: tuple[FrameRow, ...]
    # the tool points `robot(...) at p` measures, in the last frame (x, y, z entries; the
    # model's length unit): the tool frames a controller adds after the flange
    tools: tuple[tuple[Entry, Entry, Entry], ...] = ()
    # the joint limits the robot statement declares (`q1 in [lo, hi]`), by joint variable
    limits: dict[str, tuple[float, float]] = field(default_factory=dict)


def robot_tables(path: str | Path, box: dict[str, tuple[float, float]],
                 point: dict[str, float] | None = None
                 ) -> tuple[list[RobotTable], dict[str, str]]:
    """The robots of the model at `path`, their entries over `box` (name: (lo, hi) of every
    declared unknown) and at `point` (a value of each, by default the box's midpoint); and
    the model's units ({"length": "m", "angle": "rad"})."""
    run = Elaborator("matrix", Inputs(), simulate_rows=1)
    run.file(str(path))
    robots = [e for e, _ in run.globals.names.values() if isinstance(e, RobotDef)]
    if point is None:
        point = {n: 0.5 * lo + 0.5 * hi for n, (lo, hi) in box.items()}
    return [_table(run, r, box, point) for r in robots], dict(run.units)


def _table(run: Elaborator, robot: RobotDef, box: dict[str, tuple[float, float]],
           point: dict[str, float]) -> RobotTable:
    joints = tuple(f"{robot.name}.{p.id}" for p in robot.params)
    qs = tuple(run.dag.var(q, -np.inf, np.inf, kind="var") for q in joints)
    frames = run.frames_of(robot, qs)
    parts = (["base"] * max(len(robot.base), 1) + ["joint"] * len(robot.joints)
             + ["tool"] * len(robot.tool))
    rows, seen = [], {"base": 0, "joint": 0, "tool": 0}
    values = _Values(run.dag, box, set(joints), point)
    for part, frame in zip(parts, frames, strict=True):
        seen[part] += 1
        if part == "base" and not robot.base:
            continue  # no base line: the identity, nothing to write
        convention, named = _named(frame, part, robot.convention)
        rows.append(_row(robot.name, part, seen[part], convention, named, values))
    tools = tuple(tuple(Entry(axis, *values.over_box(n), values.at_point(n, 0.0),
                              tuple(values.names_in(n)))
                        for axis, n in zip("xyz", xyz, strict=True))
                  for xyz in run.tool_points(robot.name))
    limits = {p.id: lim for p, lim in zip(robot.params, robot.limits, strict=False)
              if lim is not None}
    return RobotTable(robot.name, tuple(rows), tools, limits)  # type: ignore[arg-type]


def _named(frame: Any, part: str, convention: str) -> tuple[str, list[tuple[str, int]]]:
    if isinstance(frame, chains.Frame):
        return "mdh", [("alpha", frame.alpha), ("d", frame.d), ("theta", frame.theta),
                       ("r", frame.r)]
    if part == "joint" and convention == "dh":
        return "dh", [(n, node) for n, (_, node) in zip(STANDARD_DH, frame.steps, strict=True)]
    return "xyz", [(SIX_DOF[kind], node) for kind, node in frame.steps]


def _row(robot: str, part: str, number: int, convention: str,
         named: list[tuple[str, int]], values: _Values) -> FrameRow:
    entries, motion, axis, joint = [], "fixed", 1.0, None
    for name, node in named:
        lo, hi = values.over_box(node)
        names = values.names_in(node)
        moving = [n for n in names if n in values.joints]
        entries.append(Entry(name, lo, hi, values.at_point(node, 0.0),
                             tuple(n for n in names if n not in values.joints)))
        if not moving:
            continue
        kind = MOVES.get(convention, {}).get(name)
        slope = values.at_point(node, 1.0) - values.at_point(node, 0.0)
        where = f"robot '{robot}', {part} {number}, entry {name}"
        if part != "joint" or kind is None or joint is not None or len(moving) > 1:
            raise CalError(f"{where}: a joint variable here cannot be written as a DH table "
                           f"(a joint moves theta, or {'d' if convention == 'dh' else 'r'})")
        if abs(abs(slope) - 1.0) > 1e-9:
            raise CalError(f"{where}: the joint variable enters as {slope:.6g} q, not as q "
                           "or -q plus an offset")
        motion, axis, joint = kind, float(np.sign(slope)), moving[0].split(".", 1)[1]
    return FrameRow(part, number, convention, tuple(entries), motion, axis, joint)


class _Values:
    """Frame entries as intervals: over the box, or at a point of it with every joint
    variable at a given value."""

    def __init__(self, dag: Dag, box: dict[str, tuple[float, float]], joints: set[str],
                 point: dict[str, float]):
        self.dag, self.box, self.joints = dag, box, joints
        self.point = {n: (v, v) for n, v in point.items()}

    def over_box(self, node: int) -> tuple[float, float]:
        return self._eval(node, {q: (0.0, 0.0) for q in self.joints}, {})

    def at_point(self, node: int, q: float) -> float:
        lo, hi = self._eval(node, {**self.point, **{j: (q, q) for j in self.joints}}, {})
        return 0.5 * lo + 0.5 * hi

    def names_in(self, node: int) -> list[str]:
        """The unknowns (declared, or joint variables) the node depends on."""
        found: set[str] = set()
        stack, seen = [node], set()
        while stack:
            n = stack.pop()
            if n in seen:
                continue
            seen.add(n)
            nd = self.dag.nodes[n]
            if nd.op == "var":
                found.add(nd.data)
            stack.extend(nd.args)
        return sorted(found)

    def _eval(self, node: int, fixed: dict[str, tuple[float, float]],
              memo: dict[int, tuple[float, float]]) -> tuple[float, float]:
        if node in memo:
            return memo[node]
        nd = self.dag.nodes[node]
        if nd.op == "const":
            out = (float(nd.data[0]), float(nd.data[1]))
        elif nd.op == "var":
            out = fixed.get(nd.data) or self.box.get(nd.data) or self._missing(nd.data)
        else:
            args = [self._eval(a, fixed, memo) for a in nd.args]
            param = None if nd.data is None else np.array([float(nd.data)])
            lo, hi = forward(nd.op, [(np.array([a]), np.array([b])) for a, b in args], param)
            out = (float(lo[0]), float(hi[0]))
        memo[node] = out
        return out

    def _missing(self, name: str) -> tuple[float, float]:
        raise CalError(f"the result has no parameter '{name}', which a robot frame of the "
                       "model reads: was the result solved from this model?")
