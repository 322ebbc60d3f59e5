"""Steps per second through ``gymnasium.make``: swiptopt's envs (the grid with both observations,
the continuous world), beside FrozenLake-v1.

All environments run in this one process, with the wrappers ``gymnasium.make`` adds,
random actions drawn up front, resetting at episode ends (so each episode's metrics, computed
on its last step, are in the cost), interleaved over the repeats so that they share the
machine's load; the median of each is reported with the ratios measured in this run:
ours / FrozenLake, and vector / tabular observation (the vector observation is built by the
compiled kernel in the same call as the step), and continuous / grid vector: the continuous
world (``swiptopt/AuvSwiptContinuous-v0``, random velocity commands, on the same paper
preset and on the harbour preset with its obstacles and current) against the grid env with
the same observation. The machine is printed first: the figures
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
    """Steps per second of ``env`` under random actions: ``n_actions`` discrete ones, or
    (``n_actions = 0``) uniform commands in the continuous world's box."""
    rng = np.random.default_rng(seed)
    if n_actions:
        actions = rng.integers(0, n_actions, steps).tolist()
    else:
        actions = list(rng.uniform(-1, 1, (steps, 3)).astype(np.float32))
    env.reset(seed=seed)
    step, reset = env.step, env.reset
    start = time.perf_counter()
    for a in actions:
        _, _, terminated, truncated, _ = step(a)
        if terminated or truncated:
            reset()
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--nodes", type=int, nargs="+", default=[50, 1000])
    args = parser.parse_args()

    envs: dict[str, tuple[gym.Env, int]] = {"FrozenLake-v1": (gym.make("FrozenLake-v1"), 4)}
    for n in args.nodes:
        for observation in ("tabular", "vector"):
            env = gym.make(swiptopt.ENV_ID, preset="paper", n_nodes=n, observation=observation)
            envs[f"{observation}, {n} nodes"] = (env, 7)
        envs[f"continuous, {n} nodes"] = (gym.make(swiptopt.CONTINUOUS_ENV_ID, preset="paper", n_nodes=n), 0)
    envs["continuous, harbour"] = (gym.make(swiptopt.CONTINUOUS_ENV_ID, preset="harbour"), 0)
    envs["vector, harbour grid"] = (gym.make(swiptopt.ENV_ID, preset="harbour", observation="vector"), 7)
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
        cont = med[f"continuous, {n} nodes"]
        print(f"  {f'continuous, {n} nodes':<24}{cont:>12,.0f}   ratio to FrozenLake {cont / frozen:5.2f}   "
              f"continuous / grid vector {cont / vec:4.2f}")
    harbour, grid = med["continuous, harbour"], med["vector, harbour grid"]
    print(f"  {'vector, harbour (grid)':<24}{grid:>12,.0f}   ratio to FrozenLake {grid / frozen:5.2f}")
    print(f"  {'continuous, harbour':<24}{harbour:>12,.0f}   ratio to FrozenLake {harbour / frozen:5.2f}   "
          f"continuous / grid vector {harbour / grid:4.2f}")


if __name__ == "__main__":
    main()
