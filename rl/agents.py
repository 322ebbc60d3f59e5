"""The paper's agents: random, Q-learning and SARSA (SPEC 5).

They read like scikit-learn estimators: ``__init__`` stores its arguments, learned state ends
in ``_`` (``q_table_``, ``epsilon_``, ``rng_``), and each agent has its own seeded generator
(never ``action_space.sample()``). Any of them can be scored by :func:`swiptopt.evaluate`.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np

from rl import core
from rl.config import TabularConfig
from swiptopt.errors import ConfigError

N_ACTIONS = 7


def _check_size(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ConfigError(f"{name} = {value!r} must be a positive integer", name)
    return int(value)


class RandomAgent:
    """The paper's baseline: a uniformly random trajectory from its own generator."""

    algorithm = "random"
    learns = False
    sarsa = False

    def __init__(self, n_states: int = 1, n_actions: int = N_ACTIONS, *, seed: int | None = None):
        self.n_states = _check_size("n_states", n_states)
        self.n_actions = _check_size("n_actions", n_actions)
        self.seed = seed
        self.rng_ = np.random.default_rng(seed)

    def act(self, obs: Any) -> int:
        """The training-time action (random)."""
        return core.random_action(self.rng_, self.n_actions)

    def predict(self, obs: Any, deterministic: bool = False) -> int:
        """A random action: the random trajectory is random when evaluated, too."""
        return core.random_action(self.rng_, self.n_actions)

    def update(self, *args: Any, **kwargs: Any) -> None:
        """Nothing to learn."""

    def end_episode(self) -> None:
        """Nothing to decay."""


class _TabularAgent:
    """Shared machinery of Q-learning and SARSA: table, epsilon schedule, replay, save/load."""

    algorithm = ""
    learns = True
    sarsa = False

    def __init__(
        self,
        n_states: int,
        n_actions: int = N_ACTIONS,
        *,
        config: TabularConfig | None = None,
        seed: int | None = None,
        **settings: Any,
    ):
        self.n_states = _check_size("n_states", n_states)
        self.n_actions = _check_size("n_actions", n_actions)
        self.config = (config or TabularConfig()).replace(**settings) if settings else (config or TabularConfig())
        self.seed = seed
        self.q_table_ = np.zeros((self.n_states, self.n_actions))
        self.epsilon_ = float(self.config.epsilon_start)
        self.rng_ = np.random.default_rng(seed)
        size = self.config.replay_size
        self._replay = np.zeros((size, 5))  # s, a, r, s', terminated
        self._replay_next = np.zeros(size, dtype=np.int64)  # a' for SARSA
        self._replay_count = 0

    # --------------------------------------------------------------- acting

    def act(self, obs: Any) -> int:
        """The training-time action: epsilon-greedy on the current table."""
        return core.epsilon_greedy_action(self.q_table_, self._state(obs), self.epsilon_, self.rng_)

    def predict(self, obs: Any, deterministic: bool = False) -> int:
        """Greedy (``deterministic=True``, no randomness) or epsilon-greedy action."""
        if deterministic:
            return core.greedy_action(self.q_table_, self._state(obs))
        return self.act(obs)

    def _state(self, obs: Any) -> int:
        s = int(obs)
        if not 0 <= s < self.n_states:
            raise ValueError(f"observation {obs!r} is outside the agent's {self.n_states} states")
        return s

    # --------------------------------------------------------------- learning

    def update(
        self,
        obs: Any,
        action: int,
        reward: float,
        next_obs: Any,
        terminated: bool,
        next_action: int = 0,
    ) -> None:
        """One TD update from a transition (``next_action`` is used by SARSA only)."""
        s, s2 = self._state(obs), self._state(next_obs)
        core.td_update(
            self.q_table_, s, int(action), reward, s2, int(next_action), bool(terminated), self.sarsa,
            self.config.learning_rate, self.config.discount,
        )
        if self.config.replay_size:
            self._remember_and_replay(s, int(action), reward, s2, bool(terminated), int(next_action))

    def _remember_and_replay(self, s: int, a: int, r: float, s2: int, term: bool, a2: int) -> None:
        size = self.config.replay_size
        slot = self._replay_count % size
        self._replay[slot] = (s, a, r, s2, float(term))
        self._replay_next[slot] = a2
        self._replay_count += 1
        stored = min(self._replay_count, size)
        for _ in range(self.config.replay_batch):
            j = int(self.rng_.random() * stored)
            rs, ra, rr, rs2, rterm = self._replay[j]
            core.td_update(
                self.q_table_, int(rs), int(ra), rr, int(rs2), int(self._replay_next[j]), rterm == 1.0,
                self.sarsa, self.config.learning_rate, self.config.discount,
            )

    def end_episode(self) -> None:
        """Decay epsilon once per episode, to its floor."""
        self.epsilon_ = max(self.config.epsilon_min, self.epsilon_ * self.config.epsilon_decay)

    # --------------------------------------------------------------- persistence

    def save(self, path: str | Path) -> None:
        """Save table, settings, epsilon and generator state as ``.npz`` (no pickle)."""
        np.savez(
            Path(path),
            algorithm=np.array(self.algorithm),
            q_table=self.q_table_,
            epsilon=np.array(self.epsilon_),
            config=np.array(json.dumps(dataclasses.asdict(self.config))),
            rng_state=np.array(json.dumps(self.rng_.bit_generator.state)),
            seed=np.array(-1 if self.seed is None else self.seed),
        )

    @classmethod
    def load(cls, path: str | Path) -> _TabularAgent:
        """Load an agent saved by :meth:`save`; the file must hold this class's algorithm."""
        with np.load(Path(path), allow_pickle=False) as data:
            algorithm = str(data["algorithm"])
            if algorithm != cls.algorithm:
                raise ConfigError(f"{path} holds a {algorithm!r} agent, not {cls.algorithm!r}", "path")
            q = data["q_table"]
            seed = int(data["seed"])
            config = TabularConfig(**json.loads(str(data["config"])))
            agent = cls(q.shape[0], q.shape[1], config=config, seed=None if seed < 0 else seed)
            agent.q_table_ = q.copy()
            agent.epsilon_ = float(data["epsilon"])
            agent.rng_.bit_generator.state = json.loads(str(data["rng_state"]))
        return agent


class QLearningAgent(_TabularAgent):
    """Tabular Q-learning (off-policy TD, paper eq. 17) with the paper's epsilon schedule."""

    algorithm = "q_learning"
    sarsa = False


class SarsaAgent(_TabularAgent):
    """Tabular SARSA (on-policy TD), otherwise identical to :class:`QLearningAgent`."""

    algorithm = "sarsa"
    sarsa = True


AGENTS: dict[str, type] = {"random": RandomAgent, "q_learning": QLearningAgent, "sarsa": SarsaAgent}


def make_agent(
    algorithm: str,
    n_states: int,
    n_actions: int = N_ACTIONS,
    *,
    config: TabularConfig | None = None,
    seed: int | None = None,
    **settings: Any,
) -> RandomAgent | _TabularAgent:
    """An agent by name: ``"random"``, ``"q_learning"`` or ``"sarsa"``."""
    if algorithm not in AGENTS:
        raise ConfigError(f"unknown algorithm {algorithm!r}: choose one of {sorted(AGENTS)}", "algorithm")
    if algorithm == "random":
        if settings or config is not None:
            raise ConfigError("the random agent takes no settings", "algorithm")
        return RandomAgent(n_states, n_actions, seed=seed)
    return AGENTS[algorithm](n_states, n_actions, config=config, seed=seed, **settings)
