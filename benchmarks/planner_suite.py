"""The planners' benchmarks in one run: TSP methods side by side, cvxpy versus the closed
form for the power split, and OMPL planners' path lengths at fixed time limits.

    python benchmarks/planner_suite.py            # all three (a few minutes)
    python benchmarks/planner_suite.py tsp        # or one of: tsp, power_split, paths3d

Each part is also a script of its own (``bench_tsp.py``, ``bench_power_split.py``,
``bench_paths3d.py``) that prints its own medians and ratios.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
# this file's name would shadow the planners package: keep its folder off the path
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != HERE]

PARTS = {"tsp": "bench_tsp", "power_split": "bench_power_split", "paths3d": "bench_paths3d"}


def main() -> None:
    chosen = sys.argv[1:] or list(PARTS)
    unknown = [c for c in chosen if c not in PARTS]
    if unknown:
        sys.exit(f"unknown part {unknown[0]!r}: choose from {', '.join(PARTS)}")
    for part in chosen:
        print(f"=== {part} ===", flush=True)
        spec = importlib.util.spec_from_file_location(PARTS[part], HERE / f"{PARTS[part]}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        saved, sys.argv = sys.argv, [module.__file__]
        try:
            module.main()
        finally:
            sys.argv = saved
        print(flush=True)


if __name__ == "__main__":
    main()
