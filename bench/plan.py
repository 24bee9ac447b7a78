"""`make bench`, planning: `calibc plan` on models/ur10_simulated.cal at a bound of 0.5 mm,
written into docs/benchmarks.md (its section "Planning a campaign").

For each candidate set (`calibc simulate --configs 3000 --seed S`: drawn here, never in the
repository), 30 configurations are planned (`calibc plan --n 30`, timed) and measured as a
user would: `calibc simulate --at PLAN` then `calibc solve`, each unknown's width over its
domain, the median over the unknowns; 5 random sets of 30 of the same candidates the same
way (their mean is the baseline). Every simulated measurement has a seed of its own (a
reused seed would give every design the same noise, and one lucky draw would look like a
trend). Then a sweep (`--n 10..60:10`): each count's predicted
widths (median over noisy linearized hulls) against a simulated solve of the design the
sweep chose at that count. The truth must lie inside every solve.

    python bench/plan.py [--seeds 1,2] [--out PATH]
"""

from __future__ import annotations

import argparse
import datetime
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
from run import calibc_command, machine  # noqa: E402
from ur10 import write  # noqa: E402

MODEL = ROOT / "models" / "ur10_simulated.cal"
OUT = ROOT / "docs" / "benchmarks.md"
SECTION = "## Planning a campaign"
BOUND = "0.5"  # mm: the error bound the campaign is simulated and solved at
CANDIDATES, N, RANDOM_SETS = 3000, 30, 5
SWEEP = "10..60:10"
GOALS = ("planned / random median width/domain <= 0.7; plan <= 30 s (3000 candidates, N = 30);"
         " sweep predictions within 20 % of simulated solves; truth inside every solve")


def calibc(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([*calibc_command(), *map(str, args)], capture_output=True,
                          text=True, check=False)


def measured(rows_file: Path, seed: int, tmp: Path) -> tuple[dict, bool]:
    """simulate --at, then solve: {name: width / domain} and whether the truth is inside."""
    data, result = tmp / f"m{seed}.csv", tmp / f"r{seed}.json"
    done = calibc("simulate", MODEL, "--at", rows_file, "-o", data, "--seed", seed, "-D",
                  f"e={BOUND}", "-q")
    assert done.returncode == 0, done.stderr
    calibc("solve", MODEL, "--data", data, "-D", f"e={BOUND}", "-q", "--no-identify",
           "--json", result)
    params = json.loads(result.read_text())["parameters"]
    ratios = {n: (p["result"][1] - p["result"][0]) / (p["domain"][1] - p["domain"][0])
              for n, p in params.items()}
    inside = all(p["result"][0] <= p["true"] <= p["result"][1] for p in params.values())
    return ratios, inside


def subset(candidates: Path, rows: list[int], out: Path) -> Path:
    lines = candidates.read_text(encoding="utf-8").splitlines()
    out.write_text("\n".join([lines[0], *(lines[r] for r in rows)]) + "\n", encoding="utf-8")
    return out


def case(seed: int, tmp: Path) -> tuple[str, list[str], bool]:
    cand = tmp / f"cand{seed}.csv"
    calibc("simulate", MODEL, "--configs", CANDIDATES, "--seed", 1000 + seed, "-o", cand)
    start = time.perf_counter()
    done = calibc("plan", MODEL, "--candidates", f"m={cand}", "--n", N, "-D", f"e={BOUND}",
                  "-o", tmp / "plan.csv", "--seed", seed, "--json", tmp / "plan.json")
    seconds = time.perf_counter() - start
    assert done.returncode == 0, done.stderr
    planned, ok = measured(tmp / "plan.csv", 1000 * seed + 50, tmp)
    rng = np.random.default_rng(seed)
    randoms = []
    for k in range(RANDOM_SETS):
        rows = sorted(int(r) + 1 for r in rng.choice(CANDIDATES, N, replace=False))
        got, inside = measured(subset(cand, rows, tmp / f"rand{k}.csv"), 1000 * seed + 60 + k,
                               tmp)
        randoms.append(statistics.median(got.values()))
        ok &= inside
    p, r = statistics.median(planned.values()), statistics.mean(randoms)
    chosen = json.loads((tmp / "plan.json").read_text())["chosen"]
    line = (f"| {seed} | {seconds:.1f} | {chosen} | {p:.4f} | {r:.4f} "
            f"({min(randoms):.4f}-{max(randoms):.4f}) | {p / r:.2f} |")
    sweep, ok_sweep = sweep_lines(seed, cand, tmp)
    return line, sweep, ok and ok_sweep


def sweep_lines(seed: int, cand: Path, tmp: Path) -> tuple[list[str], bool]:
    done = calibc("plan", MODEL, "--candidates", f"m={cand}", "--n", SWEEP, "-D",
                  f"e={BOUND}", "-o", tmp / "swept.csv", "--seed", seed, "--json",
                  tmp / "sweep.json")
    assert done.returncode == 0, done.stderr
    sweep = json.loads((tmp / "sweep.json").read_text())["sweep"]
    out, ok = [], True
    for j, n in enumerate(sweep["counts"]):
        got, inside = measured(subset(cand, sweep["rows"][str(n)], tmp / f"s{n}.csv"),
                               1000 * seed + 100 + n, tmp)
        ok &= inside
        pred = {u: sweep["predicted"][u][j] / sweep["domains"][u] for u in got}
        rel = [pred[u] / got[u] for u in got]
        within = sum(abs(x - 1) <= 0.2 for x in rel)
        out.append(f"| {seed} | {n} | {statistics.median(pred.values()):.4f} | "
                   f"{statistics.median(got.values()):.4f} | {statistics.median(rel):.2f} | "
                   f"{within} of {len(rel)} |")
    return out, ok


def report(seeds: list[int]) -> str:
    m = machine()
    head = [SECTION, "",
            f"{datetime.date.today()}, {m['cpu']} ({m['cores']} cores, load {m['load']} at "
            f"the start: a shared host, times are noisy). `calibc plan "
            f"models/ur10_simulated.cal --candidates m=C --n {N} -D e={BOUND}` on {CANDIDATES}"
            f" candidates drawn by `calibc simulate --seed 1000+S`; each design measured by "
            f"`simulate --at` and `solve` (median width/domain over the 23 unknowns); random: "
            f"the mean of {RANDOM_SETS} random sets of {N}. Goals: {GOALS}.", "",
            "| seed | plan (s) | chosen stage | planned | random (range) | planned / random |",
            "|---:|---:|---|---:|---|---:|"]
    sweep_head = ["", f"Sweep `--n {SWEEP}`: predicted (median over noisy linearized hulls) "
                  "against a simulated solve of the same design, median width/domain; "
                  "predicted / solved per unknown.", "",
                  "| seed | N | predicted | solved | predicted / solved (median) | within 20 % |",
                  "|---:|---:|---:|---:|---:|---|"]
    truth = True
    with tempfile.TemporaryDirectory(prefix="calibc-plan-") as name:
        for seed in seeds:
            line, sweep, ok = case(seed, Path(name))
            print(line, *sweep, sep="\n", flush=True)
            head.append(line)
            sweep_head += sweep
            truth &= ok
    return "\n".join([*head, *sweep_head, "",
                      f"Truth inside every simulated solve: {'yes' if truth else 'NO'}."]) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    section = report([int(s) for s in args.seeds.split(",")])
    write(args.out, section, SECTION)
    print(section)


if __name__ == "__main__":
    main()
