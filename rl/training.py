"""Training loops: a plain Python loop through the Gymnasium API and a compiled one.

``train(agent, env, episodes, seed, backend="python" | "compiled")``. The ``python``
backend steps ``env`` (any wrapping) and calls the agent's methods. The ``compiled``
backend runs whole episodes inside numba through the same kernel functions
(:mod:`swiptopt.kernel`) and the same agent rules (:mod:`rl.core`), drawing from the
environment's and the agent's own generators in the same order, so both backends give the
same Q-table and the same log, bit for bit, for the same seed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from rl import core
from rl.agents import RandomAgent, _TabularAgent
from swiptopt import kernel as K
from swiptopt.errors import ConfigError
from swiptopt.evaluation import final_metrics
from swiptopt.limits import check_size, training_log_note
from swiptopt.validation import Spec, check_value

BACKENDS = ("python", "compiled")

#: What :func:`train`'s ``episodes`` and ``backend`` may hold (:func:`swiptopt.validation.check_value`).
ARGUMENTS = {
    "episodes": Spec(kind="int", lo=0, strict=True, doc="training episodes"),
    "backend": Spec(kind="str", choices=BACKENDS, doc="the Python loop or the compiled trainer"),
}

#: Columns of the training log, one row per episode.
LOG_COLUMNS = (
    "return",
    "length",
    "data_bits",
    "energy_delivered_j",
    "auv_energy_j",
    "energy_efficiency_bit_per_j",
    "mobility_efficiency_bit_per_j",
    "epsilon",
)


@dataclass(frozen=True, eq=False)
class TrainingLog:
    """Per-episode training metrics: ``values[episode, column]`` with ``columns`` names."""

    values: np.ndarray
    columns: tuple[str, ...] = LOG_COLUMNS

    def __getitem__(self, column: str) -> np.ndarray:
        return self.values[:, self.columns.index(column)]

    def __len__(self) -> int:
        return self.values.shape[0]

    def to_dataframe(self):  # type: ignore[no-untyped-def]
        import pandas as pd

        return pd.DataFrame(self.values, columns=list(self.columns))


def train(
    agent: RandomAgent | _TabularAgent,
    env: Any,
    episodes: int,
    seed: int | None = None,
    backend: str = "python",
) -> TrainingLog:
    """Train ``agent`` on ``env`` for ``episodes`` episodes; the first reset uses ``seed``.

    The agent acts epsilon-greedily, learns from every transition (SARSA picks its next
    action before the update, Q-learning after) and decays epsilon after each episode.
    ``env`` must be a ``swiptopt/AuvSwipt-v1`` environment with tabular observations and one
    layout (no ``layout_seeds``) for the ``compiled`` backend. After a compiled run the
    environment must be reset before use.
    """
    check_value("episodes", episodes, ARGUMENTS["episodes"])
    check_value("backend", backend, ARGUMENTS["backend"])
    check_size("max_training_episodes", int(episodes), "episodes", "episodes", note=training_log_note(int(episodes)))
    log = np.zeros((int(episodes), len(LOG_COLUMNS)))
    if backend == "python":
        _train_python(agent, env, int(episodes), seed, log)
    else:
        _train_compiled(agent, env, int(episodes), seed, log)
    return TrainingLog(log)


def _train_python(agent: Any, env: Any, episodes: int, seed: int | None, log: np.ndarray) -> None:
    for ep in range(episodes):
        obs, _ = env.reset(seed=seed if ep == 0 else None)
        epsilon = getattr(agent, "epsilon_", 1.0)
        a = agent.act(obs)
        while True:
            obs_next, reward, terminated, truncated, info = env.step(a)
            a_next = agent.act(obs_next) if agent.sarsa and not terminated else 0
            agent.update(obs, a, reward, obs_next, terminated, a_next)
            if terminated or truncated:
                break
            if not agent.sarsa:
                a_next = agent.act(obs_next)
            obs, a = obs_next, a_next
        m = final_metrics(env, info)
        log[ep] = (
            m["return"], m["length"], m["data_bits"], m["energy_delivered_j"], m["auv_energy_j"],
            m["energy_efficiency_bit_per_j"], m["mobility_efficiency_bit_per_j"], epsilon,
        )
        agent.end_episode()


# ----------------------------------------------------------------- compiled backend


def refill_draws(rng, draw_uniforms, normal_rows, uniforms, normals, where):  # type: ignore[no-untyped-def]
    """:func:`swiptopt.kernel.refill_noise`, element by element (the same stream)."""
    if draw_uniforms:
        for i in range(uniforms.shape[0]):
            uniforms[i] = rng.random()
    if normal_rows > 0:
        for i in range(normals.shape[0]):
            normals[i] = rng.standard_normal()
    where[K.W_UPTR] = 0
    where[K.W_ZPTR] = 0


def choose_action(kind, q, s, epsilon, rng):  # type: ignore[no-untyped-def]
    """The agent's training-time action: kind 0 random, 1 Q-learning, 2 SARSA."""
    if kind == 0:
        return random_action(rng, q.shape[1])
    return epsilon_greedy_action(q, s, epsilon, rng)


