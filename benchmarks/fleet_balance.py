"""What the fleet routing planner's ``balance`` buys: the return of k-means + vehicle routing
under each of its objectives, on the fleet suite's field.

For fleets of 1, 2 and 4 AUVs on the ``fleet`` suite's scenario (the paper preset over
200 m x 200 m, 60 nodes, 100 steps; :data:`swiptopt.benchmark.experiment.FLEET_SCENARIO`),
layouts 0-3, :class:`planners.fleet.FleetRoutingPlanner` with ``balance`` = ``makespan``
(the default), ``distance`` and ``return`` plays 10 episodes per layout
(:func:`swiptopt.evaluation.evaluate_fleet`, seed 0). Each cell is the mean return over the
layouts, then its mean ratio to ``makespan``'s on the same layouts with the lowest and
highest per-layout ratio, and the stops the routing left out. Usage (a minute or two)::

    python benchmarks/fleet_balance.py [--layouts 4] [--episodes 10]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# keep this folder off the path: the planners package must not be shadowed by a script here
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402

from planners.fleet import BALANCES, FleetRoutingPlanner  # noqa: E402
from swiptopt import Scenario  # noqa: E402
from swiptopt.benchmark.experiment import FLEET_SCENARIO, FLEET_SIZES  # noqa: E402
from swiptopt.env_fleet import AuvFleetEnv  # noqa: E402
from swiptopt.evaluation import evaluate_fleet  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--layouts", type=int, default=4)
    parser.add_argument("--episodes", type=int, default=10)
    args = parser.parse_args()
    print(f"mean return over layouts 0-{args.layouts - 1}, {args.episodes} episodes each; "
          "ratio to makespan's [lowest-highest layout]; stops left out")
    print(f"{'AUVs':>4}  " + "  ".join(f"{b:<30}" for b in BALANCES))
    for n in FLEET_SIZES:
        returns = {b: [] for b in BALANCES}
        dropped = {b: 0 for b in BALANCES}
        for layout in range(args.layouts):
            env = AuvFleetEnv(Scenario.from_dict({**FLEET_SCENARIO, "n_auvs": n, "layout_seed": layout}))
            for balance in BALANCES:
                planner = FleetRoutingPlanner(balance=balance)
                records = evaluate_fleet(planner, env, episodes=args.episodes, seed=0).records
                returns[balance].append(np.mean([r["return"] for r in records]))
                dropped[balance] += len(planner.plan_.details["dropped_stops"])
        base = np.array(returns["makespan"])
        cells = []
        for balance in BALANCES:
            ratio = np.array(returns[balance]) / base
            cells.append(f"{np.mean(returns[balance]):6.2f} {ratio.mean():.2f}x "
                         f"[{ratio.min():.2f}-{ratio.max():.2f}] {dropped[balance]:>2}")
        print(f"{n:>4}  " + "  ".join(f"{c:<30}" for c in cells), flush=True)


if __name__ == "__main__":
    main()
