"""Environment steps per CPU-second of N copies: SB3's DummyVecEnv over N single envs, the
Sb3VectorEnv adapter, and the raw AuvSwiptVectorEnv.

For each world (the grid on the paper preset with 25 nodes and the vector observation; the
continuous world on the harbour preset) and each N, three ways of stepping N copies under
random actions, resetting at episode ends (so each episode's metrics are in the cost):

- ``DummyVecEnv``: SB3's loop over N single envs made with ``gymnasium.make`` (each step
  one compiled kernel call per copy, from Python);
- ``Sb3VectorEnv``: :mod:`rl.vec_env`'s SB3 ``VecEnv`` over the vector env (what SB3 sees:
  float32 rewards, one info dict per copy);
- ``AuvSwiptVectorEnv``: the Gymnasium vector env itself (``NEXT_STEP`` autoreset,
  aggregated infos), one compiled call for all copies.

All run in this one process, actions drawn up front, interleaved over the repeats so that
they share the machine's load; the figure is the median over the repeats of environment
steps (copies x vector steps) per CPU-second (``time.process_time``), with the ratios to
DummyVecEnv measured in this run. The machine is printed first: the figures are only
comparable on one machine, in one run. Usage:

    python benchmarks/vector_env_speed.py [--steps 20000] [--repeats 5] [--num-envs 1 16 64]
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from machine import describe

import swiptopt
from rl.vec_env import make_sb3_vec_env
from swiptopt.vector import AuvSwiptVectorEnv

#: The worlds measured: (world, env id, the arguments of every env).
CASES = {
    "grid, paper 25 nodes": ("grid", swiptopt.ENV_ID, {"preset": "paper", "n_nodes": 25, "observation": "vector"}),
    "continuous, harbour": ("continuous", swiptopt.CONTINUOUS_ENV_ID, {"preset": "harbour"}),
}
KINDS = ("DummyVecEnv", "Sb3VectorEnv", "AuvSwiptVectorEnv")


def random_actions(world: str, n: int, steps: int, seed: int) -> list[np.ndarray]:
    """``steps`` batches of random actions for ``n`` copies."""
    rng = np.random.default_rng(seed)
    if world == "grid":
        return list(rng.integers(0, 7, (steps, n)))
    return list(rng.uniform(-1, 1, (steps, n, 3)).astype(np.float32))


def make(kind: str, world: str, env_id: str, n: int, kwargs: dict[str, Any]) -> tuple[Any, Callable[[int], None]]:
    """The vector env of ``kind`` and a function resetting it with a seed."""
    if kind == "DummyVecEnv":
        from stable_baselines3.common.vec_env import DummyVecEnv

        venv: Any = DummyVecEnv([lambda: gym.make(env_id, **kwargs)] * n)
    elif kind == "Sb3VectorEnv":
        venv = make_sb3_vec_env(n, world, **kwargs)
    else:
        venv = AuvSwiptVectorEnv(n, world, **kwargs)
        return venv, lambda seed: venv.reset(seed=seed)

    def reset(seed: int) -> None:
        venv.seed(seed)
        venv.reset()

    return venv, reset


def steps_per_cpu_second(venv: Any, reset: Callable[[int], None], actions: list[np.ndarray], seed: int) -> float:
    """Environment steps (copies x vector steps) per CPU-second over ``actions``."""
    reset(seed)
    step = venv.step
    start = time.process_time()
    for a in actions:
        step(a)
    return len(actions) * len(actions[0]) / (time.process_time() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=20_000, help="environment steps per measurement (all copies)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--num-envs", type=int, nargs="+", default=[1, 16, 64])
    args = parser.parse_args()

    runs: dict[tuple[str, int, str], tuple[Any, Callable[[int], None], list[np.ndarray]]] = {}
    for case, (world, env_id, kwargs) in CASES.items():
        for n in args.num_envs:
            actions = random_actions(world, n, max(1, args.steps // n), 0)
            for kind in KINDS:
                venv, reset = make(kind, world, env_id, n, kwargs)
                steps_per_cpu_second(venv, reset, actions[:50], 0)  # compile and warm up
                runs[case, n, kind] = (venv, reset, actions)
    rates: dict[tuple[str, int, str], list[float]] = {key: [] for key in runs}
    for r in range(args.repeats):  # interleaved, so all see the same machine load
        for key, (venv, reset, actions) in runs.items():
            rates[key].append(steps_per_cpu_second(venv, reset, actions, r))
    med = {key: statistics.median(v) for key, v in rates.items()}

    print(describe())
    backend = next(iter(runs.values()))[0].get_attr("backend")[0]
    print(f"environment steps per CPU-second, median of {args.repeats} x {args.steps:,} steps, random actions, "
          f"{backend} kernel")
    print(f"  {'world':<22}{'N':>4}{'DummyVecEnv':>14}{'Sb3VectorEnv':>14}{'AuvSwiptVectorEnv':>19}"
          f"{'Sb3 / Dummy':>13}{'raw / Dummy':>13}")
    for case in CASES:
        for n in args.num_envs:
            dummy, sb3, raw = (med[case, n, kind] for kind in KINDS)
            print(
                f"  {case:<22}{n:>4}{dummy:>14,.0f}{sb3:>14,.0f}{raw:>19,.0f}{sb3 / dummy:>13.2f}{raw / dummy:>13.2f}"
            )


if __name__ == "__main__":
    main()
