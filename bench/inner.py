"""`make bench`, certified inner bounds: outer/inner width ratios and the extra time they cost,
written into docs/benchmarks.md (its section "Certified inner bounds").

For each case: the tight solve, then the inner bounds on its box, in this process (the solve's
and the inner bounds' own clocks, medians of `--runs` runs on the shipped data; one run per
fresh `calibc simulate` draw). Ratio: the result's width over the certified inner width, per
unknown whose result is not a point; 1 means the result is the hull of the solution set.

    python bench/inner.py [--runs 3] [--draws 3] [--out docs/benchmarks.md]
"""

from __future__ import annotations

import argparse
import datetime
import statistics
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
from run import machine  # noqa: E402
from ur10 import DATA, OUT, write  # noqa: E402

SECTION = "## Certified inner bounds"
MODELS = [("Test A", "rx90_lengths.cal"), ("33 parameters, 1/20 domains", "rx90_recalibrate.cal"),
          ("33 parameters, section-4 domains", "rx90_full.cal")]
SEEDS = (101, 202, 303, 404, 505)


def case(model: Path, data: Path | None, runs: int, consts: dict[str, str] | None = None,
         rows: str | None = None) -> dict[str, Any]:
    from calib_dsl.analysis.inner import inner_bounds
    from calib_dsl.elaborate.elaborator import Inputs
    from calib_dsl.elaborate.rows import Selection, parse_ranges
    from calib_dsl.pipeline import load, solve
    from calib_dsl.relax.layout import independents

    inputs = Inputs(data={"m": str(data)} if data else {}, consts=consts or {},
                    rows={"m": Selection(parse_ranges(rows), ())} if rows else {})
    solves, inners = [], []
    for _ in range(runs):
        prog = load(model, inputs=inputs)
        sol = solve(prog)
        inner = inner_bounds(prog, sol.lo, sol.hi)
        solves.append(sol.seconds)
        inners.append(inner.seconds)
    ind = independents(prog)
    outer = sol.hi[ind] - sol.lo[ind]
    moving = outer > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = outer / (inner.hi - inner.lo)
    names = [prog.slots.names[i] for i in ind]
    return {"solve": statistics.median(solves), "inner": statistics.median(inners),
            "ratios": {n: float(r) for n, r, m in zip(names, ratio, moving, strict=True) if m},
            "consistent": inner.consistent}


def line(label: str, r: dict[str, Any]) -> str:
    q = list(r["ratios"].values())
    if not r["consistent"] or not q:
        return f"| {label} | none certified | | | {r['solve']:.2f} | {r['inner']:.2f} | |"
    worst = max(r["ratios"], key=r["ratios"].get)
    return (f"| {label} | {statistics.median(q):.4f} | {max(q):.4f} ({worst}) | "
            f"{sum(x <= 1.05 for x in q)}/{len(q)} | {r['solve']:.2f} | {r['inner']:.2f} | "
            f"{r['inner'] / r['solve']:.0%} |")


def report(runs: int, draws: int) -> str:
    from calib_dsl.analysis.simulate import simulate

    out = [SECTION, "",
           f"{datetime.date.today()}, {machine()['cpu']}: outer/inner = the tight solve's "
           "width over the certified inner width (1: the result is the hull), per unknown whose "
           "result is not a point; times in seconds, the solve's and the inner bounds' own "
           f"clocks (medians of {runs} runs on the shipped data, one run per fresh draw of "
           "`calibc simulate`, seeds " + ", ".join(map(str, SEEDS[:draws])) + ").", "",
           "| case | outer/inner median | worst | <= 1.05 | solve s | inner s | extra |",
           "|---|---:|---:|---:|---:|---:|---:|"]
    with tempfile.TemporaryDirectory(prefix="calibc-inner-") as name:
        extras = []
        for label, file in MODELS:
            model = ROOT / "models" / file
            runs_of = [case(model, None, runs)]
            out.append(line(f"{label} (`{file}`), shipped data", runs_of[-1]))
            print(out[-1], flush=True)
            for seed in SEEDS[:draws]:
                data = Path(name) / f"{file}.{seed}.csv"
                simulate(model, 50, seed, out_csv=data)
                runs_of.append(case(model, data, 1))
                out.append(line(f"{label}, draw {seed}", runs_of[-1]))
                print(out[-1], flush=True)
            share = [r["inner"] / r["solve"] for r in runs_of]
            extras.append(f"`{file}` {min(share):.0%}-{max(share):.0%}")
        out += ["", "Where a ratio is above 1, the gap is the outer method's: on "
                "`rx90_recalibrate.cal` the inner bounds equal the hull of the model linearized "
                "at the truth to 0.9996, and of three more draws of `rx90_full.cal` one (505) "
                "stays at 1.054 for theta2, the outer rounds' own fixed point (history, *The "
                "33-parameter models' last 7 %*). The extra time is the LPs, one per end of "
                "each unknown (the joint readings among their columns), two at a time in "
                "threads, the point checks, and the ends sought again from their own points "
                "where the first search fell 1 % of the width short of its LP's optimum. "
                "Extra time over the solve (goal 30 %): " + ", ".join(extras) + ".", ""]
        if DATA.exists():
            r = case(ROOT / "models" / "ur10_tracker.cal", DATA, runs, {"e": "1.0"},
                     "1..1495:15")
            q = r["ratios"]
            out += [f"UR10 (the public Series B file, 23 parameters, every 15th row, e = 1.0 "
                    f"mm): outer/inner median {statistics.median(q.values()):.3f}, worst "
                    f"{max(q.values()):.3f}; solve {r['solve']:.2f} s, inner bounds "
                    f"{r['inner']:.2f} s. Per parameter:", "",
                    "  | " + " | ".join(q) + " |", "  |" + "---:|" * len(q),
                    "  | " + " | ".join(f"{v:.3f}" for v in q.values()) + " |", ""]
        else:
            out += [f"UR10: not measured (the public data set was not at {DATA}).", ""]
    return "\n".join(out) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--draws", type=int, default=3)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    section = report(args.runs, args.draws)
    write(args.out, section, SECTION)
    print(section)


if __name__ == "__main__":
    main()
