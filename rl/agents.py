"""The paper's agents: random, Q-learning and SARSA (Sections III and IV).

They read like scikit-learn estimators: ``__init__`` stores its arguments, learned state ends
in ``_`` (``q_table_``, ``epsilon_``, ``rng_``), and each agent has its own seeded generator
(never ``action_space.sample()``). Any of them can be scored by :func:`swiptopt.evaluate`.
"""

from __future__ import annotations

import dataclasses
import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from rl import core
from rl.config import TabularConfig
from swiptopt.errors import ConfigError
from swiptopt.kernel import N_ACTIONS
from swiptopt.validation import Spec, check_value

#: What ``n_states`` and ``n_actions`` may hold (:func:`swiptopt.validation.check_value`).
TABLE_SIZE = Spec(kind="int", lo=1, strict=True, doc="rows or columns of the Q-table")


class RandomAgent:
    """The paper's baseline: a uniformly random trajectory from its own generator."""

    algorithm = "random"
    learns = False
    sarsa = False

    def __init__(self, n_states: int = 1, n_actions: int = N_ACTIONS, *, seed: int | None = None):
        self.n_states = check_value("n_states", n_states, TABLE_SIZE)
        self.n_actions = check_value("n_actions", n_actions, TABLE_SIZE)
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


class UniformRandomAgent:
    """The random baseline for a continuous action space: each action drawn uniformly from
    the box ``[low, high]`` (per component) by the agent's own generator, in training and
    evaluation alike.

    ``low`` and ``high`` are arrays of one shape (a Gymnasium ``Box``'s bounds, e.g.
    ``UniformRandomAgent.for_space(env.action_space, seed=1)``); actions are ``float32``.
    """

    algorithm = "random"
    learns = False

    def __init__(self, low: Any, high: Any, *, seed: int | None = None):
        low, high = np.asarray(low, dtype=np.float32), np.asarray(high, dtype=np.float32)
        if low.shape != high.shape or not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))) \
                or np.any(high < low):
            raise ConfigError(f"low = {low!r} and high = {high!r} must be finite arrays of one shape with low <= high",
                              "action_space")
        self.low, self.high = low, high
        self.seed = seed
        self.rng_ = np.random.default_rng(seed)

    @classmethod
    def for_space(cls, space: Any, *, seed: int | None = None) -> UniformRandomAgent:
        """An agent for a Gymnasium ``Box`` action space."""
        return cls(space.low, space.high, seed=seed)

    def predict(self, obs: Any, deterministic: bool = False) -> np.ndarray:
        """A uniform random action in the box (random when evaluated, too)."""
        return self.rng_.uniform(self.low, self.high).astype(np.float32)


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
        self.n_states = check_value("n_states", n_states, TABLE_SIZE)
        self.n_actions = check_value("n_actions", n_actions, TABLE_SIZE)
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
        """Load an agent saved by :meth:`save`; the file must hold this class's algorithm.

        Anything else (a missing or unreadable file, not an ``.npz`` archive, a truncated
        one, a missing array, an array of the wrong shape or type, an unknown setting) is one
        :class:`ConfigError` naming the file and the problem.
        """
        path = Path(path)
        try:
            data = np.load(path, allow_pickle=False)
            if not isinstance(data, np.lib.npyio.NpzFile):
                raise _BadAgentFile("it holds a single array, not an .npz archive")
            with data:
                missing = sorted(set(_SAVED) - set(data.files))
                if missing:
                    raise _BadAgentFile(f"it lacks the array {missing[0]!r} (an agent file holds {', '.join(_SAVED)})")
                arrays = {name: data[name] for name in _SAVED}
        except _BadAgentFile as exc:
            raise ConfigError(f"{path}: not a saved agent: {exc}", "path") from None
        except FileNotFoundError:
            raise ConfigError(f"{path}: no such agent file", "path") from None
        except OSError as exc:
            raise ConfigError(f"{path}: cannot read the agent file: {exc.strerror or exc}", "path") from None
        except (ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
            # np.load's ways of saying "not an array file", a truncated or corrupt archive
            raise ConfigError(f"{path}: not a saved agent (.npz): {_first_line(exc)}", "path") from None
        try:
            return cls._from_arrays(arrays)
        except _BadAgentFile as exc:
            raise ConfigError(f"{path}: not a saved agent: {exc}", "path") from None
        except ConfigError as exc:
            raise ConfigError(f"{path}: {exc}", exc.field) from None

    @classmethod
    def _from_arrays(cls, arrays: dict[str, np.ndarray]) -> _TabularAgent:
        algorithm = _scalar(arrays, "algorithm", np.str_)
        if algorithm != cls.algorithm:
            raise ConfigError(f"it holds a {algorithm!r} agent, not {cls.algorithm!r}", "path")
        q = arrays["q_table"]
        if q.ndim != 2 or q.shape[0] < 1 or q.shape[1] < 1 or q.dtype.kind != "f":
            raise _BadAgentFile(f"q_table must be a 2-D float array (states, actions), got {q.ndim}-D {q.dtype}")
        if not np.all(np.isfinite(q)):
            raise _BadAgentFile("q_table holds values that are not finite")
        seed = int(_scalar(arrays, "seed", np.integer))
        epsilon = float(_scalar(arrays, "epsilon", np.floating))
        if not 0.0 <= epsilon <= 1.0:
            raise _BadAgentFile(f"epsilon = {epsilon!r} must lie in [0, 1]")
        config = _json(arrays, "config")
        if not isinstance(config, dict):
            raise _BadAgentFile("config must be a JSON object of agent settings")
        agent = cls(q.shape[0], q.shape[1], config=TabularConfig().replace(**config), seed=None if seed < 0 else seed)
        agent.q_table_ = np.array(q, dtype=float)
        agent.epsilon_ = epsilon
        state = _json(arrays, "rng_state")
        try:
            agent.rng_.bit_generator.state = state
        except (TypeError, ValueError, KeyError) as exc:
            generator = type(agent.rng_.bit_generator).__name__
            raise _BadAgentFile(f"rng_state is not a state of {generator}: {_first_line(exc)}") from None
        return agent


#: The arrays :meth:`_TabularAgent.save` writes.
_SAVED = ("algorithm", "q_table", "epsilon", "config", "rng_state", "seed")


class _BadAgentFile(Exception):
    """A file that is an archive but not one :meth:`_TabularAgent.save` wrote."""


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _scalar(arrays: dict[str, np.ndarray], name: str, kind: type) -> Any:
    value = arrays[name]
    if value.shape != () or not np.issubdtype(value.dtype, kind):
        raise _BadAgentFile(
            f"{name} must be a single {kind.__name__.strip('_')}, got shape {value.shape} {value.dtype}"
        )
    return value[()]


def _json(arrays: dict[str, np.ndarray], name: str) -> Any:
    text = _scalar(arrays, name, np.str_)
    try:
        return json.loads(str(text))
    except ValueError as exc:
        raise _BadAgentFile(f"{name} is not valid JSON: {_first_line(exc)}") from None


class QLearningAgent(_TabularAgent):
    """Tabular Q-learning (off-policy TD, paper eq. 21) with the paper's epsilon schedule."""

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
