"""A robot's calibrated kinematics as URDF (`calibc export --format urdf`): one joint per axis,
named as the robot statement names its variable (q1, ...), each joint's origin (xyz, rpy)
computed from the frame entries at the exported point (report/export_point.py).

URDF has no uncertainty: the point's values are written, and each joint's comment gives its
entries with their guaranteed half-widths (the model's units). URDF is in metres and radians,
whatever the model's units: lengths and angles are converted.

A modified-DH joint is F(q) = Rx(alpha) Tx(d) Rz(theta + q) Tz(r) = F(0) Rz(q) (Rz and Tz
commute; a prismatic joint F(0) Tz(q)): the joint's origin is F(0), its axis z. A standard-DH
joint is Rz(q) F(0): the motion comes first, so the joint's origin is what the previous
frame left, and F(0) moves on to the next origin. The robot starts at `base_link`, its own
base: the base frames (where it stands in the measurement set-up) are the cell's transform,
written apart (`--format cell`). What the last joint and the tool frames leave is a fixed joint
to `flange` (the frame where the model's tool points are given), and each tool point the
model measures a fixed frame `tool0` after it.
"""

from __future__ import annotations

import math
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np

from calib_dsl.elaborate.units import factor
from calib_dsl.report.decimals import clean
from calib_dsl.report.export import plus_minus
from calib_dsl.studies.robot_frames import FrameRow, RobotTable


def scales(units: dict[str, str]) -> dict[str, float]:
    """The model's units to metres and radians."""
    return {"length": _factor(units["length"], "m"), "angle": _factor(units["angle"], "rad")}


def urdf(model: str, tables: list[RobotTable], units: dict[str, str]) -> str:
    """The robots as URDF: each starts at `base_link`, the robot's own base; where it
    stands in the measurement set-up is the cell's transform (`cell`), kept out of it."""
    scale = scales(units)
    out = ['<?xml version="1.0"?>',
           f"<!-- calibc export of the guaranteed result of {_comment(model)}: frame entries "
           f"at the exported point (calibc export's option point), in m and rad (URDF's units; the "
           f"model's: {units['length']} and {units['angle']}); each joint's comment gives its "
           f"entries +- their guaranteed half-widths in the model's units. Where the robot "
           f"stands in the measurement set-up: calibc export's format cell. -->"]
    for t in tables:
        out += _robot(t, scale)
    return "\n".join(out) + "\n"


def cell(model: str, tables: list[RobotTable], units: dict[str, str]) -> str:
    """The measurement set-up: per robot, a fixed joint from `world` (the measuring
    instrument's frame, a tracker's) to the robot's `base_link` (the base frames)."""
    scale = scales(units)
    out = ['<?xml version="1.0"?>',
           f"<!-- calibc export of the cell of {_comment(model)}: where each robot's base_link "
           "stands in the measuring instrument's frame (world), in m and rad -->",
           '<robot name="cell">', '  <link name="world"/>']
    for t in tables:
        base = [f for f in t.frames if f.part == "base"]
        acc = np.eye(4)
        for f in base:
            acc = acc @ frame_matrix(f, scale)
        out += _joint(f"{t.name}_base", "fixed", "world", f"{t.name}_base_link", acc,
                      base[0] if base else None, None)
    return "\n".join(out + ["</robot>"]) + "\n"


def _robot(t: RobotTable, scale: dict[str, float]) -> list[str]:
    out = [f"<robot name={quoteattr(t.name)}>", '  <link name="base_link"/>']
    parent, acc = "base_link", np.eye(4)
    for f in (f for f in t.frames if f.part == "joint"):
        name = f.joint or f"joint{f.number}"
        child = f"link{f.number}"
        fixed = frame_matrix(f, scale)
        origin, acc = (acc @ fixed, np.eye(4)) if f.convention == "mdh" else (acc, fixed)
        limit = t.limits.get(f.joint or "")
        kind = "continuous" if f.motion == "revolute" and limit is None else f.motion
        out += _joint(name, kind, parent, child, origin, f, f.axis,
                      None if limit is None else _scaled(limit, f, scale))
        parent = child
    for f in (f for f in t.frames if f.part == "tool"):
        acc = acc @ frame_matrix(f, scale)
    out += _joint("flange_joint", "fixed", parent, "flange", acc, None, None)
    for k, tool in enumerate(t.tools, start=1):
        xyz = _t(*(e.mid * scale["length"] for e in tool))
        name = "tool0" if len(t.tools) == 1 else f"tool{k}"
        out.append(f"  <!-- the tool point the model measures: {_entries(tool)} -->")
        out += _joint(f"{name}_joint", "fixed", "flange", name, xyz, None, None)
    return out + ["</robot>"]


