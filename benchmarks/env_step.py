"""Steps per second through ``gymnasium.make``: swiptopt's env beside FrozenLake-v1.

Both environments run in this one process, with the wrappers ``gymnasium.make`` adds,
random actions drawn up front, resetting at episode ends; the median over repeats of
each is reported, and the ratio (ours / FrozenLake). Usage:

    python benchmarks/env_step.py [--steps 200000] [--repeats 5] [--nodes 50]
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium as gym
import numpy as np

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
    parser.add_argument("--nodes", type=int, default=50)
    args = parser.parse_args()

    ours = gym.make(swiptopt.ENV_ID, preset="paper", n_nodes=args.nodes)
    frozen = gym.make("FrozenLake-v1")
    steps_per_second(ours, 7, 2000, 0)  # compile and warm up
    steps_per_second(frozen, 4, 2000, 0)
    rates: dict[str, list[float]] = {"swiptopt paper": [], "FrozenLake-v1": []}
    for r in range(args.repeats):  # interleaved, so both see the same machine load
        rates["swiptopt paper"].append(steps_per_second(ours, 7, args.steps, r))
        rates["FrozenLake-v1"].append(steps_per_second(frozen, 4, args.steps, r))
    med = {k: statistics.median(v) for k, v in rates.items()}
    print(f"steps per second through gymnasium.make, median of {args.repeats} x {args.steps} steps")
    print(f"  swiptopt/AuvSwipt-v1 (paper, {args.nodes} nodes, {ours.unwrapped.backend} kernel): {med['swiptopt paper']:>12,.0f}")
    print(f"  FrozenLake-v1:                                       {med['FrozenLake-v1']:>12,.0f}")
    print(f"  ratio swiptopt / FrozenLake: {med['swiptopt paper'] / med['FrozenLake-v1']:.2f}")


if __name__ == "__main__":
    main()
