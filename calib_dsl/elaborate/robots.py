"""Robot statements and their uses: a robot's frames for given joint values, and the
workshop coordinates of a tool point (the chain itself is built by chains.py).
"""

from __future__ import annotations

import math
from typing import Any

from calib_dsl.elaborate import chains
from calib_dsl.elaborate.checks import (
    check_entries,
    check_params,
    count,
    kind_of,
)
from calib_dsl.elaborate.context import Context
from calib_dsl.elaborate.scope import (
    RobotDef,
    Scalar,
    Scope,
    TableRef,
)
from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError


class Robots(Context):
    """`robot` declarations and their uses: `robot(q...) at p`, `robot(q...) axes`."""

    # -- robots ---------------------------------------------------------------------------
    def _robot(self, s: ast.Robot, scope: Scope, top: bool) -> None:
        self._top_only("a robot definition", s.loc, top)
        check_params(s.params, "joint variable")
        convention = s.convention.id if s.convention is not None else "mdh"
        if convention not in JOINT_ENTRIES:
            raise CalError(f"unknown convention '{convention}' (mdh: modified DH, the default; "
                           "dh: standard DH)", s.convention.loc if s.convention else s.loc)
        parts: dict[str, list[ast.FrameDecl]] = {"base": [], "joint": [], "tool": []}
        for frame in s.frames:
            if frame.kind == "base" and (parts["joint"] or parts["tool"]):
                raise CalError("the base frames come first, before the joints", frame.loc)
            if frame.kind == "joint" and parts["tool"]:
                raise CalError("the tool frames come last, after the joints", frame.loc)
            allowed = JOINT_ENTRIES[convention] if frame.kind == "joint" else \
                (SIX_DOF if frame.kind == "tool" or _six_dof(frame) else MDH_BASE)
            check_entries(frame, allowed)
            parts[frame.kind].append(frame)
        if not parts["joint"]:
            raise CalError(f"robot '{s.name.id}' has no joint", s.loc)
        limits = tuple(None if e is None else self._joint_limit(e, scope) for e in s.limits)
        scope.define(s.name, RobotDef(s.name.id, s.params, tuple(parts["base"]),
                                      tuple(parts["joint"]), tuple(parts["tool"]), convention,
                                      scope, limits))

    def _joint_limit(self, e: ast.Expr, scope: Scope) -> tuple[float, float]:
        """`q in [lo, hi]`: finite, and a range (configurations are drawn within it)."""
        lo, hi, _ = self.domain(e, scope)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            shown = ", ".join(f"{x:g}".replace("inf", "oo") for x in (lo, hi))
            raise CalError(f"a joint limit is a finite range [lo, hi] with lo < hi, not "
                           f"[{shown}]", e.loc)
        return lo, hi

    def _robot_at(self, e: ast.RobotAt, scope: Scope) -> tuple[int, ...]:
        args = self._joint_values(e, scope, "'at' gives the workshop coordinates of a tool "
                                            "point on a robot")
        robot = self.lookup(e.robot, e.loc, scope)
        assert isinstance(robot, RobotDef)
        point = self.value(e.point, scope)
        if not isinstance(point, tuple) or len(point) != 3:
            raise CalError(f"a tool point is a 3-vector (x, y, z), not {kind_of(point)}",
                           e.point.loc)
        where = e.point.loc
        xyz = (self.node(point[0], where), self.node(point[1], where), self.node(point[2], where))
        for n in xyz:
            self._note_unit(n, "length")
        key = (robot.name, args, xyz)
        found = self._robot_calls.get(key)
        if found is None:
            frames = self._frames(robot, args)
            found = tuple(chains.forward_point(self.dag, frames, xyz, self.formulation))
            self._robot_calls[key] = found
        return found

    def _robot_axes(self, e: ast.RobotAxes, scope: Scope) -> tuple[int, ...]:
        args = self._joint_values(e, scope, "'axes' gives the orientation of a robot's last "
                                            "frame")
        robot = self.lookup(e.robot, e.loc, scope)
        assert isinstance(robot, RobotDef)
        key = (robot.name, args, "axes")
        found = self._robot_calls.get(key)
        if found is None:
            found = chains.forward_axes(self.dag, self._frames(robot, args), self.formulation)
            self._robot_calls[key] = found
            self.note_rotation(found)
        return found

    def _note_unit(self, node: int, dimension: str) -> None:
        """The unknowns a frame entry (or a tool point's coordinate) adds or subtracts take
        the model's unit of its dimension: `theta2 + q2` makes theta2 an angle. A factor
        (`s * 100`) says nothing of its own dimension, so only sums are followed."""
        nodes, stack = self.dag.nodes, [node]
        while stack:
            n = nodes[stack.pop()]
            if n.op in ("add", "sub", "neg"):
                stack.extend(n.args)
            elif n.op == "var" and n.data in self.dag.variables:
                self.dag.variables[n.data].unit = self.units[dimension]

    def _joint_values(self, e: ast.RobotAt | ast.RobotAxes, scope: Scope,
                      what: str) -> tuple[Scalar, ...]:
        robot = self.lookup(e.robot, e.loc, scope)
        if not isinstance(robot, RobotDef):
            raise CalError(f"'{e.robot}' is not a robot: {what}", e.loc)
        if len(e.args) != len(robot.params):
            raise CalError(f"robot '{e.robot}' takes {count(len(robot.params), 'joint value')}"
                           f", got {len(e.args)}", e.loc)
        for a, limit in zip(e.args, robot.limits or (None,) * len(e.args), strict=True):
            column = self._cell_column(a, scope)
            if limit is not None and column is not None:
                old = self.joint_limits.get(column, limit)  # (two joints: both limits hold)
                self.joint_limits[column] = (max(old[0], limit[0]), min(old[1], limit[1]))
        return tuple(self.scalar(self.value(a, scope), a.loc, "a joint value") for a in e.args)

    def tool_points(self, robot: str) -> list[tuple[int, int, int]]:
        """The tool points `robot(...) at p` has been asked for, as DAG nodes (x, y, z), each
        once: what `calibc export` writes as the robot's tool frame."""
        found = [key[2] for key in self._robot_calls if key[0] == robot and
                 isinstance(key[2], tuple)]
        return list(dict.fromkeys(found))

    def _cell_column(self, a: ast.Expr, scope: Scope) -> tuple[str, str] | None:
        """(table, column) when the joint value is a table's cell `m.q1[k]`."""
        if isinstance(a, ast.Index) and isinstance(a.base, ast.Field) and \
                isinstance(a.base.base, ast.Name):
            table = self.lookup(a.base.base.id, a.base.base.loc, scope)
            if isinstance(table, TableRef):
                return table.name, a.base.name
        return None

    def frames_of(self, robot: RobotDef, args: tuple[Scalar, ...]) -> list[Any]:
        """The robot's frames (base, joints, tool: chains.Frame or Transform of DAG nodes)
        for these joint values: what `calibc export` writes as a DH table."""
        return self._frames(robot, args)

    def _frames(self, robot: RobotDef, args: tuple[Scalar, ...]) -> list[Any]:
        """The frames of a robot for these joint values (the same for every tool point)."""
        key = (robot.name, args)
        frames = self._robot_frames.get(key)
        if frames is None:
            inner = Scope(robot.scope)
            for p, a in zip(robot.params, args, strict=True):
                inner.names[p.id] = (a, p.loc)
            # a robot with no base line has the identity base (the MDH frame of zeros)
            bases = robot.base or (None,)
            frames = [self._frame(b, inner, "mdh") for b in bases]
            frames += [self._frame(j, inner, robot.convention) for j in robot.joints]
            frames += [self._frame(t, inner, "mdh") for t in robot.tool]
            self._robot_frames[key] = frames
        return frames

    def _frame(self, decl: ast.FrameDecl | None, scope: Scope, convention: str) -> Any:
        values = {}
        for entry in decl.entries if decl is not None else ():
            v = self.scalar(self.value(entry.value, scope), entry.value.loc, "a frame entry")
            values[entry.name.id] = self.node(v, entry.value.loc)
            self._note_unit(values[entry.name.id], DIMENSION[entry.name.id])
        zero = self.dag.const(0.0)

        def get(name: str) -> int:
            return values.get(name, zero)

        if decl is not None and (decl.kind == "tool" or _six_dof(decl)):
            return chains.xyz_euler(*(get(n) for n in SIX_DOF))
        if decl is not None and decl.kind == "joint" and convention == "dh":
            return chains.standard_dh(get("theta"), get("d"), get("a"), get("alpha"))
        return chains.Frame(alpha=get("alpha"), d=get("d"), theta=get("theta"), r=get("r"))


MDH_BASE = ("theta", "r")  # a modified-DH base frame (alpha = d = 0)
SIX_DOF = ("x", "y", "z", "rx", "ry", "rz")  # translation, then X-Y-Z Euler angles
# the dimension of each frame entry: what its unknowns' unit is
DIMENSION = {**dict.fromkeys(("alpha", "theta", "rx", "ry", "rz"), "angle"),
             **dict.fromkeys(("d", "r", "a", "x", "y", "z"), "length")}
JOINT_ENTRIES = {"mdh": ("alpha", "d", "theta", "r"), "dh": ("theta", "d", "a", "alpha")}


def _six_dof(frame: ast.FrameDecl) -> bool:
    """A base frame given by position and X-Y-Z Euler angles rather than (theta, r)."""
    return any(e.name.id in SIX_DOF for e in frame.entries)
