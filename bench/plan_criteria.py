"""Planning criteria in expectation over the noise (docs/decisions/32-planning-floor.md):
what a design of 30 of the UR10's candidates can gain over random ones, measured on the
noisy linearized hull (the width a solve gives to first order, docs/planning.md).

For each candidate set (`calibc simulate --configs 3000 --seed 1000+S`, as bench/plan.py),
with `settings.plan_draws`-like draws of the noise shared by every design (common random
numbers: each candidate row keeps its draw), the expected median width/domain over the 23
unknowns (the median over the unknowns of each one's mean over the draws) of

- the stages' designs (`calib_dsl.plan.choose.stages`) and 5 random sets of 30;
- an exchange on the noisy criterion itself (mean log expected width, a few draws of its
  own), then measured on the shared draws: what the criterion gains beyond its own draws;
- for each unknown asked, a design exchanged for that unknown's expected width alone: the
  least expected width any design was found to give it (a median <= T needs 12 of the 23
  unknowns at <= T each);
- random sets of larger N: how many random poses the planned 30 are worth.

    python bench/plan_criteria.py [--seeds 1,2,3] [--unknowns base_x,d3] [--budget 120]
        [--start variances|random] [--tries 4] [--larger 36,43,50]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))
from run import calibc_command  # noqa: E402

from calib_dsl import plan as api  # noqa: E402
from calib_dsl.lp.hull import linear_hull  # noqa: E402
from calib_dsl.plan.choose import stages  # noqa: E402
from calib_dsl.plan.planner import linear  # noqa: E402
from calib_dsl.plan.refine import rows_of  # noqa: E402
from calib_dsl.settings import DEFAULT  # noqa: E402

MODEL = ROOT / "models" / "ur10_simulated.cal"
CANDIDATES, N, RANDOM_SETS, DRAWS = 3000, 30, 5, 20
OWN_DRAWS, FRESH_DRAWS = 24, 40


class Case:
    """One candidate set linearized: rows (configurations, rows each, unknowns) in domain
    and bound units, the box, the shared draws (draws, configurations, rows each)."""

    def __init__(self, seed: int, tmp: Path) -> None:
        cand = tmp / f"cand{seed}.csv"
        subprocess.run([*calibc_command(), "simulate", str(MODEL), "--configs",
                        str(CANDIDATES), "--seed", str(1000 + seed), "-o", str(cand), "-q"],
                       check=True)
        problem = api.problem_of(MODEL, {"e": 0.5}, seed, "matrix", None)
        lin, _ = linear(problem, api._pool(problem, cand, "m"), None)
        self.seed, self.names, self.blocks, self.box = seed, lin.names, lin.blocks, lin.box
        self.draws = self.noise(DRAWS, 7, len(lin.blocks))
        self.stages = stages(lin, N, DEFAULT)

    def noise(self, draws: int, stream: int, rows: int) -> np.ndarray:
        rng = np.random.default_rng([self.seed, stream])
        return rng.uniform(-1.0, 1.0, (draws, rows, self.blocks.shape[1]))

    def ratios(self, rows: np.ndarray, draws: np.ndarray, columns: list[int] | None = None,
               by_slot: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Width/domain (draws, columns), the hulls' extreme points and row weights summed;
        `by_slot`: the draws follow the design's members, not the candidates."""
        a = rows_of(self.blocks, rows, None)
        cols = list(range(len(self.names))) if columns is None else columns
        out, points, weight = [], [], np.zeros(len(a))
        for n in draws:
            shift = (n[: len(rows)] if by_slot else n[np.asarray(rows)]).reshape(-1)
            h = linear_hull(a, -1.0 - shift, 1.0 - shift, self.box[0], self.box[1], cols)
            span = self.box[1][cols] - self.box[0][cols]
            out.append((h.hi - h.lo) / span)
            points.append(h.points)
            weight += h.weight
        return np.array(out), np.vstack(points), weight


def expected(r: np.ndarray) -> float:
    """The median over the unknowns of each one's mean over the draws."""
    return float(np.median(r.mean(axis=0)))


