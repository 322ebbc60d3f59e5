"""Agent-environment steps per second of the training backends, side by side.

Q-learning on the paper preset (25 nodes by default), in one process, interleaved, each the
median over repeats, compilation done before timing:

- ``compiled``: ``train(..., backend="compiled")``, whole episodes in numba;
- ``python``: ``train(..., backend="python")`` through ``gymnasium.make``; the environment
  itself steps with the compiled kernel (its default);
- ``python, python kernel``: the same loop with the environment's pure-Python kernel
  (``AuvSwiptEnv(backend="python")``), i.e. no compiled code at all.

The ratios are measured side by side in this one run and the machine is printed with them:
absolute rates vary several-fold between machines and with their load, the ratios much less.

    python benchmarks/train_speed.py [--nodes 25] [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium as gym
from machine import describe

import swiptopt
from rl import QLearningAgent, train


def rate(backend: str, episodes: int, nodes: int, seed: int, kernel: str = "auto") -> float:
    env = gym.make(swiptopt.ENV_ID, preset="paper", n_nodes=nodes, backend=kernel)
    agent = QLearningAgent(env.observation_space.n, seed=seed)
    start = time.perf_counter()
    log = train(agent, env, episodes, seed=seed, backend=backend)
    elapsed = time.perf_counter() - start
    return float(log["length"].sum()) / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", type=int, default=25)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--python-episodes", type=int, default=300)
    parser.add_argument("--compiled-episodes", type=int, default=200_000)
    args = parser.parse_args()
    rate("compiled", 10, args.nodes, 0)  # compile (or load numba's cache) before timing
    runs: dict[str, list[float]] = {"compiled": [], "python": [], "python, python kernel": []}
    for r in range(args.repeats):
        runs["compiled"].append(rate("compiled", args.compiled_episodes, args.nodes, r))
        runs["python"].append(rate("python", args.python_episodes, args.nodes, r))
        runs["python, python kernel"].append(rate("python", args.python_episodes // 3, args.nodes, r, kernel="python"))
    med = {k: statistics.median(v) for k, v in runs.items()}
    print(describe())
    print(f"Q-learning training, paper preset, {args.nodes} nodes, median of {args.repeats} runs, one core")
    for name, value in med.items():
        print(f"  {name + ' backend:':<32}{value:>14,.0f} agent-environment steps/s")
    print(f"  ratio compiled / python:                 {med['compiled'] / med['python']:.1f}")
    print(f"  ratio compiled / python, python kernel:  {med['compiled'] / med['python, python kernel']:.1f}")


if __name__ == "__main__":
    main()
