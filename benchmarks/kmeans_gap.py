"""Why k-means + TSP ends below the optimum, choice by choice, and what the tuned variant gets.

On the deterministic paper preset (25 nodes by default, layouts 0-9), the return of each
variant of :class:`planners.RewardKMeansTspPlanner` against the MILP's best walk
(:func:`planners.solve_optimum`, the ``default`` budget unless ``--budget`` says otherwise):

- ``coverage``: k-means + TSP with hover points chosen for coverage
  (:class:`planners.KMeansTspPlanner`);
- ``linger 0``: the coverage plan without the executor's linger rule;
- ``grid tour``: the coverage plan with the TSP over grid moves instead of straight lines;
- ``steps dwell``: the coverage plan's hover points and tour, dwell in whole steps by marginal
  reward;
- ``reward+convex``: hover points and K chosen by the reward, the convex dwell program;
- ``reward+steps``: both changes: the tuned planner's defaults;
- ``rate_greedy`` for reference.

Each column is the mean return and its ratio to the MILP's mean best return; the last
lines give the plan's travel and stops. Usage (about 15 minutes with the defaults):

    python benchmarks/kmeans_gap.py [--nodes 25] [--layouts 0-9] [--budget default]
"""

from __future__ import annotations

import sys
from pathlib import Path

# keep this folder off the path: the planners package must not be shadowed by a script here
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import argparse

import numpy as np

from planners import BUDGETS, KMeansTspPlanner, RateGreedyPlanner, RewardKMeansTspPlanner, solve_optimum
from swiptopt import Scenario, evaluate
from swiptopt.env import AuvSwiptEnv

DETERMINISTIC = {"channel": "none", "failure_prob_min": 0.0, "failure_prob_max": 0.0}
VARIANTS = {
    "coverage": lambda: KMeansTspPlanner(),
    "linger 0": lambda: KMeansTspPlanner(linger_steps=0),
    "grid tour": lambda: KMeansTspPlanner(tour_costs="grid"),
    "steps dwell": lambda: RewardKMeansTspPlanner(selection="coverage", dwell="steps", linger_steps=2),
    "reward+convex": lambda: RewardKMeansTspPlanner(dwell="convex"),
    "reward+steps": lambda: RewardKMeansTspPlanner(),
    "rate_greedy": lambda: RateGreedyPlanner(),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", type=int, default=25)
    parser.add_argument("--layouts", default="0-9", help="a range a-b or a comma-separated list")
    parser.add_argument("--budget", default="default", choices=list(BUDGETS))
    args = parser.parse_args()
    if "-" in args.layouts:
        first, last = (int(v) for v in args.layouts.split("-"))
        layouts = list(range(first, last + 1))
    else:
        layouts = [int(v) for v in args.layouts.split(",")]

    names = ["milp"] + list(VARIANTS)
    print(f"{'layout':>6} " + " ".join(f"{n:>13}" for n in names))
    returns: dict[str, list[float]] = {n: [] for n in names}
    travel: dict[str, list[float]] = {n: [] for n in VARIANTS}
    for layout in layouts:
        env = AuvSwiptEnv(Scenario.preset("paper", n_nodes=args.nodes, layout_seed=layout, **DETERMINISTIC))
        best = solve_optimum(env.scenario, budget=args.budget, tables=env.tables)
        returns["milp"].append(best.objective)
        for name, make in VARIANTS.items():
            record = evaluate(make(), env, episodes=1).records[0]
            returns[name].append(record["return"])
            # moves: steps whose propulsion was spent (hover needs none without a current)
            travel[name].append(record["auv_propulsion_j"] / env.tables.propulsion_j[:, 0].max())
        print(f"{layout:>6} " + " ".join(f"{returns[n][-1]:13.2f}" for n in names), flush=True)
    reference = float(np.mean(returns["milp"]))
    print(f"{'mean':>6} " + " ".join(f"{np.mean(returns[n]):13.2f}" for n in names))
    print(f"{'/milp':>6} " + " ".join(f"{np.mean(returns[n]) / reference:13.1%}" for n in names))
    print(f"{'moves':>6} {'':>13} " + " ".join(f"{np.mean(travel[n]):13.1f}" for n in VARIANTS))


if __name__ == "__main__":
    main()
