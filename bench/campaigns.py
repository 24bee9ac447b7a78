"""`make bench`, campaigns: `calibc solve models/ur10_tracker.cal` on simulated UR10 tracker
campaigns of every size and shape, and on the public Series B, written into
docs/benchmarks.md (its section "Campaigns").

Each simulated campaign is `calibc simulate models/ur10_simulated.cal --systematic A` (a
smooth pose-dependent error of at most A, plus the model's 0.1 mm of uniform noise: the
consistent set is thin, as real data's is) with random poses, a grid or repeated poses. Each
campaign, and Series B (every 2nd row and all rows; skipped where the data are absent), is
solved at 5 % above its smallest consistent bound (the proven-feasible end of `--min-error`).
Per case: the whole command's wall and CPU time (user + system, the process's own accounting)
and peak memory (its maximum resident set), the certified outer/inner (median and worst over
the parameters: the true hull lies between, so it is the honest measure), and the width over
the linearized yardstick (bench/yardstick.py: a second reference). The simulated
campaigns' truth is checked inside every result.

    python bench/campaigns.py [--cases 500:random,1500:grid,...] [--runs 1] [--out PATH]

The machine may be shared: each case runs `--runs` times (median), and the section says
the host's load.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
from run import calibc_command, machine, run_process  # noqa: E402
from ur10 import DATA, write  # noqa: E402
from yardstick import ratios, summary, yardstick  # noqa: E402

MODEL = ROOT / "models" / "ur10_tracker.cal"
SIMULATED = ROOT / "models" / "ur10_simulated.cal"
OUT = ROOT / "docs" / "benchmarks.md"
SECTION = "## Campaigns: every size and shape"
SYSTEMATIC = 0.9  # mm: with the model's 0.1 mm of noise, errors up to 1 mm as on Series B
ABOVE = 1.05  # each case's bound: this times its smallest proven-consistent bound
SIZES = (500, 1500, 3000, 6000, 12000)
SHAPES = ("random", "grid", "repeated")
DEFAULT_CASES = ",".join(f"{n}:{s}" for n in SIZES for s in SHAPES) + ",B:2,B:1"
# goals of the issue: outer/inner median and worst, seconds at 1500 and 12,000 rows, GB
GOALS = "outer/inner median <= 1.1, worst <= 1.2; <= 20 s at 1500 rows, <= 60 s and 2 GB at 12,000"


def truth() -> dict[str, float]:
    text = SIMULATED.read_text()
    return {m.group(1): float(m.group(2))
            for m in re.finditer(r"param (\w+) in [^;]*? true (-?[0-9.e-]+);", text)}


def simulate(rows: int, shape: str, path: Path) -> None:
    cmd = [*calibc_command(), "simulate", str(SIMULATED), "--configs", str(rows), "--seed",
           str(rows), "--poses", shape, "--systematic", str(SYSTEMATIC), "-o", str(path), "-q"]
    subprocess.run(cmd, check=True, capture_output=True)


def smallest_bound(data: Path, rows: str | None) -> float:
    """The proven-consistent end of `--min-error e` (a Chebyshev fit certified at a point:
    the smallest consistent bound is at most this); its lower end's tight solves are left
    out (they only prove how close it is)."""
    from calib_dsl.analysis.min_error import min_error
    from calib_dsl.problem import Problem

    problem = Problem.load(MODEL, inputs=inputs_of(data, rows, 1.0)).keeping_priors()
    found = min_error(problem, "e", lambda prog: "infeasible")
    return float(found.hi)


def solve(args: list[str], e: float, runs: int, tmp: Path) -> dict:
    out = tmp / "out.json"
    cmd = [*calibc_command(), "solve", str(MODEL), *args, "-D", f"e={e:.6g}", "--json",
           str(out), "-q"]
    measured = [run_process(cmd) for _ in range(runs)]
    return {"wall": statistics.median(m["wall"] for m in measured),
            "cpu": statistics.median(m["cpu"] for m in measured),
            "rss": statistics.median(m["rss"] for m in measured),
            "json": json.loads(out.read_text())}


def inputs_of(data: Path, rows: str | None, e: float):
    from calib_dsl.elaborate.elaborator import Inputs
    from calib_dsl.elaborate.rows import Selection, parse_ranges

    sel = {"m": Selection(parse_ranges(rows), ())} if rows else {}
    return Inputs(data={"m": data}, rows=sel, consts={"e": f"{e:.6g}"})


def case(name: str, runs: int, tmp: Path, data: Path) -> str:
    size, _, shape = name.partition(":")
    if size == "B":
        label = "Series B, " + ("all rows" if shape == "1" else f"every {shape}nd row")
        if not data.exists():
            return f"| {label} | skipped: no data at {data} (UR10_DATA, --data) | | | | | | | |"
        rows, table = f"1..1495:{shape}", data
        truth_of: dict[str, float] = {}
    else:
        rows, table = None, tmp / f"{size}_{shape}.csv"
        simulate(int(size), shape, table)
        label = f"{int(size):,} rows, {shape}"
        truth_of = truth()
    args = ["--data", f"m={table}"] + (["--rows", rows] if rows else [])
    e = ABOVE * smallest_bound(table, rows)
    r = solve(args, e, runs, tmp)
    out = r["json"]
    if out.get("status") != "contracted":
        return (f"| {label} | {e:.3f} | {r['wall']:.1f} | {r['cpu']:.1f} | {out.get('status')} | "
                f"{r['rss']:.0f} | | | |")
    tight = out.get("tightness") or {}
    oi = (f"{tight.get('median_ratio', float('nan')):.3f} / "
          f"{tight.get('worst_ratio', float('nan')):.3f}") if tight else "not computed"
    yard = ratios(out, yardstick(MODEL, inputs_of(table, rows, e)))
    inside = all(p["result"][0] <= truth_of[n] <= p["result"][1]
                 for n, p in out["parameters"].items() if n in truth_of)
    held = ("yes" if inside else "**no**") if truth_of else "-"
    inner = tight.get("seconds", float("nan"))
    return (f"| {label} | {e:.3f} | {r['wall']:.1f} | {r['cpu']:.1f} | "
            f"{out['seconds']:.1f} / {inner:.1f} | "
            f"{r['rss']:.0f} | {oi} | {summary(yard)} | {held} |")


def report(cases: list[str], runs: int, data: Path) -> str:
    m = machine()
    lines = [SECTION, "",
             f"{datetime.date.today()}, {m['cpu']} ({m['cores']} cores, load "
             f"{m['load']} at the start: a host shared with other work, so times are "
             f"noisy): `calibc solve models/ur10_tracker.cal --data FILE -D e=E` as shipped "
             f"(inner bounds and shaving at their defaults), {runs} run(s) each. Simulated "
             f"campaigns: `calibc simulate models/ur10_simulated.cal --configs N --seed N "
             f"--poses SHAPE --systematic {SYSTEMATIC}` (plus 0.1 mm uniform noise); E = "
             f"{ABOVE} times the proven-consistent end of `--min-error e` (a certified "
             f"point: the smallest consistent bound is at most that). Outer/inner: the "
             f"certified ratio (median / worst). Width / yardstick: over the linearized hull "
             f"at the least-squares estimate (bench/yardstick.py). Goals: {GOALS}.", "",
             "| campaign | E (mm) | whole command, wall (s) | CPU, user + system (s) | "
             "solve / inner bounds, wall (s) | peak (MB) | outer/inner | width / yardstick | "
             "truth inside |",
             "|---|---:|---:|---:|---|---:|---|---|---|"]
    with tempfile.TemporaryDirectory(prefix="calibc-campaigns-") as name:
        for c in cases:
            line = case(c, runs, Path(name), data)
            print(line, flush=True)
            lines.append(line)
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default=DEFAULT_CASES,
                    help="ROWS:SHAPE or B:STEP (Series B every STEP-th row), comma-separated")
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--data", type=Path, default=Path(os.environ.get("UR10_DATA", DATA)))
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    section = report(args.cases.split(","), args.runs, args.data)
    write(args.out, section, SECTION)
    print(section)


if __name__ == "__main__":
    main()
