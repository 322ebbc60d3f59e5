"""The optimum as the reference: the MILP's bound and best walk against the baselines.

On the deterministic paper preset (``channel = "none"``, no link failures), for each number
of nodes and layout, side by side:

- ``UB``: the old bound (:func:`planners.upper_bound`: every node fully served, no travel);
- ``LP``: the MILP's linear relaxation (after its cut rounds) and the time it took;
- the MILP at two named budgets, ``compare`` (about 10 s of one core at 25 nodes) and
  ``default`` (about a minute): its best return, proven bound, gap, branch-and-bound nodes,
  and the CPU and wall time it took (the budgets are deterministic; the times are not);
- each baseline's return (k-means + TSP, greedy, lawnmower, rate-greedy) and its gap to the
  tightest bound found for the layout.

Usage (about 20 minutes with the defaults on one free core):

    python benchmarks/optimum.py [--nodes 10,25,50] [--layouts 0,1,2] [--budgets compare,default]
"""

from __future__ import annotations

import sys
from pathlib import Path

# keep this folder off the path: the planners package must not be shadowed by a script here
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import argparse
import time

from planners import (
    BUDGETS,
    GreedyPlanner,
    KMeansTspPlanner,
    LawnmowerPlanner,
    RateGreedyPlanner,
    solve_optimum,
    upper_bound,
)
from swiptopt import Scenario, evaluate
from swiptopt.env import AuvSwiptEnv

DETERMINISTIC = {"channel": "none", "failure_prob_min": 0.0, "failure_prob_max": 0.0}
BASELINES = {
    "kmeans_tsp": lambda: KMeansTspPlanner(tsp_time_limit_s=1.0),
    "greedy": GreedyPlanner,
    "lawnmower": LawnmowerPlanner,
    "rate_greedy": RateGreedyPlanner,
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", default="10,25,50", help="node counts, comma-separated")
    parser.add_argument("--layouts", default="0,1,2", help="layout seeds, comma-separated")
    parser.add_argument("--budgets", default="compare,default", help=f"MILP budgets from {', '.join(BUDGETS)}")
    args = parser.parse_args()
    nodes = [int(n) for n in args.nodes.split(",")]
    layouts = [int(k) for k in args.layouts.split(",")]
    budgets = args.budgets.split(",")
    unknown = [b for b in budgets if b not in BUDGETS]
    if unknown:
        sys.exit(f"unknown budget {unknown[0]!r}: choose from {', '.join(BUDGETS)}")

    for b in budgets:
        print(f"budget {b}: {BUDGETS[b]}")
    milp_head = "".join(f" | {b + ': best':>13} {'bound':>7} {'gap':>6} {'nodes':>5} {'cpu':>5} {'wall':>5}" for b in budgets)
    base_head = "".join(f" | {name:>11} {'gap':>6}" for name in BASELINES)
    print(f"\n{'N':>3} {'lay':>3} {'UB':>7} | {'LP':>7} {'time':>5}{milp_head}{base_head}")
    for n in nodes:
        for layout in layouts:
            scenario = Scenario.preset("paper", n_nodes=n, layout_seed=layout, **DETERMINISTIC)
            env = AuvSwiptEnv(scenario)
            old = upper_bound(scenario).return_
            results = {}
            for b in budgets:
                started = time.process_time()
                result = solve_optimum(scenario, budget=b, tables=env.tables)
                results[b] = (result, time.process_time() - started)
            bounds = [r.bound for r, _ in results.values() if r.bound is not None]
            tightest = min(bounds + [old])
            first = next(iter(results.values()))[0]
            line = f"{n:>3} {layout:>3} {old:7.2f} | {_num(first.lp_bound)} {_num(first.lp_time_s, 5, 1)}"
            for result, cpu in results.values():
                line += (
                    f" | {_num(result.objective, 13)} {_num(result.bound)} {_pct(result.gap)} "
                    f"{result.nodes:>5} {cpu:4.0f}s {result.wall_s:4.0f}s"
                )
            for make in BASELINES.values():
                value = evaluate(make(), env, episodes=1).records[0]["return"]
                line += f" | {value:11.2f} {_pct((tightest - value) / abs(tightest))}"
            print(line, flush=True)
            for b, (result, _) in results.items():
                if result.status not in ("optimal", "feasible"):
                    print(f"    {b}: {result.status}: {result.message}")
    print(
        "\ngap: (tightest bound - return) / |tightest bound|. cpu: this process's CPU time for the"
        "\nsolve (one core); wall: its wall-clock time, longer when the machine is shared."
    )


def _num(value: float | None, width: int = 7, digits: int = 2) -> str:
    return f"{'-':>{width}}" if value is None else f"{value:{width}.{digits}f}"


def _pct(value: float | None) -> str:
    return f"{'-':>6}" if value is None else f"{100 * value:5.1f}%"


if __name__ == "__main__":
    main()
