"""Training steps per second of PPO and DQN on swiptopt's env beside CartPole-v1.

Stable-Baselines3 at its defaults through :func:`rl.deep.train_deep` (one torch thread, on
the CPU), on the paper preset (vector observation) and on Gymnasium's CartPole-v1, in this
one process, interleaved so that both see the same machine load; each figure is the median
over repeats of ``timesteps / training time``, and the ratio (ours / CartPole) says how much
of a run's cost is the environment. Usage:

    python benchmarks/deeprl_speed.py [--timesteps 8192] [--repeats 3] [--nodes 25]
"""

from __future__ import annotations

import argparse
import statistics

import gymnasium as gym
from machine import describe

from rl.deep import train_deep
from swiptopt import Scenario
from swiptopt.env import AuvSwiptEnv


def rate(algorithm: str, env: gym.Env, timesteps: int, seed: int) -> float:
    """Environment steps per second of one training run (construction excluded)."""
    return timesteps / train_deep(algorithm, env, timesteps, seed).train_seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=8192)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--nodes", type=int, default=25)
    args = parser.parse_args()

    scenario = Scenario.preset("paper", n_nodes=args.nodes)
    envs = {
        f"swiptopt paper, {args.nodes} nodes": lambda: AuvSwiptEnv(scenario, observation="vector"),
        "CartPole-v1": lambda: gym.make("CartPole-v1"),
    }
    for algorithm in ("ppo", "dqn"):  # warm up: imports, first allocations
        for make in envs.values():
            rate(algorithm, make(), 256, 0)
    rates: dict[tuple[str, str], list[float]] = {(a, e): [] for a in ("ppo", "dqn") for e in envs}
    for r in range(args.repeats):
        for algorithm, name in rates:
            rates[algorithm, name].append(rate(algorithm, envs[name](), args.timesteps, r))
    med = {key: statistics.median(values) for key, values in rates.items()}
    ours, cartpole = envs
    print(f"SB3 training steps per second (defaults, one torch thread), median of {args.repeats} x {args.timesteps} steps")
    print(describe())
    for algorithm in ("ppo", "dqn"):
        a, b = med[algorithm, ours], med[algorithm, cartpole]
        print(f"  {algorithm.upper()}: {ours}: {a:>8,.0f}   CartPole-v1: {b:>8,.0f}   ratio ours / CartPole: {a / b:.2f}")


if __name__ == "__main__":
    main()
