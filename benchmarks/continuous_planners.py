"""The continuous world's planners on the harbour layouts: return and planning time per configuration.

Each configuration is a planner with settings, run in a fresh process (OMPL's random seed is
process-wide, so a plan depends on what the process planned before): the planner
(``OmplTourPlanner(0, **settings)`` or ``StraightLinePlanner(0, **settings)``) plans the
harbour preset's layouts ``--layouts`` in order, and :func:`swiptopt.evaluate` scores it over
``--episodes`` episodes (seed 100). The first configuration is the reference the others are
compared with, layout by layout. Planning time is reported as wall clock and as the process's
CPU time (steadier on a shared machine); imports and numba compilation happen before the
first plan and are not counted. The machine is printed first. Usage:

    python benchmarks/continuous_planners.py [CONFIG ...] [--layouts 0 1 ... 11] [--episodes 5]
    # e.g. straight 'ompl:{"k_max": 8, "k_patience": null}' 'ompl:{"adaptive": false}'
"""

from __future__ import annotations

import sys
from pathlib import Path

# keep this folder off the path: the planners package must not be shadowed by a script here
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


DEFAULT_CONFIGS = ["straight", "ompl"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("configs", nargs="*", default=DEFAULT_CONFIGS,
                        help='"ompl" or "straight", optionally with settings as JSON: \'ompl:{"k_max": 12}\' '
                             "(default: both planners with their defaults); the first is the reference")
    parser.add_argument("--layouts", type=int, nargs="+", default=list(range(12)))
    parser.add_argument("--episodes", type=int, default=5)
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))
    from machine import describe

    print(describe())
    print(f"harbour layouts {args.layouts}, {args.episodes} episodes each (seed 100); planning time per layout")
    print(f"{'planner':<52}{'mean return':>12}{'model':>8}{'wall s (max)':>16}{'CPU s (max)':>15}")
    reference = None
    for config in args.configs:
        planner, _, text = config.partition(":")
        settings = json.loads(text) if text else {}
        rows = in_fresh_process(planner, settings, args.layouts, args.episodes)
        returns = np.array([r["return"] for r in rows])
        wall, cpu = np.array([r["wall_s"] for r in rows]), np.array([r["cpu_s"] for r in rows])
        label = f"{planner} {json.dumps(settings)}" if settings else planner
        print(f"{label:<52}{returns.mean():>12.2f}{np.mean([r['model'] for r in rows]):>8.2f}"
              f"{wall.mean():>8.1f} ({wall.max():4.1f}){cpu.mean():>8.1f} ({cpu.max():4.1f})")
        print(f"{'':<4}K per layout: {[r['k'] for r in rows]}")
        print(f"{'':<4}returns per layout: {np.round(returns, 2).tolist()}")
        if reference is None:
            reference = returns
        else:
            print(f"{'':<4}minus the first: {np.round(returns - reference, 2).tolist()}")


if __name__ == "__main__":
    main()
