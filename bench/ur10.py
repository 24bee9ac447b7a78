"""`make bench`, real data: calibc on the public UR10 laser-tracker data (Series B) against the
linearized yardstick, written into docs/benchmarks.md (its section "Real data").

The yardstick is the LP over the model linearized at the least-squares estimate of the same
rows (studies/reference.py: the same domains, each measured value within its bound): not
rigorous, but what the data hold to first order. Each case runs `calibc solve` in fresh
processes (median wall time and peak memory of `--runs` runs) and reports, per parameter,
calibc's width over the yardstick's.

    python bench/ur10.py [--runs 3] [--data PATH] [--out docs/benchmarks.md]

Skipped (with a note in the file) where the data set is absent: `make fetch-ur10` gets it.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
from run import calibc_command, machine, run_process  # noqa: E402
from yardstick import yardstick as linearized_yardstick  # noqa: E402

MODEL = ROOT / "models" / "ur10_tracker.cal"
DATA = ROOT.parent / "shared" / "data" / "ur10" / "measurements_joint_configurations.csv"
OUT = ROOT / "docs" / "benchmarks.md"
SECTION = "## Real data: UR10 (Series B)"
# (rows, e in mm, what is expected): the goals
CASES = [("1..1495:15", "1.0", "<= 1.2x the yardstick, <= 10 s"),
         ("1..1495", "1.0", "<= 1.2x the yardstick, <= 60 s, <= 2 GB"),
         ("1..1495", "0.9", "infeasible (exit 1), <= 60 s, <= 2 GB; the solve alone"),
         ("1..1495", "0.9", "infeasible, and the rows at fault named (the diagnosis too)"),
         ("1..1495 without 533, 856", "0.9",
          "not refuted, a narrow enclosure (the smallest bound is about 0.893), <= 60 s"),
         ("1..1495", "0.9", "--outliers 2: consistent, row 856 a certain outlier; 533 and "
          "855 possible (each is proven consistent with all rows but 856 and the other)")]


def yardstick(rows: str, e: str, data: Path) -> dict[str, tuple[float, float, float]]:
    """name: (domain width, yardstick width, least-squares value) on these rows at e."""
    from calib_dsl.elaborate.elaborator import Inputs
    from calib_dsl.elaborate.rows import Selection, parse_ranges

    rows, _, without = rows.partition(" without ")
    excluded = tuple(int(r) for r in without.split(",")) if without else ()
    inputs = Inputs(data={"m": data}, rows={"m": Selection(parse_ranges(rows), excluded)},
                    consts={"e": e})
    return linearized_yardstick(MODEL, inputs)


def solve(rows: str, e: str, data: Path, runs: int, tmp: Path, diagnose: bool,
          extra: tuple[str, ...] = ()) -> dict:
    rows, _, without = rows.partition(" without ")
    cmd = [*calibc_command(), "solve", str(MODEL), "--data", f"m={data}", "-D", f"e={e}",
           "--rows", rows, "--json", str(tmp / "out.json"), *extra]
    cmd += ["--exclude", without.replace(" ", "")] if without else []
    cmd += [] if diagnose else ["--no-diagnose"]
    measured = [run_process(cmd) for _ in range(runs)]
    out = json.loads((tmp / "out.json").read_text())
    return {"wall": statistics.median(m["wall"] for m in measured),
            "rss": statistics.median(m["rss"] for m in measured), "json": out}


def report(data: Path, runs: int) -> str:
    lines = [SECTION, "",
             f"{datetime.date.today()}, {machine()['cpu']}: `calibc solve "
             "models/ur10_tracker.cal` (23 parameters, priors +-5 mm / +-10 mrad, the base "
             "+-5 mm / +-5 mrad about the data's least-squares estimate) on the public file; "
             f"medians of {runs} runs. Width ratio: calibc's width over the linearized "
             "yardstick's (the LP over the model linearized at the least-squares estimate, "
             "not rigorous).", ""]
    with tempfile.TemporaryDirectory(prefix="calibc-ur10-") as name:
        tmp = Path(name)
        for rows, e, goal in CASES:
            diagnose = "diagnosis" in goal
            extra = ("--outliers", "2") if goal.startswith("--outliers") else ()
            r = solve(rows, e, data, 1 if diagnose or extra else runs, tmp, diagnose, extra)
            status = r["json"]["status"]
            head = (f"- rows `{rows}`, e = {e} mm (goal: {goal}): **{status}**, "
                    f"{r['wall']:.1f} s, peak {r['rss']:.0f} MB")
            if extra:
                lines += [head + _outliers(r["json"]), ""]
                continue
            if status != "contracted":
                named = r["json"].get("conflict", {}).get("rows", [])
                lines.append(head + (f"; rows named: {', '.join(str(x['row']) for x in named)}"
                                     if named else "") + ".")
                continue
            yard = yardstick(rows, e, data)
            ratios = {}
            for n, p in r["json"]["parameters"].items():
                lo, hi = p["result"]
                ratios[n] = (hi - lo) / yard[n][1]
            worst = max(ratios, key=ratios.get)  # type: ignore[arg-type]
            lines.append(head + f"; width / yardstick: median "
                         f"{statistics.median(ratios.values()):.2f}, worst "
                         f"{ratios[worst]:.2f} ({worst}); yardstick / domain: median "
                         f"{np.median([y[1] / y[0] for y in yard.values()]):.2f}.")
            lines.append("")
            lines.append("  | " + " | ".join(ratios) + " |")
            lines.append("  |" + "---:|" * len(ratios))
            lines.append("  | " + " | ".join(f"{v:.2f}" for v in ratios.values()) + " |")
            lines.append("")
    return "\n".join(lines) + "\n"


def _outliers(out: dict) -> str:
    """The rows an --outliers run names, and its widths over the domains."""
    found = out.get("outliers", {})
    ratios = [p["result"][1] - p["result"][0] for p in out.get("parameters", {}).values()]
    domains = [p["domain"][1] - p["domain"][0] for p in out.get("parameters", {}).values()]
    narrowed = [r / d for r, d in zip(ratios, domains, strict=True) if r < d]
    return (f"; certain outliers: {found.get('certain')}, possible: {found.get('possible')}; "
            f"{len(narrowed)} of {len(ratios)} parameters narrowed, to a median "
            f"{statistics.median(narrowed) if narrowed else 1.0:.2f} of their domains.")


def write(out: Path, section: str, title: str = SECTION) -> None:
    """Replace the section `title` in `out` (or add it at the end)."""
    text = out.read_text(encoding="utf-8") if out.exists() else ""
    start = ("\n" + text).find("\n" + title + "\n")  # the heading's own line
    if start >= 0:
        end = text.find("\n## ", start + len(title))
        text = text[:start] + section + (text[end + 1:] if end >= 0 else "")
    else:
        text = text.rstrip("\n") + "\n\n" + section
    out.write_text(text, encoding="utf-8")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--data", type=Path, default=Path(os.environ.get("UR10_DATA", DATA)))
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    if not args.data.exists():
        section = (f"{SECTION}\n\nNot measured on {datetime.date.today()}: the public data "
                   f"set was not at {args.data} (`make fetch-ur10` gets it).\n")
    else:
        section = report(args.data, args.runs)
    write(args.out, section)
    print(section)


if __name__ == "__main__":
    main()
