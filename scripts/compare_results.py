"""Compare every shipped model's `calibc solve --json` result with a base revision's.

    python scripts/compare_results.py BASE_REV [--only NAME ...] [--code DIR] [--list]
                                      [--added-ok]

A refactoring must leave results bit for bit: each case below is solved by the code of
BASE_REV (extracted with `git archive` into a temporary folder) and by the working tree, on
the working tree's model files, and the two JSON documents must be equal once the fields
that measure time (and the provenance: the command, the date, the machine) are dropped. The
base's results are cached by commit under .cache/compare/, so a second run only solves the
working tree (or the package under --code DIR, e.g. a `git archive` of a commit, while the
tree changes). Cases whose data are absent (the public UR10 set, CALIBC_UR10 or
/work/shared/data/ur10 by default) are skipped with a note. Shaving runs a fixed number of
ends (`--shave N`): by default how many ends it shaves depends on the machine's speed, which
no comparison can hold fixed. With `--added-ok`, a field the working tree writes and the base
did not is printed as added but is no difference (a feature added beside a refactoring).
BASE_REV `auto` is what CI compares against (.ci/run): the merge base with origin/main where
it is not HEAD itself, else HEAD's parent; with neither (a shallow clone without history) the
comparison is skipped with the reason. Exit 0: all equal; 1: some differ (the paths that
differ are printed)."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
from io import BytesIO
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
UR10 = Path(os.environ.get("CALIBC_UR10", "/work/shared/data/ur10"))
REAL = f"m={UR10 / 'measurements_joint_configurations.csv'}"
FAULTY = ROOT / ".cache" / "compare" / "rx90_faulty.csv"
# measured time, what is derived from it, and where and when the command ran
TIMING = {"seconds", "budget", "provenance"}

# name -> arguments of `calibc solve` (model files relative to the repository)
CASES: dict[str, list[str]] = {
    "circle_fit": ["models/examples/circle_fit.cal"],
    "language_tour": ["models/examples/language_tour.cal"],
    "paper_cse": ["models/examples/paper_cse.cal"],
    "paper_propagation": ["models/examples/paper_propagation.cal"],
    "planar_arm": ["models/examples/planar_arm.cal", "--residuals"],
    "planar_arm_hc4": ["models/examples/planar_arm.cal", "--strategy", "hc4"],
    "planar_arm_outliers": ["models/examples/planar_arm.cal", "--outliers", "1"],
    "rx90_full": ["models/rx90_full.cal"],
    "rx90_full_hc4": ["models/rx90_full.cal", "--strategy", "hc4"],
    "rx90_full_shave2": ["models/rx90_full.cal", "--shave", "2"],
    "rx90_lengths": ["models/rx90_lengths.cal", "--lsq"],
    "rx90_lengths_rotation": ["models/rx90_lengths.cal", "--formulation", "rotation"],
    "rx90_recalibrate": ["models/rx90_recalibrate.cal"],
    # a row moved by 1 cm: inconsistent, the row named by the diagnosis, found by --outliers
    "rx90_faulty_diagnose": ["models/rx90_lengths.cal", "--data", str(FAULTY)],
    "rx90_faulty_outliers": ["models/rx90_lengths.cal", "--data", str(FAULTY),
                             "--outliers", "1"],
    "ur10_all": ["models/ur10_all.cal"],
    "ur10_simulated": ["models/ur10_simulated.cal"],
    "ur10_tracker": ["models/ur10_tracker.cal", "--residuals"],
    "ur10_tracker_outliers": ["models/ur10_tracker.cal", "--outliers", "1",
                              "--rows", "1..100:4"],
    "ur10_tracker_diagnose": ["models/ur10_tracker.cal", "-D", "e=0.02", "--rows", "1..100:5"],
    "ur10_tracker_real": ["models/ur10_tracker.cal", "--data", REAL, "-D", "e=1.2",
                          "--rows", "1..1495:15"],
    "ur10_tracker6d_real": ["models/ur10_tracker6d.cal", "--data", REAL,
                            "--rows", "1..1495:30"],
    "ur5_simulated": ["models/ur5_simulated.cal"],
    "ur5_tracker": ["models/ur5_tracker.cal", "--residuals"],
}


def faulty() -> None:
    """RX90's data with row 17's a1x moved by 1 cm (the path is fixed: the JSON names it)."""
    lines = (ROOT / "models" / "data" / "rx90_50.csv").read_text().splitlines()
    j = lines[0].split(",").index("a1x")
    cells = lines[17].split(",")
    cells[j] = repr(float(cells[j]) + 0.01)
    lines[17] = ",".join(cells)
    FAULTY.parent.mkdir(parents=True, exist_ok=True)
    FAULTY.write_text("\n".join(lines) + "\n")


NEEDS_UR10 = {"ur10_tracker_real", "ur10_tracker6d_real"}


def strip(doc: object) -> object:
    if isinstance(doc, dict):
        return {k: strip(v) for k, v in doc.items() if k not in TIMING}
    if isinstance(doc, list):
        return [strip(v) for v in doc]
    return doc


def solve(code: Path, args: list[str]) -> dict:
    """One case's JSON (minus timing) solved by the package at `code`; the exit code too."""
    start = (f"import sys; sys.path.insert(0, {str(code)!r}); "
             "from calib_dsl.cli import main; main()")
    shave = [] if "--shave" in args else ["--shave", "0"]
    cmd = [sys.executable, "-c", start, "solve", "-q", *shave, "--json", "-", *args]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    run = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    doc = json.loads(run.stdout) if run.stdout.strip().startswith("{") else None
    return {"exit": run.returncode, "json": strip(doc), "stderr": run.stderr[-400:]
            if run.returncode not in (0, 1, 4) else ""}


