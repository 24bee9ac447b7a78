"""A serial chain written in the other DH convention (`calibc export --format dh-table
--convention dh|mdh`), exactly: the same transforms regrouped, nothing approximated.

Modified DH (Khalil-Kleinfinger) writes joint i as Rx(alpha_i) Tx(d_i) Rz(theta_i) Tz(r_i);
standard DH as Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i). A chain of n MDH joints
  M_1 M_2 ... M_n = Rx(alpha_1) Tx(d_1) . prod_i [Rz(theta_i) Tz(r_i) Rx(alpha_{i+1}) Tx(d_{i+1})]
with alpha_{n+1} = d_{n+1} = 0: the standard-DH joint i has theta_i, d = r_i, a = d_{i+1},
alpha = alpha_{i+1}, and Rx(alpha_1) Tx(d_1) becomes a base frame of its own (an MDH frame with
theta = r = 0). The flange (frame n) is the same in both, so tool frames and tool points do
not move; the joint variables stay in theta (revolute) or in r/d (prismatic). Standard to
modified is the same regrouping read backwards (the last joint's a and alpha become a tool
frame). Each entry keeps its guaranteed enclosure: entries move, none is recomputed.
"""

from __future__ import annotations

from dataclasses import replace

from calib_dsl.studies.robot_frames import STANDARD_DH, Entry, FrameRow, RobotTable

CONVENTIONS = ("mdh", "dh")


def converted(t: RobotTable, to: str) -> RobotTable:
    """The robot `t` with its joints in convention `to` (itself if they are already)."""
    joints = [f for f in t.frames if f.part == "joint"]
    if all(f.convention == to for f in joints):
        return t
    base = [f for f in t.frames if f.part == "base"]
    tool = [f for f in t.frames if f.part == "tool"]
    if to == "dh":
        head = _entries(joints[0], ("alpha", "d"))
        rows = [_dh(f, nxt) for f, nxt in zip(joints, [*joints[1:], None], strict=True)]
        if any(e.reads or e.lo != 0 or e.hi != 0 for e in head):  # (else the identity)
            base = [*base, _fixed("base", len(base) + 1, head)]
        return replace(t, frames=tuple([*base, *rows, *tool]))
    tail = _entries(joints[-1], ("alpha", "a"))
    rows = [_mdh(f, prev) for f, prev in zip(joints, [None, *joints[:-1]], strict=True)]
    if any(e.reads or e.lo != 0 or e.hi != 0 for e in tail):  # (else the identity)
        tool = [_fixed("tool", 1, tail), *(replace(f, number=f.number + 1) for f in tool)]
    return replace(t, frames=tuple([*base, *rows, *tool]))


def _dh(f: FrameRow, nxt: FrameRow | None) -> FrameRow:
    """Standard-DH joint i from MDH joint i (theta, r) and joint i + 1 (alpha, d)."""
    alpha, d = _entries(nxt, ("alpha", "d")) if nxt is not None else (_zero("alpha"),
                                                                       _zero("d"))
    entries = {"theta": f.entry("theta"), "d": _renamed(f.entry("r"), "d"),
               "a": _renamed(d, "a"), "alpha": alpha}
    return replace(f, convention="dh", entries=tuple(entries[n] for n in STANDARD_DH))


def _mdh(f: FrameRow, prev: FrameRow | None) -> FrameRow:
    """MDH joint i from standard-DH joint i (theta, d) and joint i - 1 (a, alpha)."""
    alpha, a = _entries(prev, ("alpha", "a")) if prev is not None else (_zero("alpha"),
                                                                        _zero("a"))
    entries = (alpha, _renamed(a, "d"), f.entry("theta"), _renamed(f.entry("d"), "r"))
    return replace(f, convention="mdh", entries=entries)


def _fixed(part: str, number: int, pre: tuple[Entry, Entry]) -> FrameRow:
    """A fixed MDH frame Rx(alpha) Tx(d) (theta = r = 0)."""
    alpha, d = pre
    return FrameRow(part, number, "mdh",
                    (alpha, _renamed(d, "d"), _zero("theta"), _zero("r")))


def _entries(f: FrameRow | None, names: tuple[str, str]) -> tuple[Entry, Entry]:
    assert f is not None
    return f.entry(names[0]), f.entry(names[1])


def _renamed(e: Entry, name: str) -> Entry:
    return replace(e, name=name)


def _zero(name: str) -> Entry:
    return Entry(name, 0.0, 0.0, 0.0)
