"""Deep-RL training throughput: the benchmark's default training configurations against
Stable-Baselines3's defaults, in one process.

For each deep-RL algorithm of each world, two trainings through :func:`rl.deep.train_deep`
(one torch thread, on the CPU, torch's pinned CPU paths), interleaved so that both see the
same machine load:

- **SB3's defaults**: one copy of the environment, SB3's hyperparameters, its default
  networks ([64, 64] for PPO and DQN, [256, 256] for SAC; SB3's DummyVecEnv around the
  single env);
- **the default configuration**: the benchmark's own settings for the algorithm
  (:data:`swiptopt.benchmark.algorithms.ALGORITHMS`: n_envs copies stepped together by the
  compiled vector env, the tuned rollout, batch and network).

Each figure is the median over repeats of environment steps per CPU-second of training
(``time.process_time``; the stop-choosing agent counts decisions, and its continuous-world
legs are planned in a child process whose CPU is not counted). The ratio is how much more
experience a CPU-second buys. Usage::

    python benchmarks/deeprl_speed.py [--timesteps 65536] [--repeats 3] [--only ppo dqn]
"""

from __future__ import annotations

import argparse
import statistics
import time

from machine import describe

import planners  # noqa: F401 (registers the stop-choice environments)
from rl.deep import train_deep
from swiptopt import Scenario
from swiptopt.benchmark.algorithms import deep_hyperparams, resolve_settings
from swiptopt.worlds import CONTINUOUS, GRID

#: (label, benchmark algorithm, SB3 algorithm, world, preset)
CASES = (
    ("PPO, grid", "ppo", "ppo", GRID, "paper"),
    ("DQN, grid", "dqn", "dqn", GRID, "paper"),
    ("stop-choosing PPO, grid", "stop_ppo", "maskable_ppo", GRID, "paper"),
    ("PPO, harbour", "ppo", "ppo", CONTINUOUS, "harbour"),
    ("SAC, harbour", "sac", "sac", CONTINUOUS, "harbour"),
)


def _scenario(preset: str) -> Scenario:
    return Scenario.preset(preset, n_nodes=25) if preset == "paper" else Scenario.preset(preset)


def _stop_env(algorithm: str, world: str) -> str | None:
    from planners.stops import STOP_ENV_IDS

    return STOP_ENV_IDS[world] if algorithm == "stop_ppo" else None


def default_rate(name: str, sb3: str, world: str, preset: str, timesteps: int, seed: int) -> float:
    """Steps per CPU-second of the benchmark's default configuration of ``name``."""
    settings = resolve_settings(name, {})
    env_kwargs = {"candidates": settings["candidates"]} if name == "stop_ppo" and world == GRID else (
        {"legs": settings["legs"]} if name == "stop_ppo" else {})
    result = train_deep(sb3, _scenario(preset), timesteps, seed, hyperparams=deep_hyperparams(settings),
                        policy_kwargs={"net_arch": list(settings["net_arch"])}, world=world,
                        n_envs=settings["n_envs"], env_id=_stop_env(name, world), env_kwargs=env_kwargs)
    return result.model.num_timesteps / result.cpu_seconds


def sb3_rate(name: str, sb3: str, world: str, preset: str, timesteps: int, seed: int) -> float:
    """Steps per CPU-second of SB3's defaults on one copy of the same environment."""
    result = train_deep(sb3, _scenario(preset), timesteps, seed, world=world, env_id=_stop_env(name, world))
    return result.model.num_timesteps / result.cpu_seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--timesteps", type=int, default=65_536, help="steps per training run")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--only", nargs="*", default=None, help="benchmark algorithms to measure (default: all)")
    args = parser.parse_args()
    cases = [c for c in CASES if args.only is None or c[1] in args.only]
    print(describe())
    print(f"training steps per CPU-second, median of {args.repeats} runs of {args.timesteps:,} steps each")
    print(f"{'algorithm':<26} {'SB3 defaults':>13} {'default config':>15} {'ratio':>7}")
    ratios = []
    for label, name, sb3, world, preset in cases:
        sb3_rate(name, sb3, world, preset, 512, 0)  # warm up: imports, compiled code, legs planned once
        default_rate(name, sb3, world, preset, 512, 0)
        ours, theirs = [], []
        for r in range(args.repeats):
            theirs.append(sb3_rate(name, sb3, world, preset, args.timesteps, r))
            ours.append(default_rate(name, sb3, world, preset, args.timesteps, r))
        a, b = statistics.median(theirs), statistics.median(ours)
        ratios.append(b / a)
        print(f"{label:<26} {a:>13,.0f} {b:>15,.0f} {b / a:>6.1f}x", flush=True)
    print(f"median ratio {statistics.median(ratios):.1f}x ({time.strftime('%Y-%m-%d')})")


if __name__ == "__main__":
    main()
