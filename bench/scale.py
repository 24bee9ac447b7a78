"""`make bench`, scale: thousands of configurations, written into docs/benchmarks.md (its
section "Scale").

- RX90 Test A (`models/rx90_lengths.cal`) on 1,000, 5,000 and 10,000 configurations drawn by
  `calibc simulate` (seeded), both strategies: the whole command's wall time and peak memory,
  its compile (parse, elaborate, compile) and solve times (medians of `--runs` fresh
  processes), and with `--baseline REV` the same runs of an earlier revision of calibc (a
  git worktree of it imported in place of this one), side by side with their ratios.
- The UR10 laser-tracker model (`models/ur10_tracker.cal`) on a simulated table the size of
  the public data's Series A (11,910 configurations), tight: the whole command (goal: 60 s and
  2 GB), and the slope of peak memory over the number of configurations (goal: 0.1 MB each).

    python bench/scale.py [--runs 3] [--baseline REV] [--quick] [--out docs/benchmarks.md]
"""

from __future__ import annotations

import argparse
import datetime
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
from run import calibc_command, machine, measure, run_process  # noqa: E402
from ur10 import OUT, write  # noqa: E402

SECTION = "## Scale"
RX90 = ROOT / "models" / "rx90_lengths.cal"
UR10 = ROOT / "models" / "ur10_tracker.cal"
UR10_SIM = ROOT / "models" / "ur10_simulated.cal"
SIZES = (1000, 5000, 10000)
UR10_SIZES = (3000, 11910)  # the slope of memory, and Series A's size
SEED = 24
GOAL_UR10 = (60.0, 2048.0)  # s and MB, the whole command
GOAL_SLOPE = 0.1  # MB per configuration


def simulate(model: Path, n: int, out: Path) -> Path:
    if not out.exists():
        run_process([*calibc_command(), "simulate", str(model), "--configs", str(n), "--seed",
                     str(SEED), "-o", str(out), "-q"])
    return out


def baseline_tree(rev: str, tmp: Path) -> Path:
    """A worktree of `rev`: its calib_dsl is imported in place of this one's."""
    tree = tmp / "baseline"
    subprocess.run(["git", "worktree", "add", "--detach", str(tree), rev], cwd=ROOT,
                   check=True, capture_output=True)
    return tree


def rx90(runs: int, tmp: Path, sizes: tuple[int, ...], tree: Path | None) -> list[dict]:
    out = []
    for n in sizes:
        data = simulate(RX90, n, tmp / f"rx90_{n}.csv")
        for strategy in ("hc4", "tight"):
            # (without the inner bounds, which the baseline computes at every size: they
            # would hide compile and solve)
            argv = [str(RX90), "--data", str(data), "--strategy", strategy, "--no-inner",
                    "-q"]
            row: dict[str, Any] = {"n": n, "strategy": strategy, "now": measure(argv, runs, tmp)}
            if tree is not None:
                row["then"] = _in_tree(tree, argv, runs, tmp)
            out.append(row)
            print(n, strategy, {k: round(v["wall"], 2) for k, v in row.items()
                                if isinstance(v, dict)}, flush=True)
    return out


def _in_tree(tree: Path, argv: list[str], runs: int, tmp: Path) -> dict[str, Any]:
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = str(tree) + (os.pathsep + old if old else "")
    try:
        return measure([a.replace(str(ROOT / "models"), str(tree / "models")) for a in argv],
                       runs, tmp)
    finally:
        if old is None:
            del os.environ["PYTHONPATH"]
        else:
            os.environ["PYTHONPATH"] = old


def ur10(runs: int, tmp: Path, sizes: tuple[int, ...]) -> list[dict]:
    out = []
    for n in sizes:
        data = simulate(UR10_SIM, n, tmp / f"ur10_{n}.csv")
        argv = [str(UR10), "--data", f"m={data}", "-q"]
        out.append({"n": n, "now": measure(argv, runs, tmp)})
        print("ur10", n, round(out[-1]["now"]["wall"], 2), flush=True)
    return out


