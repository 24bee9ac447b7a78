"""`make bench`, predictions on the real UR10: `calibc validate` calibrated on every 15th row
of the public Series B file (e = 1.0 mm) and validated on the other rows, and `calibc predict`
after calibrating on all rows, each timed as a whole process (median of `--runs`), written
into docs/benchmarks.md (its section "Predictions: UR10"): coverage, box widths, outer/inner
of the predicted coordinates (the inner intervals: predictions at certified points). A
simulated UR10 (`calibc simulate models/ur10_simulated.cal`, 1500 random poses) is validated
the same way, against its own model.

    python bench/predict.py [--runs 1] [--out docs/benchmarks.md]
"""

from __future__ import annotations

import argparse
import datetime
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
from run import machine  # noqa: E402
from ur10 import DATA, OUT, write  # noqa: E402

SECTION = "## Predictions: UR10"
MODEL = ROOT / "models" / "ur10_tracker.cal"
SIMULATED = ROOT / "models" / "ur10_simulated.cal"
SIM_ROWS, SIM_SEED = 1500, 41
CALIBC = [sys.executable, "-c", "from calib_dsl.cli import main; main()"]


def timed(args: list[str], out: Path, runs: int) -> tuple[tuple[float, float], dict]:
    """The command's wall and CPU (user + sys) seconds, medians of `runs`, and its JSON."""
    seconds, cpu = [], []
    for _ in range(runs):
        used = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        done = subprocess.run([*CALIBC, *args, "-q", "--json", str(out)], cwd=ROOT,
                              capture_output=True, text=True)
        seconds.append(time.perf_counter() - start)
        now = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu.append(now.ru_utime + now.ru_stime - used.ru_utime - used.ru_stime)
        if done.returncode != 0:
            raise SystemExit(f"calibc {args[0]} failed: {done.stderr.strip()}")
    return ((statistics.median(seconds), statistics.median(cpu)),
            json.loads(out.read_text(encoding="utf-8")))


def line(label: str, seconds: tuple[float, float], doc: dict) -> str:
    t, w = doc.get("tightness") or {}, doc["width"]
    cover = f"{doc['coverage']:.4f}" if "coverage" in doc else "-"
    ratio = (f"{t['median_ratio']:.3f} | {t['worst_ratio']:.3f}"
             if t.get("median_ratio") is not None else "none | none")
    return (f"| {label} | {cover} | {w['median']:.3f} | {w['max']:.3f} | {ratio} | "
            f"{seconds[0]:.1f} | {seconds[1]:.1f} |")


def simulated(tmp: Path, out: Path, runs: int) -> str:
    """Validate on a simulated UR10: every 15th of SIM_ROWS random poses calibrated."""
    table = tmp / "simulated.csv"
    done = subprocess.run([*CALIBC, "simulate", str(SIMULATED), "--configs", str(SIM_ROWS),
                           "--seed", str(SIM_SEED), "-q", "-o", str(table)], cwd=ROOT,
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"calibc simulate failed: {done.stderr.strip()}")
    every = f"1..{SIM_ROWS}:15"
    s, doc = timed(["validate", str(SIMULATED), "--data", f"m={table}", "--rows", every,
                    "--at", str(table), "--at-skip", every], out, runs)
    return line(f"simulated UR10 ({SIM_ROWS} poses, seed {SIM_SEED}): validate, every 15th "
                "calibrated", s, doc)


def report(runs: int) -> str:
    out = [SECTION, "", f"{machine()['cpu']}; {datetime.date.today()}; wall and CPU "
           f"(user + sys) seconds of the whole process, median of {runs}. Widths in mm per "
           "coordinate; outer/inner over the predicted coordinates.", "",
           "| case | coverage | width median | width max | outer/inner median | worst | s | "
           "CPU s |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    data = str(DATA)
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "out.json"
        s, doc = timed(["validate", str(MODEL), "--data", f"m={data}", "--rows", "1..1495:15",
                        "-D", "e=1.0", "--at", data, "--at-skip", "1..1495:15"], f, runs)
        out.append(line("validate: every 15th row calibrated, the others held out", s, doc))
        s, doc = timed(["predict", str(MODEL), "--data", f"m={data}", "-D", "e=1.0", "--at",
                        data, "--at-rows", "1..1495:15"], f, runs)
        out.append(line("predict: all rows calibrated, every 15th predicted", s, doc))
        out.append(simulated(Path(tmp), f, runs))
    return "\n".join(out) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    if not DATA.exists():
        section = (f"{SECTION}\n\nNot measured on {datetime.date.today()}: the public data "
                   f"set was not at {DATA} (`make fetch-ur10` gets it).\n")
    else:
        section = report(args.runs)
    write(args.out, section, SECTION)
    print(section)


if __name__ == "__main__":
    main()
