"""Fill numba's disk cache before the tests start (run by ``conftest.py``).

Every compiled function of the package is compiled on first call and cached on disk
(``swiptopt.jit``). On a fresh clone the cache is empty, so without this each pytest-xdist
worker and each fresh process a test starts compiles the same functions again until one of
them has written the cache: minutes of duplicated work on a 2-core machine. Here each world's
functions are compiled once, in two processes side by side, before the workers start.

``python -m tests.warm_numba grid`` (or ``continuous``) compiles one world's functions.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PARTS = ("grid", "continuous")


def _play(env, actions) -> None:
    env.reset(seed=0)
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()


def grid() -> None:
    """The grid kernel (tabular and vector observations, one env and vectorised copies),
    the tabular agents' compiled training loop and the bounds' uses of the kernel."""
    import gymnasium as gym

    import swiptopt
    from planners.bounds import exact_optimum
    from planners.hindsight import Draws, step_amounts
    from rl import QLearningAgent, train
    from swiptopt import Scenario, fpmath
    from swiptopt import kernel as K
    from swiptopt.vector import AuvSwiptVectorEnv

    for observation in ("tabular", "vector"):
        env = gym.make(swiptopt.ENV_ID, preset="tiny", channel="rician", observation=observation)
        _play(env, [1, 2, 3, 0, 6] * 4)
        copies = AuvSwiptVectorEnv(2, preset="tiny", channel="rician", observation=observation)
        copies.reset(seed=0)
        for _ in range(5):
            copies.step(np.array([1, 2]))
    env = gym.make(swiptopt.ENV_ID, preset="tiny")
    train(QLearningAgent(env.observation_space.n, seed=0), env.unwrapped, 2, seed=0, backend="compiled")
    tables = K.build_tables(Scenario.preset("tiny", channel="rician"))
    step_amounts(tables, Draws.sample(tables, 0))
    exact_optimum(Scenario.preset("tiny", channel="none", failure_prob_min=0.0, failure_prob_max=0.0,
                                  episode_steps=2))
    fpmath.log1p(np.array([0.5]))


def continuous() -> None:
    """The continuous world's kernel (one env and vectorised copies) and the 3D planners'
    compiled collision and energy checks."""
    import gymnasium as gym

    import swiptopt
    from planners.continuous import OmplTourPlanner
    from planners.paths3d import plan_path_3d, segments_free
    from swiptopt import Scenario, evaluate
    from swiptopt.vector import AuvSwiptVectorEnv

    env = gym.make(swiptopt.CONTINUOUS_ENV_ID, preset="harbour", channel="rician")
    _play(env, [np.array([0.5, -0.5, 0.1], np.float32)] * 10)
    copies = AuvSwiptVectorEnv(2, "continuous", preset="harbour", channel="rician")
    copies.reset(seed=0)
    for _ in range(5):
        copies.step(np.full((2, 3), 0.5, np.float32))
    harbour = Scenario.preset("harbour")
    points = np.array([[5.0, 5.0, 5.0], [40.0, 30.0, 10.0]])
    segments_free(points[:1], points[1:], harbour)
    plan_path_3d(points[0], points[1], harbour, objective="energy", seed=1, iterations=50)
    small = gym.make(swiptopt.CONTINUOUS_ENV_ID, preset="harbour", n_nodes=4, episode_steps=40)
    evaluate(OmplTourPlanner(0, k=2, search_evaluations=10, ompl_iterations=50), small, 1)


def warm_all() -> None:
    """Both parts at once, each in its own process (failures are left to the tests)."""
    runs = [subprocess.Popen([sys.executable, "-m", "tests.warm_numba", part], cwd=ROOT,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for part in PARTS]
    for run in runs:
        run.wait()


if __name__ == "__main__":
    {"grid": grid, "continuous": continuous}[sys.argv[1]]()
