"""The planners' benchmarks in one run: TSP methods side by side, cvxpy versus the closed
form for the power split, and OMPL planners' path lengths at fixed time limits.

    python benchmarks/planners.py            # all three (a few minutes)
    python benchmarks/planners.py tsp        # or one of: tsp, power_split, paths3d

Each part is also a script of its own (``bench_tsp.py``, ``bench_power_split.py``,
``bench_paths3d.py``) that prints its own medians and ratios.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

PARTS = {"tsp": "bench_tsp", "power_split": "bench_power_split", "paths3d": "bench_paths3d"}


def main() -> None:
    chosen = sys.argv[1:] or list(PARTS)
    unknown = [c for c in chosen if c not in PARTS]
    if unknown:
        sys.exit(f"unknown part {unknown[0]!r}: choose from {', '.join(PARTS)}")
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    for part in chosen:
        print(f"=== {part} ===", flush=True)
        module = importlib.import_module(PARTS[part])
        saved, sys.argv = sys.argv, [module.__file__]
        try:
            module.main()
        finally:
            sys.argv = saved
        print(flush=True)


if __name__ == "__main__":
    main()
