"""Training steps per second of SAC and PPO in the continuous world (the harbour suite's env)
beside Gymnasium's Pendulum-v1, with the benchmark's settings.

Stable-Baselines3 through :func:`rl.deep.train_deep` (one torch thread, on the CPU), with the
settings the ``harbour`` suite gives each algorithm (:mod:`swiptopt.benchmark.algorithms`),
on the harbour preset in the continuous world (trained across the suite's layouts) and on
Pendulum-v1 (a box action too), in this one process, interleaved so that both see the same
machine load. SAC is measured while it learns (``learning_starts = 0``: a gradient step every
``train_freq`` steps from the first), which is what its budget pays for beyond its first
``learning_starts`` steps. Each figure is the median over repeats of ``timesteps / training time``; the ratio
(ours / Pendulum) says how much of a run's cost is the environment. Usage:

    python benchmarks/continuous_rl_speed.py [--timesteps 4096] [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path
from typing import Any, Callable

import gymnasium as gym
from machine import describe

# benchmarks/planners.py, beside this script, would shadow the planners package
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from rl.deep import train_deep
from swiptopt import Scenario
from swiptopt.benchmark.algorithms import deep_hyperparams, resolve_settings
from swiptopt.benchmark.experiment import builtin_experiments
from swiptopt.worlds import CONTINUOUS

ALGORITHMS = ("sac", "ppo")


def settings_of(algorithm: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """The harbour suite's SB3 arguments and policy arguments for ``algorithm``."""
    suite = builtin_experiments()["harbour"]
    settings = resolve_settings(algorithm, suite.algorithms[algorithm])
    hyperparams = deep_hyperparams(settings)
    if algorithm == "sac":
        hyperparams["learning_starts"] = 0
    return hyperparams, {"net_arch": list(settings["net_arch"])}


def rate(algorithm: str, train: Callable[..., Any], timesteps: int, seed: int) -> float:
    """Environment steps per second of one training run (construction excluded)."""
    hyperparams, policy = settings_of(algorithm)
    return timesteps / train(algorithm, timesteps, seed, hyperparams, policy).train_seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=4096)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    suite = builtin_experiments()["harbour"]
    scenario = Scenario.from_dict(suite.scenario)
    layouts = tuple(suite.training_layouts)

    def harbour(algorithm, timesteps, seed, hyperparams, policy):  # type: ignore[no-untyped-def]
        return train_deep(algorithm, scenario, timesteps, seed, hyperparams=hyperparams, policy_kwargs=policy,
                          layout_seeds=layouts, world=CONTINUOUS)

    def pendulum(algorithm, timesteps, seed, hyperparams, policy):  # type: ignore[no-untyped-def]
        return train_deep(algorithm, gym.make("Pendulum-v1"), timesteps, seed, hyperparams=hyperparams,
                          policy_kwargs=policy)

    envs = {f"harbour ({scenario.n_nodes} nodes, continuous)": harbour, "Pendulum-v1": pendulum}
    for algorithm in ALGORITHMS:  # warm up: imports, compilation, first allocations
        for train in envs.values():
            rate(algorithm, train, 256, 0)
    rates: dict[tuple[str, str], list[float]] = {(a, e): [] for a in ALGORITHMS for e in envs}
    for r in range(args.repeats):
        for algorithm, name in rates:
            rates[algorithm, name].append(rate(algorithm, envs[name], args.timesteps, r))
    med = {key: statistics.median(values) for key, values in rates.items()}
    ours, reference = envs
    print(f"SB3 training steps per second (the harbour suite's settings, one torch thread), median of "
          f"{args.repeats} x {args.timesteps} steps; SAC learning from its first step")
    print(describe())
    for algorithm in ALGORITHMS:
        a, b = med[algorithm, ours], med[algorithm, reference]
        print(f"  {algorithm.upper()}: {ours}: {a:>8,.0f}   {reference}: {b:>8,.0f}   ratio ours / {reference}: "
              f"{a / b:.2f}")


if __name__ == "__main__":
    main()
