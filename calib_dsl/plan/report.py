"""What `calibc plan` prints and writes: a plan's table, a sweep's, their JSON, the figure
of widths against N."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from calib_dsl.plan.planner import Plan, Sweep


def render_plan(p: Plan) -> str:
    lines = [f"planned {len(p.rows)} of the candidates in {p.seconds:.1f} s (chosen: "
             f"{p.chosen})", "", f"{'unknown':<12} {'domain':>11} {'predicted':>11} "
             f"{'ratio':>7}"]
    for n, d, w in zip(p.names, p.domain, p.predicted, strict=True):
        lines.append(f"{n:<12} {d:>11.4g} {w:>11.4g} {w / d:>7.3f}")
    lines.append(f"median predicted width / domain: "
                 f"{float(np.median(p.predicted / p.domain)):.4f}")
    lines += ["", "stage        LP score  simulated solve: median width/domain, truth inside"]
    for s in p.stages:
        got = p.solved.get(s.name)
        solved = ("not a finalist" if s.name not in p.solved else "inconsistent" if got is None
                  else f"{got.median_ratio:.4f}, {'yes' if got.truth_inside else 'NO'}")
        lines.append(f"{s.name:<12} {s.score:>8.4f}  {solved}")
    return "\n".join(lines)


def plan_json(p: Plan) -> dict[str, Any]:
    return {
        "rows": [int(r) + 1 for r in p.rows],  # data row numbers, 1: the first after the header
        "chosen": p.chosen, "seconds": p.seconds,
        "unknowns": {n: {"domain": float(d), "predicted": float(w)}
                     for n, d, w in zip(p.names, p.domain, p.predicted, strict=True)},
        "stages": [{"name": s.name, "score": s.score, "seconds": s.seconds,
                    "rows": [int(r) + 1 for r in np.sort(s.rows)],
                    "solved": _solved_json(p, s.name)} for s in p.stages],
    }


def _solved_json(p: Plan, name: str) -> dict[str, Any] | None:
    got = p.solved.get(name)
    if got is None:
        return None
    return {"widths": dict(zip(got.names, got.width.tolist(), strict=True)),
            "median_ratio": got.median_ratio, "truth_inside": got.truth_inside,
            "score": got.score}


def render_sweep(s: Sweep) -> str:
    shown = list(s.targets) or s.names
    head = f"{'N':>5} {'median w/d':>10} " + " ".join(f"{n:>10}" for n in shown)
    lines = ["predicted guaranteed widths (median over simulated draws)", head]
    domain = s.plans[0].domain
    for n, w in zip(s.counts, s.widths, strict=True):
        cells = " ".join(f"{w[s.names.index(t)]:>10.4g}" for t in shown)
        lines.append(f"{n:>5} {float(np.median(w / domain)):>10.4f} {cells}")
    if s.targets:
        goal = ", ".join(f"{t} <= {v:g}" for t, v in s.targets.items())
        lines.append(f"smallest N meeting every target ({goal}): "
                     f"{s.enough if s.enough is not None else f'none up to {s.counts[-1]}'}")
    return "\n".join(lines)


def sweep_json(s: Sweep) -> dict[str, Any]:
    return {"counts": s.counts, "targets": s.targets, "enough": s.enough,
            "domains": dict(zip(s.names, s.plans[0].domain.tolist(), strict=True)),
            "predicted": {n: s.widths[:, j].tolist() for j, n in enumerate(s.names)},
            "rows": {str(n): [int(r) + 1 for r in p.rows]
                     for n, p in zip(s.counts, s.plans, strict=True)}}


def draw_sweep(s: Sweep, path: str | Path) -> None:
    """Each unknown's predicted width over its domain against N (targets dashed)."""
    from calib_dsl.plot.backend import new_figure, save

    fig = new_figure(7.0, 4.5)
    ax = fig.add_subplot()
    domain = s.plans[0].domain
    for j, n in enumerate(s.names):
        ax.plot(s.counts, s.widths[:, j] / domain[j], marker=".", lw=1,
                label=n if n in s.targets or len(s.names) <= 10 else None)
    for t, v in s.targets.items():
        ax.axhline(v / domain[s.names.index(t)], ls="--", lw=0.8, color="k")
    if s.enough is not None:
        ax.axvline(s.enough, ls=":", color="k")
    ax.set_yscale("log")
    ax.set_xlabel("configurations measured (N)")
    ax.set_ylabel("predicted guaranteed width / domain")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, ncol=2)
    save(fig, path)
