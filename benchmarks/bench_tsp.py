"""Tour length and solve time of each TSP method side by side, on TSPLIB and random instances.

For every instance: CP-SAT (``method="exact"``), OR-Tools routing (``"routing"``) and the
default (``"auto"``), each on its deterministic budget (``--deterministic-time`` CP-SAT
seconds, ``--solution-limit`` routing solutions; the defaults of ``solve_tsp`` unless
given), all in this one process, one after the other. The lengths do not depend on the
machine; the times do (the machine is printed first). The gap is to the reference length:
TSPLIB's proven optimum (EUC_2D, nint distances), or, for random instances, a proven optimum
when a method found one ("-" when nothing is known). A status other than optimal or
feasible (``time_limit``: the wall-clock safety net stopped a search) is shown after the
time. A few minutes with the defaults. Usage:

    python benchmarks/bench_tsp.py [--deterministic-time 1.0] [--solution-limit 100] [--seed 0]
"""

from __future__ import annotations

import sys
from pathlib import Path

# keep this folder off the path: the planners package must not be shadowed by a script here
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import argparse
import importlib.util
import json

import numpy as np

from planners.tsp import TspResult, solve_tsp

HERE = Path(__file__).resolve().parent

TSPLIB_FILE = Path(__file__).resolve().parents[1] / "tests" / "planners" / "data" / "tsplib_instances.json"
TSPLIB_NAMES = ("eil51", "berlin52", "st70", "eil76", "kroA100")
RANDOM_SIZES = (15, 50, 100)
RANDOM_SIDE_M = 1000.0
METHODS = ("exact", "routing", "auto")


def euclidean_matrix(points: np.ndarray) -> np.ndarray:
    """(n, n) Euclidean distances between the rows of ``points`` (n, d)."""
    return np.linalg.norm(points[:, None, :] - points[None, :, :], axis=-1)


def instances(seed: int) -> list[tuple[str, np.ndarray, float | None]]:
    """(name, distance matrix, best-known length or None), TSPLIB first."""
    with TSPLIB_FILE.open() as f:
        tsplib = {inst["name"]: inst for inst in json.load(f)["instances"]}
    found = []
    for name in TSPLIB_NAMES:
        coords = np.asarray(tsplib[name]["coords"], dtype=float)
        # TSPLIB EUC_2D: Euclidean distance rounded to the nearest integer.
        found.append((name, np.floor(euclidean_matrix(coords) + 0.5), float(tsplib[name]["best_known"])))
    rng = np.random.default_rng(seed)
    for n in RANDOM_SIZES:
        points = rng.uniform(0.0, RANDOM_SIDE_M, (n, 2))
        found.append((f"random{n}", euclidean_matrix(points), None))
    return found


def cell(result: TspResult, reference: float | None) -> str:
    """'length  time  gap' for one method on one instance."""
    if not result.order:
        return f"{'no solution':>11}{result.solve_time_s:6.2f}s {'':>7}"
    if result.status == "time_limit":
        return f"{result.length:10.1f}!{result.solve_time_s:6.2f}s {'clock':>7}"
    if reference:
        # Integer cost scaling lets a tour beat a "proven" CP-SAT optimum by ~1e-6 relative;
        # show that as 0.00 %, not -0.00 %.
        gap_pct = 100 * (result.length / reference - 1)
        gap = f"{0.0 if abs(gap_pct) < 0.005 else gap_pct:6.2f}%"
    else:
        gap = f"{'-':>7}"
    proof = "*" if result.proven_optimal else " "
    return f"{result.length:10.1f}{proof}{result.solve_time_s:6.2f}s {gap}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--deterministic-time", type=float, default=None, help="CP-SAT budget, deterministic s")
    parser.add_argument("--solution-limit", type=int, default=None, help="routing budget, solutions")
    parser.add_argument("--seed", type=int, default=0, help="seed of the random instances")
    args = parser.parse_args()
    budgets = {"deterministic_time": args.deterministic_time, "solution_limit": args.solution_limit}

    spec = importlib.util.spec_from_file_location("machine", HERE / "machine.py")
    machine = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(machine)
    print(machine.describe())
    solve_tsp(np.ones((5, 5)), method="exact")  # load OR-Tools before timing anything
    print(f"{'instance':<10} {'n':>4} {'best known':>10}   " + "   ".join(f"{m:<26}" for m in METHODS))
    print(f"{'':<10} {'':>4} {'':>10}   " + "   ".join(f"{'length':>10} {'time':>7} {'gap':>7}" for _ in METHODS))
    for name, matrix, best_known in instances(args.seed):
        results = [solve_tsp(matrix, method=m, **budgets) for m in METHODS]
        proven = [r.length for r in results if r.proven_optimal]
        reference = best_known if best_known is not None else (proven[0] if proven else None)
        known = f"{best_known:10.0f}" if best_known is not None else f"{'-':>10}"
        row = "   ".join(cell(r, reference) for r in results)
        print(f"{name:<10} {len(matrix):>4} {known}   {row}", flush=True)
    print("* proven optimal; ! stopped by the wall-clock safety net. Gap to the best known length (TSPLIB), "
          "else to a proven optimum.")


if __name__ == "__main__":
    main()
