"""The continuous world's planners on the harbour layouts: return and planning time for a few k_max.

Each configuration runs in a fresh process (OMPL's random seed is process-wide, so a plan
depends on what the process planned before): the OMPL tour (``OmplTourPlanner(0, k_max=K)``)
plans layouts ``--layouts`` of the harbour preset in order, and :func:`swiptopt.evaluate`
scores it over ``--episodes`` episodes (seed 100), as C1's command did; then the straight-line
planner the same way. Planning time is reported as wall clock and as the process's CPU time
(steadier on a shared machine); imports and numba compilation happen before the first plan
and are not counted. ``--fixed`` also runs the executor without its reactions
(``adaptive=False``), the planned tour as planned. The machine is printed first. Usage:

    python benchmarks/continuous_planners.py [--k-max 8 10 12] [--layouts 0 1 ... 11] [--episodes 5] [--fixed]
"""

from __future__ import annotations

import sys
from pathlib import Path

# benchmarks/planners.py would shadow the planners package: keep this folder off the path
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import argparse
import json
import subprocess
import time

import numpy as np

HERE = Path(__file__).resolve().parent


def run(planner: str, settings: dict, layouts: list[int], episodes: int) -> list[dict]:
    """One configuration in this process: per layout, the plan's K, planning wall and CPU
    time (s), the model's return and the mean return over the episodes."""
    import cvxpy  # noqa: F401  (imports before the clock starts)
    import scipy.stats  # noqa: F401
    import sklearn.cluster  # noqa: F401

    from planners import OmplTourPlanner, StraightLinePlanner
    from planners.paths3d import _checks, _energy_function
    from swiptopt import evaluate
    from swiptopt.continuous import compiled
    from swiptopt.env_continuous import AuvSwiptContinuousEnv

    _checks(), _energy_function(), compiled("step")  # compile before the clock starts
    cls = {"ompl": OmplTourPlanner, "straight": StraightLinePlanner}[planner]
    rows = []
    for layout in layouts:
        env = AuvSwiptContinuousEnv(preset="harbour", layout_seed=layout)
        policy = cls(0, **settings)
        obs, info = env.reset(seed=0)
        wall, cpu = time.perf_counter(), time.process_time()
        policy.begin_episode(env, obs, info)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        result = evaluate(policy, env, episodes, seed=100)
        rows.append({"layout": layout, "k": policy.plan_.k, "wall_s": wall, "cpu_s": cpu,
                     "model": policy.plan_.model_return, "return": float(result.summary["return"].mean)})
    return rows


def in_fresh_process(planner: str, settings: dict, layouts: list[int], episodes: int) -> list[dict]:
    code = (f"import sys, json; sys.path.insert(0, {str(HERE)!r}); from continuous_planners import run; "
            f"print(json.dumps(run({planner!r}, {settings!r}, {layouts!r}, {episodes})))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--k-max", type=int, nargs="+", default=[8, 10, 12])
    parser.add_argument("--layouts", type=int, nargs="+", default=list(range(12)))
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--fixed", action="store_true", help="also the executor without its reactions")
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))
    from machine import describe

    print(describe())
    configs = [("straight", "straight line", {})]
    for k in args.k_max:
        configs.append(("ompl", f"OMPL tour, k_max {k}", {"k_max": k}))
        if args.fixed:
            configs.append(("ompl", f"OMPL tour, k_max {k}, fixed executor", {"k_max": k, "adaptive": False}))
    print(f"harbour layouts {args.layouts}, {args.episodes} episodes each (seed 100); planning time per layout")
    print(f"{'planner':<36}{'mean return':>12}{'model':>8}{'wall s (max)':>16}{'CPU s (max)':>15}  K per layout")
    straight = None
    for planner, label, settings in configs:
        rows = in_fresh_process(planner, settings, args.layouts, args.episodes)
        returns = np.array([r["return"] for r in rows])
        wall, cpu = np.array([r["wall_s"] for r in rows]), np.array([r["cpu_s"] for r in rows])
        print(f"{label:<36}{returns.mean():>12.2f}{np.mean([r['model'] for r in rows]):>8.2f}"
              f"{wall.mean():>8.1f} ({wall.max():4.1f}){cpu.mean():>8.1f} ({cpu.max():4.1f})  {[r['k'] for r in rows]}")
        print(f"{'':<4}returns per layout: {np.round(returns, 2).tolist()}")
        if straight is None:
            straight = returns
        else:
            print(f"{'':<4}minus the straight line: {np.round(returns - straight, 2).tolist()}")


if __name__ == "__main__":
    main()