def extract(rev: str, into: Path) -> str:
    sha = subprocess.run(["git", "rev-parse", rev], cwd=ROOT, check=True,
                         capture_output=True, text=True).stdout.strip()
    blob = subprocess.run(["git", "archive", sha, "calib_dsl", "grammars"], cwd=ROOT,
                          check=True, capture_output=True).stdout
    with tarfile.open(fileobj=BytesIO(blob)) as tar:
        tar.extractall(into, filter="data")
    return sha


def differences(a: object, b: object, path: str = "",
                added: list[str] | None = None) -> list[str]:
    """Where the base's `a` and the tree's `b` differ; with `added` (a list), the fields only
    `b` has go there instead (added since the base)."""
    if isinstance(a, dict) and isinstance(b, dict):
        new = set(b) - set(a) if added is not None else set()
        out = [f"{path}.{k}: only in one" for k in sorted((set(a) ^ set(b)) - new)]
        if added is not None:
            added += [f"{path}.{k}" for k in sorted(new)]
        for k in sorted(set(a) & set(b)):
            out += differences(a[k], b[k], f"{path}.{k}", added)
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        pairs = enumerate(zip(a, b, strict=True))
        return [d for i, (x, y) in pairs for d in differences(x, y, f"{path}[{i}]", added)]
    return [] if a == b else [f"{path}: {json.dumps(a)[:80]} != {json.dumps(b)[:80]}"]


def git(*args: str) -> str | None:
    run = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)
    return run.stdout.strip() if run.returncode == 0 else None


def auto_base() -> tuple[str | None, str]:
    """CI's base: the merge base with origin/main where it is not HEAD, else HEAD's parent;
    (None, why) where the checkout has neither."""
    head = git("rev-parse", "HEAD")
    if head is None:
        return None, "not a git checkout"
    merge = git("merge-base", "HEAD", "origin/main") if git(
        "rev-parse", "--verify", "-q", "origin/main") else None
    if merge and merge != head:
        return merge, f"the merge base with origin/main ({merge[:12]})"
    parent = git("rev-parse", "--verify", "-q", "HEAD~1")
    if parent:
        return parent, f"HEAD's parent ({parent[:12]})"
    return None, "the checkout has no history (a shallow clone?): no base revision"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("base", help="the revision to compare against (e.g. main; auto: CI's)")
    ap.add_argument("--only", nargs="*", help="these cases only")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    ap.add_argument("--code", type=Path, default=ROOT,
                    help="the folder holding the calib_dsl to compare (default: this tree)")
    ap.add_argument("--added-ok", action="store_true",
                    help="fields only the tree writes are printed as added, not differences")
    opts = ap.parse_args()
    if opts.list:
        print("\n".join(f"{n}: {' '.join(a)}" for n, a in CASES.items()))
        return 0
    if opts.base == "auto":
        opts.base, why = auto_base()
        print(f"compare_results: base {why}" if opts.base else f"compare_results: skipped "
              f"({why})")
        if opts.base is None:
            return 0
    names = opts.only or list(CASES)
    faulty()
    failed = 0
    with tempfile.TemporaryDirectory() as tmp:
        sha = extract(opts.base, Path(tmp))
        cache = ROOT / ".cache" / "compare" / sha
        cache.mkdir(parents=True, exist_ok=True)
        for name in names:
            if name in NEEDS_UR10 and not UR10.is_dir():
                print(f"{name}: skipped (the UR10 data are not at {UR10}; set CALIBC_UR10)")
                continue
            saved = cache / f"{name}.json"
            if not saved.exists():
                saved.write_text(json.dumps(solve(Path(tmp), CASES[name]), indent=1))
            base = json.loads(saved.read_text())
            mine = solve(opts.code.resolve(), CASES[name])
            added: list[str] | None = [] if opts.added_ok else None
            diff = differences(base, mine, "", added)
            failed += bool(diff)
            print(f"{name}: {'DIFFERS' if diff else 'same'} (exit {mine['exit']})")
            for line in diff[:12]:
                print("   ", line)
            for line in (added or [])[:12]:
                print("    added:", line)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