def exchange(case: Case, start: np.ndarray, draws: np.ndarray, columns: list[int] | None,
             budget: int, tries: int = 4) -> np.ndarray:
    """Swap members (least multiplier over the draws' hulls) for candidates (most expected
    cut at their extreme points) while the mean log expected width falls."""
    chosen, r = np.array(start), case.blocks.shape[1]

    def value(rows: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        got, pts, w = case.ratios(rows, draws, columns, by_slot=True)
        return float(np.mean(np.log(np.maximum(got.mean(axis=0), 1e-6)))), pts, w

    best, points, weight = value(chosen)
    spent = 1
    while spent < budget:
        leave = np.argsort(weight[: len(chosen) * r].reshape(len(chosen), r).sum(axis=1),
                           kind="stable")[:tries]
        cut = expected_cut(case.blocks, points)
        cut[chosen] = -np.inf
        join = np.argsort(-cut, kind="stable")[:tries]
        trials = [(i, c) for i in leave for c in join][: budget - spent]
        for i, c in trials:
            trial = chosen.copy()
            trial[i] = c
            s, p, w = value(trial)
            spent += 1
            if s < best - 1e-6:
                chosen, best, points, weight = trial, s, p, w
                break
        else:
            break
    return chosen


def expected_cut(blocks: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Per candidate, the excess of |a u + noise| over 1 at the points, in expectation over
    a uniform noise (v^2 / 4 for v = |a u| <= 2)."""
    v = np.abs(np.einsum("crn,kn->crk", blocks, points, optimize=True))
    return np.where(v <= 2.0, v * v / 4.0, v - 1.0).sum(axis=(1, 2))


def study(case: Case, unknowns: list[str], budget: int, larger: list[int],
          alone: tuple[str, int]) -> None:
    """`alone`: where each unknown's own exchange starts ("variances", or "random": a
    random set) and how many members and candidates it pairs per round."""
    rng = np.random.default_rng(case.seed)
    rand = [case.ratios(rng.choice(len(case.blocks), N, replace=False), case.draws)[0]
            for _ in range(RANDOM_SETS)]
    base = float(np.mean([expected(r) for r in rand]))
    print(f"\nseed {case.seed}: random sets of {N}: expected median width/domain {base:.4f}"
          f" (goal 0.7 of it: {0.7 * base:.4f})")
    designs = {s.name: case.ratios(s.rows, case.draws)[0] for s in case.stages}
    start = next(s.rows for s in case.stages if s.name == "variances")
    own = case.noise(OWN_DRAWS // 4, 99, N)
    designs["noisy exchange"] = case.ratios(exchange(case, start, own, None, budget),
                                            case.draws)[0]
    print("| design | expected median | / random |\n|---|---:|---:|")
    for name, r in designs.items():
        print(f"| {name} | {expected(r):.4f} | {expected(r) / base:.3f} |")
    mean_random = np.mean([r.mean(axis=0) for r in rand], axis=0)
    fresh = case.noise(FRESH_DRAWS, 321, len(case.blocks))
    own_start = start if alone[0] == "variances" else np.random.default_rng(
        [case.seed, 77]).choice(len(case.blocks), N, replace=False)
    print("| unknown | random | variances | own design | own / random median |\n"
          "|---|---:|---:|---:|---:|")
    for name in unknowns:
        k = case.names.index(name)
        mine = exchange(case, own_start, case.noise(OWN_DRAWS, 123, N), [k], budget,
                        alone[1])
        was = case.ratios(start, fresh, [k])[0].mean()
        got = case.ratios(mine, fresh, [k])[0].mean()
        print(f"| {name} | {mean_random[k]:.4f} | {was:.4f} | {got:.4f} | {got / base:.3f} |",
              flush=True)
    for n in larger:
        r = [expected(case.ratios(rng.choice(len(case.blocks), n, replace=False),
                                  case.draws)[0]) for _ in range(RANDOM_SETS)]
        print(f"random sets of {n}: expected median {np.mean(r):.4f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--unknowns", default="", help="names, comma-separated (default: all)")
    ap.add_argument("--budget", type=int, default=120, help="noisy hulls per exchange")
    ap.add_argument("--larger", default="36,43,50", help="random set sizes to compare")
    ap.add_argument("--start", choices=("variances", "random"), default="variances",
                    help="where each unknown's own exchange starts")
    ap.add_argument("--tries", type=int, default=4, help="its members x candidates a round")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="calibc-criteria-") as name:
        for seed in (int(s) for s in args.seeds.split(",")):
            case = Case(seed, Path(name))
            asked = args.unknowns.split(",") if args.unknowns else case.names
            study(case, asked, args.budget, [int(n) for n in args.larger.split(",") if n],
                  (args.start, args.tries))


if __name__ == "__main__":
    main()
