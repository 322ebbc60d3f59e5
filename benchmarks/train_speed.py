"""Agent-environment steps per second of the two training backends, side by side.

Q-learning on the paper preset (25 nodes by default): the Python loop through
``gymnasium.make`` and the compiled (numba) loop, in one process, interleaved, each the
median over repeats; prints both rates and the ratio. Compilation is done before timing.

    python benchmarks/train_speed.py [--nodes 25] [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium as gym

import swiptopt
from rl import QLearningAgent, train


def rate(backend: str, episodes: int, nodes: int, seed: int) -> float:
    env = gym.make(swiptopt.ENV_ID, preset="paper", n_nodes=nodes)
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
    parser.add_argument("--compiled-episodes", type=int, default=100_000)
    args = parser.parse_args()
    rate("compiled", 10, args.nodes, 0)  # compile (or load numba's cache) before timing
    python, compiled = [], []
    for r in range(args.repeats):
        python.append(rate("python", args.python_episodes, args.nodes, r))
        compiled.append(rate("compiled", args.compiled_episodes, args.nodes, r))
    py, co = statistics.median(python), statistics.median(compiled)
    print(f"Q-learning training, paper preset, {args.nodes} nodes, median of {args.repeats} runs, one core")
    print(f"  python backend:   {py:>14,.0f} agent-environment steps/s")
    print(f"  compiled backend: {co:>14,.0f} agent-environment steps/s")
    print(f"  ratio compiled / python: {co / py:.1f}")


if __name__ == "__main__":
    main()
