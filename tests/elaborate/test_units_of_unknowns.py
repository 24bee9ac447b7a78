"""The unit of each unknown, as the robot frames say (docs/json.md `unit`): an unknown added
into a length entry or a tool point's coordinate is a length, into an angle entry an angle; a
factor or an unknown no frame uses has none. Read by the report and the figures, which must
never add millimetres to radians."""

from __future__ import annotations

from pathlib import Path

from calib_dsl.pipeline import load

ROOT = Path(__file__).resolve().parents[2]


def test_the_ur10_s_unknowns_are_lengths_and_angles():
    units = load(ROOT / "models" / "ur10_tracker.cal").units
    assert {n for n, u in units.items() if u == "rad"} == {
        "base_rx", "base_ry", "base_rz", "alpha2", "theta2", "alpha3", "theta3", "alpha4",
        "theta4", "alpha5", "theta5"}
    assert {n for n, u in units.items() if u == "mm"} == {
        "base_x", "base_y", "base_z", "d2", "r2", "d3", "d4", "d5", "r5", "tx", "ty", "tz"}


def test_only_sums_say_a_dimension(write_model):
    path = write_model("""
units mm, deg;
param a in [0, 1]; param s in [0.9, 1.1]; param off in [-1, 1]; param free in [0, 1];
param px in [-1, 1];
robot r(q) {
  joint alpha = 0, d = s * 100, theta = q - off, r = a;
}
r(0.5) at (px, 0, 0) == (100, 0, 0);
free <= 1;
""")
    units = load(path).units
    assert units == {"a": "mm", "off": "deg", "px": "mm"}  # s: a factor; free: no frame
