"""Simulated UR5 campaigns for tests: a robot with known true values, measured by a tracker
(exact joints, positions within +- e), written in a test's temporary directory as a model
and a CSV in whatever layout the test needs (target and dif columns, other units...)."""

from __future__ import annotations

import csv
from collections.abc import Callable, Mapping
from pathlib import Path

from calib_dsl.studies.simulate import simulate

ROBOT = (Path(__file__).resolve().parent.parent / "models" / "robots" / "ur5.cal").as_posix()

# name: (the domain's centre, as the model writes it; half-width; a true value inside)
PARAMS: dict[str, tuple[str, float, float]] = {
    "base_x": ("0", 5, 1.2), "base_y": ("0", 5, -0.7), "base_z": ("0", 5, 0.4),
    "base_rx": ("0", 0.005, 0.001), "base_ry": ("0", 0.005, -0.002),
    "base_rz": ("0", 0.005, 0.0015),
    "alpha2": ("ur5_alpha2", 0.01, 1.5718), "d2": ("ur5_d2", 5, 0.3),
    "theta2": ("ur5_theta2", 0.01, 0.001), "r2": ("ur5_r2", 5, -0.5),
    "alpha3": ("ur5_alpha3", 0.01, 0.002), "d3": ("ur5_d3", 5, -425.6),
    "theta3": ("ur5_theta3", 0.01, -0.001),
    "alpha4": ("ur5_alpha4", 0.01, -0.001), "d4": ("ur5_d4", 5, -392.0),
    "theta4": ("ur5_theta4", 0.01, 0.002),
    "alpha5": ("ur5_alpha5", 0.01, 1.5690), "d5": ("ur5_d5", 5, 0.2),
    "theta5": ("ur5_theta5", 0.01, -0.002), "r5": ("ur5_r5", 5, 95.1),
    "tx": ("0", 5, 0.3), "ty": ("0", 5, -0.4), "tz": ("50", 5, 50.6),
}
FIXED = ("const alpha1 = ur5_alpha1; const d1 = ur5_d1; const theta1 = ur5_theta1; "
         "const r1 = ur5_r1;\nconst r3 = ur5_r3; const r4 = ur5_r4;\nconst alpha6 = ur5_alpha6; "
         "const d6 = ur5_d6; const theta6 = ur5_theta6; const r6 = ur5_r6;\n")
JOINTS = "m.q1[k], m.q2[k], m.q3[k], m.q4[k], m.q5[k], m.q6[k]"


def header(e: float, true: Mapping[str, float] | None = None,
           half: Mapping[str, float] | None = None, with_true: bool = True) -> str:
    """The model up to its table: units, robot, e, the parameters (`true` values replace
    PARAMS', `half` their half-widths)."""
    lines = ['units mm, rad;', f'include "{ROBOT}";', f"const e = {e!r};"]
    for name, (centre, w, t) in PARAMS.items():
        t = (true or {}).get(name, t)
        w = (half or {}).get(name, w)
        lines.append(f"param {name} in {centre} +- {w!r}" + (f" true {t!r};" if with_true
                                                               else ";"))
    return "\n".join(lines) + "\n" + FIXED


def simulate_rows(tmp: Path, rows: int, seed: int, e: float,
                  true: Mapping[str, float] | None = None) -> list[dict[str, float]]:
    """`rows` configurations (joints uniform in [-pi, pi]) and their positions within +- e of
    the true robot's, as dicts q1..q6, x, y, z."""
    model = tmp / "simulation.cal"
    wide = {name: 1000 * w for name, (_, w, _) in PARAMS.items()}  # (a truth beyond a prior)
    model.write_text(header(e, true, wide) + (
        'table m = "simulation.csv" {\n  q1, q2, q3, q4, q5, q6 : +- 0 simulate in [-pi, pi];\n'
        "  x, y, z : +- e;\n}\nfor k in 1..rows(m) {\n"
        f"  ur5({JOINTS}) at (tx, ty, tz) == (m.x[k], m.y[k], m.z[k]);\n}}\n"),
        encoding="utf-8")
    simulate(model, rows, seed)
    with open(tmp / "simulation.csv", newline="", encoding="utf-8") as f:
        return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]


def write_table(path: Path, rows: list[dict[str, float]], columns: list[str],
                cell: Callable[[dict[str, float], str], float]) -> None:
    """A CSV of `columns`, each cell `cell(row, column)` written to full precision."""
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(columns)
        for r in rows:
            w.writerow([repr(cell(r, c)) for c in columns])
