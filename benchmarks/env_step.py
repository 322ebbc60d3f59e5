"""Steps per second through ``gymnasium.make``: swiptopt's env, both observations, beside FrozenLake-v1.

All environments run in this one process, with the wrappers ``gymnasium.make`` adds,
random actions drawn up front, resetting at episode ends (so each episode's metrics, computed
on its last step, are in the cost), interleaved over the repeats so that they share the
machine's load; the median of each is reported with the ratios measured in this run:
ours / FrozenLake, and vector / tabular observation (the vector observation is built by the
compiled kernel in the same call as the step). The machine is printed first: the figures
are only comparable on one machine, in one run. Usage:

    python benchmarks/env_step.py [--steps 200000] [--repeats 5] [--nodes 50 1000]
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium as gym
import numpy as np
from machine import describe

import swiptopt


def steps_per_second(env: gym.Env, n_actions: int, steps: int, seed: int) -> float:
    actions = np.random.default_rng(seed).integers(0, n_actions, steps).tolist()
    env.reset(seed=seed)
    step, reset = env.step, env.reset
    start = time.perf_counter()
    for a in actions:
        _, _, terminated, truncated, _ = step(a)
        if terminated or truncated:
            reset()
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--nodes", type=int, nargs="+", default=[50, 1000])
    args = parser.parse_args()

    envs: dict[str, tuple[gym.Env, int]] = {"FrozenLake-v1": (gym.make("FrozenLake-v1"), 4)}
    for n in args.nodes:
        for observation in ("tabular", "vector"):
            env = gym.make(swiptopt.ENV_ID, preset="paper", n_nodes=n, observation=observation)
            envs[f"{observation}, {n} nodes"] = (env, 7)
    for env, n_actions in envs.values():
        steps_per_second(env, n_actions, 2000, 0)  # compile and warm up
    rates: dict[str, list[float]] = {name: [] for name in envs}
    for r in range(args.repeats):  # interleaved, so all see the same machine load
        for name, (env, n_actions) in envs.items():
            rates[name].append(steps_per_second(env, n_actions, args.steps, r))
    med = {name: statistics.median(v) for name, v in rates.items()}

    print(describe())
    kernel = envs[f"tabular, {args.nodes[0]} nodes"][0].unwrapped.backend
    print(f"steps per second through gymnasium.make, median of {args.repeats} x {args.steps:,} steps, "
          f"swiptopt paper preset ({kernel} kernel)")
    frozen = med["FrozenLake-v1"]
    print(f"  {'FrozenLake-v1':<24}{frozen:>12,.0f}")
    for n in args.nodes:
        tab, vec = med[f"tabular, {n} nodes"], med[f"vector, {n} nodes"]
        print(f"  {f'tabular, {n} nodes':<24}{tab:>12,.0f}   ratio to FrozenLake {tab / frozen:5.2f}")
        print(f"  {f'vector, {n} nodes':<24}{vec:>12,.0f}   ratio to FrozenLake {vec / frozen:5.2f}   "
              f"vector / tabular {vec / tab:4.2f}")


if __name__ == "__main__":
    main()
