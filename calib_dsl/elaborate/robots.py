"""Robot statements and their uses: a robot's frames for given joint values, and the
workshop coordinates of a tool point (the chain itself is built by chains.py).
"""

from __future__ import annotations

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
)
from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError


class Robots(Context):
    """`robot` declarations and `robot(q...) at p` uses."""

    # -- robots ---------------------------------------------------------------------------
    def _robot(self, s: ast.Robot, scope: Scope, top: bool) -> None:
        self._top_only("a robot definition", s.loc, top)
        check_params(s.params, "joint variable")
        base = None
        joints = []
        if s.convention is not None and s.convention.id != "mdh":
            raise CalError(f"robot convention '{s.convention.id}' is not supported yet (mdh)",
                           s.convention.loc)
        for i, frame in enumerate(s.frames):
            if frame.kind == "tool":
                raise CalError("a tool frame is not supported yet: give the tool point in "
                               "the last joint's frame", frame.loc)
            allowed = ("theta", "r") if frame.kind == "base" else ("alpha", "d", "theta", "r")
            check_entries(frame, allowed)
            if frame.kind == "base":
                if i != 0:
                    raise CalError("the base frame must come first, and only once", frame.loc)
                base = frame
            else:
                joints.append(frame)
        if not joints:
            raise CalError(f"robot '{s.name.id}' has no joint", s.loc)
        scope.define(s.name, RobotDef(s.name.id, s.params, base, tuple(joints), scope))

    def _robot_at(self, e: ast.RobotAt, scope: Scope) -> tuple[int, ...]:
        robot = self.lookup(e.robot, e.loc, scope)
        if not isinstance(robot, RobotDef):
            raise CalError(f"'{e.robot}' is not a robot: 'at' gives the workshop coordinates "
                           "of a tool point on a robot", e.loc)
        if len(e.args) != len(robot.params):
            raise CalError(f"robot '{e.robot}' takes {count(len(robot.params), 'joint value')}"
                           f", got {len(e.args)}", e.loc)
        args = tuple(self.scalar(self.value(a, scope), a.loc, "a joint value") for a in e.args)
        point = self.value(e.point, scope)
        if not isinstance(point, tuple) or len(point) != 3:
            raise CalError(f"a tool point is a 3-vector (x, y, z), not {kind_of(point)}",
                           e.point.loc)
        where = e.point.loc
        xyz = (self.node(point[0], where), self.node(point[1], where), self.node(point[2], where))
        key = (robot.name, args, xyz)
        found = self._robot_calls.get(key)
        if found is None:
            frames = self._frames(robot, args)
            found = tuple(chains.forward_point(self.dag, frames, xyz, self.formulation))
            self._robot_calls[key] = found
        return found

    def _frames(self, robot: RobotDef, args: tuple[Scalar, ...]) -> list[Any]:
        """The frames of a robot for these joint values (the same for every tool point)."""
        key = (robot.name, args)
        frames = self._robot_frames.get(key)
        if frames is None:
            inner = Scope(robot.scope)
            for p, a in zip(robot.params, args, strict=True):
                inner.names[p.id] = (a, p.loc)
            frames = [self._frame(robot.base, inner)]
            frames += [self._frame(j, inner) for j in robot.joints]
            self._robot_frames[key] = frames
        return frames

    def _frame(self, decl: ast.FrameDecl | None, scope: Scope) -> Any:
        values = {}
        for entry in decl.entries if decl is not None else ():
            v = self.scalar(self.value(entry.value, scope), entry.value.loc, "a frame entry")
            values[entry.name.id] = self.node(v, entry.value.loc)
        zero = self.dag.const(0.0)
        return chains.Frame(alpha=values.get("alpha", zero), d=values.get("d", zero),
                           theta=values.get("theta", zero), r=values.get("r", zero))
