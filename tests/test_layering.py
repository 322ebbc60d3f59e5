"""The architecture (docs/architecture.md), enforced by reading every module's imports.

Bottom to top: the ``swiptopt`` model modules -> ``rl`` and ``planners`` ->
``swiptopt.benchmark`` and ``swiptopt.cli``. A module may import its own layer and the layers
below it, never above; ``rl`` and ``planners`` never import each other. Imports inside
functions count too: a lazy import upward is still an upward dependency.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TOP = ("swiptopt.benchmark", "swiptopt.cli")


def _layer(module: str) -> str:
    if module.startswith(TOP):
        return "benchmark"
    for package in ("rl", "planners", "swiptopt"):
        if module == package or module.startswith(package + "."):
            return "model" if package == "swiptopt" else package
    return "external"


#: What each layer may import (besides external packages and itself).
ALLOWED = {
    "model": {"model"},
    "rl": {"model", "rl"},
    "planners": {"model", "planners"},
    "benchmark": {"model", "rl", "planners", "benchmark"},
}


def _modules() -> list[tuple[str, Path]]:
    out = []
    for package in ("swiptopt", "rl", "planners"):
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            out.append((name, path))
    return out


def _imports(module: str, path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolve against the module's package
                base = module.split(".")
                is_package = path.name == "__init__.py"
                base = base if is_package else base[:-1]
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            found.append((node.lineno, target))
            # "from swiptopt import benchmark" imports the submodule benchmark
            found += [(node.lineno, f"{target}.{a.name}") for a in node.names if f"{target}.{a.name}".startswith(TOP)]
    return found


def test_the_layering_holds():
    modules = _modules()
    assert len(modules) > 20, "the scan found too few modules: is the tree where the test expects it?"
    violations = []
    for module, path in modules:
        mine = _layer(module)
        for line, target in _imports(module, path):
            theirs = _layer(target)
            if theirs != "external" and theirs not in ALLOWED[mine]:
                violations.append(f"{path.relative_to(ROOT)}:{line} ({mine}) imports {target} ({theirs})")
    assert not violations, "imports against the layering:\n" + "\n".join(violations)


def test_the_checker_sees_a_violation(tmp_path):
    # the rule must be able to fail: an upward import in a model module is reported
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from planners.tsp import solve_tsp\n    from swiptopt import benchmark\n")
    targets = [t for _, t in _imports("swiptopt.bad", bad)]
    assert "planners.tsp" in targets and "swiptopt.benchmark" in targets
    assert {_layer(t) for t in targets} - ALLOWED["model"] == {"planners", "benchmark"}


#: Solver and plotting packages that must load only when a function needs them.
HEAVY = ("cvxpy", "ortools", "ompl", "sklearn", "highspy", "dask", "distributed", "matplotlib", "numba", "torch",
         "stable_baselines3", "pandas", "scipy")


@pytest.mark.parametrize("statement", ["import swiptopt", "import planners", "import rl",
                                       "from planners import *", "import swiptopt.benchmark"])
def test_imports_stay_light(statement):
    code = f"import sys; {statement}; print(sorted(m for m in {HEAVY!r} if m in sys.modules))"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]", f"{statement} loads {result.stdout.strip()}"
    assert result.stderr == ""


def test_flat_planners_api():
    import planners

    for name in ("solve_tsp", "plan_path_3d", "kmeans_hover_points", "optimise_dwell_and_split",
                 "optimal_split_ratio", "upper_bound", "exact_optimum", "KMeansTspPlanner", "LawnmowerPlanner",
                 "GreedyPlanner", "TspResult", "PathResult", "HoverPoints", "PowerSplitResult"):
        assert name in planners.__all__ and callable(getattr(planners, name))
    assert sorted(planners.__all__) == planners.__all__