def train_loop(  # type: ignore[no-untyped-def]
    episodes, kind, q, epsilon, epsilon_decay, epsilon_min, learning_rate, discount, agent_rng, env_rng,
    arrays, data0, energy0, start_cell, uniforms, normals, log,
):
    """Whole training episodes through the kernel (``arrays``: the tables' and the state's
    :class:`swiptopt.kernel.StepArrays`); mirrors ``_train_python`` step by step.

    Returns epsilon after the last decay.
    """
    params, where, acc, parts = arrays.params, arrays.where, arrays.acc, arrays.parts
    data_left, energy = arrays.data_left, arrays.energy
    draw_uniforms = params[K.P_DRAW_UNIFORMS] == 1.0
    rows = int(params[K.P_NORMAL_ROWS])
    gamma = params[K.P_GAMMA]
    sarsa = kind == 2
    for ep in range(episodes):
        reset_state(start_cell, data0, energy0, params, where, data_left, energy, arrays.delivered, arrays.collected,
                    acc, parts)
        refill = needs_refill(where, data0.shape[0], uniforms.shape[0], normals.shape[0], rows)
        s = tabular_observation(start_cell, arrays.cov_ptr, arrays.cov_node, data_left, energy, arrays.capacity, gamma)
        a = choose_action(kind, q, s, epsilon, agent_rng)
        while True:
            if refill:
                refill_draws(env_rng, draw_uniforms, rows, uniforms, normals, where)
            code, s_next, refill = step_tabular(a, uniforms, normals, arrays)
            reward = parts[0] + parts[1] + parts[2]
            terminated = code == K.TERMINATED
            a_next = 0
            if sarsa and not terminated:
                a_next = choose_action(kind, q, s_next, epsilon, agent_rng)
            if kind != 0:
                td_update(q, s, a, reward, s_next, a_next, terminated, sarsa, learning_rate, discount)
            if code != K.RUNNING:
                break
            if not sarsa:
                a_next = choose_action(kind, q, s_next, epsilon, agent_rng)
            s = s_next
            a = a_next
        auv = acc[K.A_PROPULSION_J] + acc[K.A_HOTEL_J] + acc[K.A_PROJECTOR_J]
        log[ep, 0] = acc[K.A_RETURN]
        log[ep, 1] = where[K.W_T]
        log[ep, 2] = acc[K.A_BITS]
        log[ep, 3] = acc[K.A_JOULES]
        log[ep, 4] = auv
        log[ep, 5] = acc[K.A_BITS] / auv if auv > 0 else 0.0
        mobility = acc[K.A_PROPULSION_J] + acc[K.A_HOTEL_J]
        log[ep, 6] = acc[K.A_BITS] / mobility if mobility > 0 else 0.0
        log[ep, 7] = epsilon
        if kind != 0:
            epsilon = max(epsilon_min, epsilon * epsilon_decay)
    return epsilon


_COMPILED: dict[str, Callable] = {}


def compiled_train_loop() -> Callable:
    """:func:`train_loop` compiled with numba against the compiled kernel and agent rules."""
    if not _COMPILED:
        helpers = {
            name: K.compiled(name) for name in ("reset_state", "needs_refill", "tabular_observation", "step_tabular")
        }
        helpers.update(
            K.compile_family(
                {
                    "random_action": core.random_action,
                    "greedy_action": core.greedy_action,
                    "epsilon_greedy_action": core.epsilon_greedy_action,
                    "td_update": core.td_update,
                }
            )
        )
        _COMPILED.update(
            K.compile_family(
                {"refill_draws": refill_draws, "choose_action": choose_action, "train_loop": train_loop}, helpers
            )
        )
    return _COMPILED["train_loop"]


# the Python names train_loop resolves when it runs uncompiled (for debugging)
random_action = core.random_action
epsilon_greedy_action = core.epsilon_greedy_action
td_update = core.td_update
reset_state = K.reset_state
needs_refill = K.needs_refill
tabular_observation = K.tabular_observation
step_tabular = K.step_tabular


def _train_compiled(agent: Any, env: Any, episodes: int, seed: int | None, log: np.ndarray) -> None:
    base = env.unwrapped
    if getattr(base, "observation", None) != "tabular" or not hasattr(base, "tables"):
        raise ConfigError("the compiled backend needs a swiptopt env with observation='tabular'", "backend")
    if getattr(base, "layout_seeds", None) is not None:
        # the compiled loop runs every episode on the tables of its first reset
        raise ConfigError(
            "the compiled backend trains on one layout: use backend='python' with layout_seeds", "backend"
        )
    if isinstance(agent, RandomAgent):
        kind, q, cfg = 0, np.zeros((1, agent.n_actions)), None
    elif isinstance(agent, _TabularAgent):
        kind, q, cfg = (2 if agent.sarsa else 1), agent.q_table_, agent.config
        if cfg.replay_size:
            raise ConfigError("experience replay runs on the python backend only", "backend")
    else:
        raise ConfigError(f"the compiled backend trains the rl agents, not {type(agent).__name__}", "backend")
    if episodes == 0:
        return
    base.reset(seed=seed)  # seeds the env's generator exactly as the Python loop's first reset
    t = base.tables
    state = K.new_state(t)
    uniforms, normals = K.noise_buffers(t)
    epsilon = agent.epsilon_ if cfg else 1.0
    loop = compiled_train_loop()
    new_epsilon = loop(
        episodes, kind, q, epsilon,
        cfg.epsilon_decay if cfg else 1.0, cfg.epsilon_min if cfg else 1.0,
        cfg.learning_rate if cfg else 1.0, cfg.discount if cfg else 0.0,
        agent.rng_, base.np_random,
        K.step_args(t, state), t.data0, t.energy0, t.start_cell, uniforms, normals, log,
    )
    if cfg:
        agent.epsilon_ = float(new_epsilon)
    base.state = None
    base._done = True  # the env's own episode state is stale now: reset before use
