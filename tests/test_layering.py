"""The package's layering: each stage imports only itself and lower layers, no module imports
another's private name, there are no import cycles, and no module grows past the size a
reader can hold. Read from the source (every import, late ones too), so it fails the moment
a change breaks the rule."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "calib_dsl"

# lowest first; a module may import from its own package and from lower ranks only. A
# feature's package spans layers where its parts do (the outliers' solve drives the tight
# strategy, which the rows at fault are below): such a module has a rank of its own
# ("package.module"), and its package's other modules may not import it.
RANKS = {
    "settings": 0, "arith": 0, "frontend": 0, "progress": 0,
    "settings_analysis": -1,  # settings.py's groups for analysis/, which settings.py imports
    "settings_strategy": -1,  # settings.py's group for the loose split, likewise
    "ir": 1,
    "elaborate": 2, "compile": 2,
    "propagate": 3,
    "relax": 4,
    "lp": 5,
    "analysis": 6,  # what the solver relies on: least squares, fits, point proofs, rank
    "inner": 7,  # certified inner bounds: their LPs and warm starts
    "outliers": 7,  # the rows at fault: ranked, named, dropped from relaxations
    "studies": 7,  # what a user asks beside a solve: simulation, advice, frames, a yardstick
    "strategy": 8,
    "inner.shave": 9,  # contracts a solution's ends towards its inner bounds
    "outliers.solve": 9, "outliers.proof": 9,  # solves with outliers: tight solves of subsets
    "outliers.at_fault": 9,  # a verdict's proof against a row at fault: a tight solve
    "accuracy": 9,  # the accuracy statement and predictions: over the strategy, beside a solve
    "report": 10, "plot": 10,
    "sections": 11,  # the report's optional sections, computed (the report only renders)
    "problem": 11,  # a model loaded once, and the programs of other inputs it gives
    "handover": 11,  # the handover report: renders the JSON documents
    "pipeline": 12,
    "batch": 13,  # many solves on Dask: the pipeline's calls, one job each
    "api": 13,  # beside batch: neither imports the other
    "outputs": 13,  # the figures, residuals and exports the command line writes
    "plan": 13,  # planning a campaign (calibc plan, simulate --at): simulated solves
    "cli": 14,
    "__main__": 15,  # `python -m calib_dsl`: the command line
}
MAX_LINES = 450  # "no module over ~400 lines"


def modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def imports(path: Path, name: str) -> list[tuple[str, list[str], int]]:
    """(imported module, names imported from it, line) for every import in the file."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(a.name, [], node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")
                base = ".".join(up[:len(up) - node.level + 1] + ([base] if base else []))
            found.append((base, [a.name for a in node.names], node.lineno))
    return [f for f in found if f[0] == "calib_dsl" or f[0].startswith("calib_dsl.")]


def stage(module: str) -> str:
    """The unit a module's rank belongs to: its own "package.module" entry, else its package."""
    parts = module.split(".")
    if len(parts) > 2 and ".".join(parts[1:3]) in RANKS:
        return ".".join(parts[1:3])
    return parts[1] if len(parts) > 1 else ""


ALL = modules()


@pytest.mark.parametrize("name", sorted(n for n in ALL if stage(n)))
def test_imports_only_lower_layers(name):
    mine = stage(name)
    assert mine in RANKS, f"{name}: a new stage must be given its rank in RANKS"
    for target, names, line in imports(ALL[name], name):
        targets = [target] + [f"{target}.{n}" for n in names if f"{target}.{n}" in ALL]
        for t in targets:
            other = stage(t)
            if not other or other == mine:
                continue
            assert RANKS[other] < RANKS[mine], (
                f"{ALL[name].relative_to(PACKAGE.parent)}:{line}: {mine} (rank {RANKS[mine]}) "
                f"imports {t} (rank {RANKS[other]}): only lower layers may be imported")


@pytest.mark.parametrize("name", sorted(ALL))
def test_no_private_names_from_other_modules(name):
    for target, names, line in imports(ALL[name], name):
        if target == name:
            continue
        private = [n for n in names if n.startswith("_") and f"{target}.{n}" not in ALL]
        assert not private, (f"{ALL[name].relative_to(PACKAGE.parent)}:{line}: imports the "
                             f"private {private} of {target}")


def test_no_import_cycles():
    graph = {n: set() for n in ALL}
    for name, path in ALL.items():
        for target, names, _ in imports(path, name):
            for t in [target] + [f"{target}.{n}" for n in names]:
                if t in ALL and t != name and not ALL[t].name == "__init__.py":
                    graph[name].add(t)
    done: set[str] = set()

    def visit(node: str, path: list[str]) -> None:
        if node in path:
            cycle = path[path.index(node):] + [node]
            pytest.fail("import cycle: " + " -> ".join(cycle))
        if node in done:
            return
        for nxt in sorted(graph[node]):
            visit(nxt, path + [node])
        done.add(node)

    for n in sorted(graph):
        visit(n, [])


@pytest.mark.parametrize("name", sorted(ALL))
def test_modules_stay_small(name):
    lines = len(ALL[name].read_text(encoding="utf-8").splitlines())
    assert lines <= MAX_LINES, f"{name}: {lines} lines (split it: one job per module)"


def test_the_check_sees_a_violation(tmp_path):
    """The checker itself: a lower layer importing a higher one, and a private import, are
    found (so the tests above cannot pass by reading nothing)."""
    bad = tmp_path / "calib_dsl" / "arith"
    bad.mkdir(parents=True)
    (bad / "x.py").write_text("from calib_dsl.strategy.tight import _secret\n")
    found = imports(bad / "x.py", "calib_dsl.arith.x")
    assert found == [("calib_dsl.strategy.tight", ["_secret"], 1)]
    assert RANKS[stage(found[0][0])] > RANKS["arith"]
    assert len(ALL) > 30 and any(imports(p, n) for n, p in ALL.items())