def _phases(m: dict[str, Any]) -> str:
    return (f"{m['wall']:.1f} | {m['elaborate'] + m['compile']:.1f} | {m['solve']:.1f} | "
            f"{m['rss']:.0f}")


def report(rx: list[dict], ur: list[dict], runs: int, rev: str | None, minutes: float) -> str:
    info = machine()
    lines = [SECTION, "",
             f"{datetime.date.today()}, {info['cpu']} ({info['cores']} cores, {info['ram']}), "
             f"Python {info['python']}, numpy {info['numpy']}: `bench/scale.py`, "
             f"{minutes:.1f} minutes; medians of {runs} runs, each a fresh process. *wall*: the "
             "whole `calibc solve` command; *compile*: parse, elaborate and compile; *solve*: "
             "the strategy; *MB*: peak resident memory of the process.", "",
             "RX90 Test A (`models/rx90_lengths.cal`, matrix formulation, `--no-inner`), "
             f"data drawn by `calibc simulate --seed {SEED}`:", ""]
    head = "| configurations | strategy | primitives | wall s | compile s | solve s | MB |"
    rule = "|---:|---|---:|---:|---:|---:|---:|"
    if rev:
        head += f" {rev}: wall s | compile s | solve s | MB | wall ratio | MB ratio |"
        rule += "---:|---:|---:|---:|---:|---:|"
    lines += [head, rule]
    for r in rx:
        now = r["now"]
        line = (f"| {r['n']} | {r['strategy']} | {now['primitives']} | {_phases(now)} |")
        if "then" in r:
            then = r["then"]
            line += (f" {_phases(then)} | {then['wall'] / now['wall']:.1f}x | "
                     f"{then['rss'] / now['rss']:.1f}x |")
        lines.append(line)
    if rev:
        lines += ["", f"Ratios: {rev} over now (above 1: now is faster, or smaller)."]
    lines += ["", "UR10 laser-tracker model (`models/ur10_tracker.cal`, 23 parameters, "
              "tight, inner bounds at their default), on tables simulated by "
              f"`calibc simulate models/ur10_simulated.cal --seed {SEED}`:", "",
              "| configurations | primitives | wall s | compile s | solve s | MB | goal |",
              "|---:|---:|---:|---:|---:|---:|---|"]
    for r in ur:
        now = r["now"]
        goal = ""
        if r["n"] == max(x["n"] for x in ur):
            ok = now["wall"] <= GOAL_UR10[0] and now["rss"] <= GOAL_UR10[1]
            goal = f"<= {GOAL_UR10[0]:.0f} s and 2 GB: {'met' if ok else 'NOT met'}"
        lines.append(f"| {r['n']} | {now['primitives']} | {_phases(now)} | {goal} |")
    if len(ur) >= 2:
        a, b = ur[0], ur[-1]
        slope = (b["now"]["rss"] - a["now"]["rss"]) / (b["n"] - a["n"])
        lines += ["", f"Peak memory grows by {slope:.3f} MB per configuration between "
                  f"{a['n']} and {b['n']} (goal: <= {GOAL_SLOPE} MB: "
                  f"{'met' if slope <= GOAL_SLOPE else 'NOT met'})."]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--baseline", metavar="REV", help="also measure this git revision")
    ap.add_argument("--quick", action="store_true", help="1,000 RX90 rows and 3,000 UR10 only")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    start = datetime.datetime.now()
    with tempfile.TemporaryDirectory(prefix="calibc-scale-") as name:
        tmp = Path(name)
        tree = baseline_tree(args.baseline, tmp) if args.baseline else None
        try:
            rx = rx90(args.runs, tmp, SIZES[:1] if args.quick else SIZES, tree)
            ur = ur10(args.runs, tmp, UR10_SIZES[:1] if args.quick else UR10_SIZES)
        finally:
            if tree is not None:
                subprocess.run(["git", "worktree", "remove", "--force", str(tree)], cwd=ROOT,
                               capture_output=True)
    minutes = (datetime.datetime.now() - start).total_seconds() / 60
    section = report(rx, ur, args.runs, args.baseline, minutes)
    write(args.out, section, SECTION)
    print(section)


if __name__ == "__main__":
    main()
