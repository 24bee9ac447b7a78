"""The calibrated chain as the `kinematics:` YAML that ROS's `ur_description` reads
(`calibc export --format ur-kinematics`): what Universal Robots' `ur_calibration` package
writes for a robot's factory calibration, so the result drops into an existing ROS set-up.

Per joint, from the previous joint's frame (the robot's base first), the origin where the
joint turns about its z axis: x, y, z in metres, roll, pitch, yaw in radians (URDF's fixed-axis
convention), named shoulder, upper_arm, forearm, wrist_1, wrist_2, wrist_3. The measurement
set-up (tracker to base) is not part of it (`--format cell`). It is written for a chain of
six revolute joints about +z, and refused otherwise.
"""

from __future__ import annotations

import hashlib

from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.report.decimals import clean
from calib_dsl.report.dh_convert import converted
from calib_dsl.report.urdf import frame_matrix, rpy_of, scales
from calib_dsl.studies.robot_frames import RobotTable

LINKS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")


def ur_kinematics(model: str, tables: list[RobotTable], units: dict[str, str]) -> str:
    if len(tables) != 1:
        raise CalError(f"a ur-kinematics export is of one robot; {model} has {len(tables)}")
    t = converted(tables[0], "mdh")  # (an MDH joint's origin is its frame at q = 0)
    joints = [f for f in t.frames if f.part == "joint"]
    if len(joints) != 6 or any(f.motion != "revolute" or f.axis != 1.0 for f in joints):
        raise CalError(f"robot '{t.name}': a ur-kinematics export is of six revolute joints "
                       "turning about +z (a Universal Robots arm)")
    scale = scales(units)
    body = ["kinematics:"]
    for link, f in zip(LINKS, joints, strict=True):
        m = frame_matrix(f, scale)
        values = (*m[:3, 3], *rpy_of(m[:3, :3]))
        body.append(f"  {link}:")
        body += [f"    {k}: {clean(v)}" for k, v in
                 zip(("x", "y", "z", "roll", "pitch", "yaw"), values, strict=True)]
    digest = hashlib.sha256("\n".join(body).encode()).hexdigest()[:16]
    head = [f"# calibc export of the guaranteed result of {model}, robot {t.name}: joint "
            "origins at the exported point (calibc export --point), in m and rad, for "
            "ur_description's kinematics_params"]
    return "\n".join([*head, *body, f"  hash: calibc_{digest}"]) + "\n"

