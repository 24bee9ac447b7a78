"""A robot's calibrated kinematics as URDF (`calibc export --format urdf`): one joint per axis,
each joint's origin (xyz, rpy) computed from the frame entries at the result's midpoints.

URDF has no uncertainty: the midpoints are written, and each joint's comment gives its
entries with their guaranteed half-widths (the model's units). URDF is in metres and radians,
whatever the model's units: lengths and angles are converted.

A modified-DH joint is F(q) = Rx(alpha) Tx(d) Rz(theta + q) Tz(r) = F(0) Rz(q) (Rz and Tz
commute; a prismatic joint F(0) Tz(q)): the joint's origin is F(0), its axis z. A standard-DH
joint is Rz(q) F(0): the motion comes first, so the joint's origin is what the previous
frame left, and F(0) moves on to the next origin. Base frames make a fixed joint from
`base_link`; what the last joint and the tool frames leave, a fixed joint to `flange` (the
frame where the model's tool points are given).
"""

from __future__ import annotations

import math
from xml.sax.saxutils import quoteattr

import numpy as np

from calib_dsl.elaborate.units import factor
from calib_dsl.report.export import plus_minus
from calib_dsl.studies.robot_frames import FrameRow, RobotTable


def urdf(model: str, tables: list[RobotTable], units: dict[str, str]) -> str:
    scale = {"length": _factor(units["length"], "m"), "angle": _factor(units["angle"], "rad")}
    out = ['<?xml version="1.0"?>',
           f"<!-- calibc export of the guaranteed result of {_comment(model)}: frame entries "
           f"at the midpoints of their enclosures, in m and rad (URDF's units; the model's: "
           f"{units['length']} and {units['angle']}); each joint's comment gives its entries "
           f"+- their guaranteed half-widths in the model's units. -->"]
    for t in tables:
        out += _robot(t, scale)
    return "\n".join(out) + "\n"


def _robot(t: RobotTable, scale: dict[str, float]) -> list[str]:
    out = [f"<robot name={quoteattr(t.name)}>", '  <link name="base_link"/>']
    acc = np.eye(4)
    for f in (f for f in t.frames if f.part == "base"):
        acc = acc @ frame_matrix(f, scale)
    parent = "base_link"
    if any(f.part == "base" for f in t.frames):
        out += _joint("base", "fixed", parent, "link0", acc, None, None)
        parent, acc = "link0", np.eye(4)
    for f in (f for f in t.frames if f.part == "joint"):
        child = f"link{f.number}"
        fixed = frame_matrix(f, scale)
        origin, acc = (acc @ fixed, np.eye(4)) if f.convention == "mdh" else (acc, fixed)
        kind = {"revolute": "continuous"}.get(f.motion, f.motion)
        out += _joint(f"joint{f.number}", kind, parent, child, origin, f, f.axis)
        parent = child
    for f in (f for f in t.frames if f.part == "tool"):
        acc = acc @ frame_matrix(f, scale)
    out += _joint("flange_joint", "fixed", parent, "flange", acc, None, None)
    return out + ["</robot>"]


def _joint(name: str, kind: str, parent: str, child: str, origin: np.ndarray,
           f: FrameRow | None, axis: float | None) -> list[str]:
    xyz = " ".join(_num(x) for x in origin[:3, 3])
    rpy = " ".join(_num(x) for x in rpy_of(origin[:3, :3]))
    out = [f'  <link name="{child}"/>']
    if f is not None:
        entries = ", ".join(f"{e.name} = {plus_minus(e.lo, e.hi, e.mid)[0]!r} +- "
                            f"{plus_minus(e.lo, e.hi, e.mid)[1]}" for e in f.entries)
        out.append(f"  <!-- {f.convention} joint {f.number} ({f.joint or 'no variable'}): "
                   f"{entries} -->")
    out += [f'  <joint name="{name}" type="{kind}">',
            f'    <parent link="{parent}"/>', f'    <child link="{child}"/>',
            f'    <origin xyz="{xyz}" rpy="{rpy}"/>']
    if axis is not None and kind != "fixed":
        out.append(f'    <axis xyz="0 0 {_num(axis)}"/>')
    if kind == "prismatic":  # URDF requires limits; calibration does not know them
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
    return repr(float(x) + 0.0)  # (no "-0.0")


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