def _entries(entries: Any) -> str:
    return ", ".join(f"{e.name} = {clean(e.mid)} " + (
        f"+- {plus_minus(e.lo, e.hi, float(clean(e.mid)))[1]}" if e.reads else "(nominal)")
        for e in entries)


def _scaled(limit: tuple[float, float], f: FrameRow, scale: dict[str, float]
            ) -> tuple[float, float]:
    """A joint limit in URDF's units (radians, or metres for a prismatic joint)."""
    k = scale["length" if f.motion == "prismatic" else "angle"]
    return limit[0] * k, limit[1] * k


def _joint(name: str, kind: str, parent: str, child: str, origin: np.ndarray,
           f: FrameRow | None, axis: float | None,
           limit: tuple[float, float] | None = None) -> list[str]:
    xyz = " ".join(_num(x) for x in origin[:3, 3])
    rpy = " ".join(_num(x) for x in rpy_of(origin[:3, :3]))
    out = [f'  <link name="{child}"/>']
    if f is not None:
        out.append(f"  <!-- {f.convention} {f.part} {f.number} ({f.joint or 'no variable'}): "
                   f"{_entries(f.entries)} -->")
    out += [f'  <joint name="{name}" type="{kind}">',
            f'    <parent link="{parent}"/>', f'    <child link="{child}"/>',
            f'    <origin xyz="{xyz}" rpy="{rpy}"/>']
    if axis is not None and kind != "fixed":
        out.append(f'    <axis xyz="0 0 {_num(axis)}"/>')
    if limit is not None:  # (the model's; effort and velocity are the controller's)
        out.append(f'    <limit lower="{_num(limit[0])}" upper="{_num(limit[1])}" '
                   'effort="0" velocity="0"/>')
    elif kind == "prismatic":  # URDF requires limits; the model declares none
        out.append('    <limit lower="0" upper="0" effort="0" velocity="0"/>'
                   "  <!-- not calibrated: set the joint's limits -->")
    return out + ["  </joint>"]


def frame_matrix(f: FrameRow, scale: dict[str, float]) -> np.ndarray:
    """The frame's 4x4 transform at q = 0, from its entries' midpoints (in m and rad)."""
    v = {e.name: e.mid * scale[e.dimension] for e in f.entries}
    if f.convention == "mdh":
        return _rx(v["alpha"]) @ _t(v["d"], 0, 0) @ _rz(v["theta"]) @ _t(0, 0, v["r"])
    if f.convention == "dh":
        return _rz(v["theta"]) @ _t(0, 0, v["d"]) @ _t(v["a"], 0, 0) @ _rx(v["alpha"])
    return _t(v["x"], v["y"], v["z"]) @ _rx(v["rx"]) @ _ry(v["ry"]) @ _rz(v["rz"])


def rpy_of(r: np.ndarray) -> tuple[float, float, float]:
    """URDF's roll, pitch, yaw: r = Rz(yaw) Ry(pitch) Rx(roll) (fixed axes x, y, z)."""
    c = math.hypot(r[0, 0], r[1, 0])
    pitch = math.atan2(-r[2, 0], c)
    if c > 1e-12:
        return math.atan2(r[2, 1], r[2, 2]), pitch, math.atan2(r[1, 0], r[0, 0])
    return math.atan2(-r[1, 2], r[1, 1]), pitch, 0.0  # gimbal lock: yaw taken as 0


def _factor(unit: str, to: str) -> float:
    lo, hi = factor(unit, to)
    return 0.5 * lo + 0.5 * hi


def _num(x: float) -> str:
    return clean(x)


def _comment(text: str) -> str:
    return text.replace("--", "- -")


def _t(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
