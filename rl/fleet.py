"""Parameter-shared training on a fleet (docs/fleet.md): every AUV of every copy of
:class:`swiptopt.env_fleet.AuvFleetEnv` is one sub-environment of one Stable-Baselines3
``VecEnv``, so one policy learns from all AUVs' experience and acts for each of them (as
SuperSuit's ``pettingzoo_env_to_vec_env`` with ``concat_vec_envs`` does, here without the
extra dependency and with the fleet's own rule for AUVs that leave early).

Sub-environment ``c * n_auvs + k`` is AUV ``k`` of copy ``c``. An AUV's episode is its time
in the fleet: it ends (``done``, with ``terminal_observation``, ``TimeLimit.truncated``
when the fleet's time ran out, ``episode_metrics`` the fleet's and ``episode`` its own
return and length, as SB3's ``Monitor`` writes it) when its battery is spent or the fleet's
episode ends. An AUV that left before the others waits with a zero observation and zero
reward, its actions ignored, until the copy's episode ends (then ``done`` once more, its
terminal observation zero): SuperSuit's "black death". When a copy's episode ends, every
AUV of it starts the next one in the same step, as SB3's vector envs reset.

``seed(s)`` then ``reset()`` seeds copy ``c`` with ``s + c * n_auvs`` (its first AUV's
seed); later resets go on with each copy's generator. Stable-Baselines3 loads when the class
is first built.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import Any

import numpy as np

from swiptopt.env import INFO_KEY
from swiptopt.env_fleet import AuvFleetEnv
from swiptopt.errors import ConfigError


def make_shared_vec_env(n_copies: int, scenario: Any = None, **kwargs: Any) -> Any:
    """A parameter-shared :class:`FleetSharedVecEnv` over ``n_copies`` new
    ``AuvFleetEnv(scenario, observation="vector", **kwargs)``."""
    if isinstance(n_copies, bool) or not isinstance(n_copies, int) or not 1 <= n_copies <= 1024:
        raise ConfigError(f"n_copies = {n_copies!r} must be an integer in [1, 1024]", "n_copies")
    if kwargs.get("observation", "vector") != "vector":
        raise ConfigError("a shared policy acts on the vector observation: observation='vector'", "observation")
    kwargs["observation"] = "vector"
    return _shared_class()([AuvFleetEnv(scenario, **kwargs) for _ in range(n_copies)])


class IndependentAgents:
    """One agent per AUV (the paper's tabular Q-learning or SARSA, or the random agent),
    each acting on its own AUV's observation and learning from its own reward alone, as the
    paper's agents would be used on a fleet. ``act`` is greedy (the evaluation's), the
    agents' own ``act`` is their training-time action."""

    def __init__(self, agents: list[Any]):
        self.agents = agents

    @classmethod
    def make(cls, algorithm: str, n_auvs: int, n_states: int, *, config: Any = None,
             seed: int = 0) -> IndependentAgents:
        """``n_auvs`` agents of ``algorithm`` (:func:`rl.make_agent`), AUV k's seeded ``seed + k``."""
        from rl.agents import make_agent

        return cls([make_agent(algorithm, n_states, config=config, seed=seed + k) for k in range(n_auvs)])

    def act(self, observations: Mapping[str, Any]) -> dict[str, int]:
        return {a: int(self.agents[_index(a)].predict(obs, deterministic=True)) for a, obs in observations.items()}


def _index(agent: str) -> int:
    return int(agent.rsplit("_", 1)[1])


def train_independent(learners: IndependentAgents, env: AuvFleetEnv, episodes: int, seed: int | None = None) -> None:
    """Train every AUV's agent in ``env`` (tabular observation) for ``episodes`` fleet
    episodes, the first reset seeded with ``seed``: each acts epsilon-greedily on its own
    observation and learns from its own transitions, in the single AUV's order
    (:func:`rl.train`: SARSA picks its next action before its update, Q-learning after),
    and decays its epsilon after each episode. An AUV that leaves the fleet early learns its
    last transition as terminal."""
    if env.observation != "tabular":
        raise ConfigError("independent tabular agents act on the tabular observation: observation='tabular'",
                          "observation")
    agents = learners.agents
    for ep in range(episodes):
        observations, _ = env.reset(seed=seed if ep == 0 else None)
        actions = {a: agents[_index(a)].act(obs) for a, obs in observations.items()}
        while env.agents:
            after, rewards, terminations, truncations, _ = env.step(actions)
            upcoming = {}
            for a, action in actions.items():
                agent, done = agents[_index(a)], terminations[a] or truncations[a]
                a_next = agent.act(after[a]) if agent.sarsa and not terminations[a] else 0
                agent.update(observations[a], action, rewards[a], after[a], terminations[a], a_next)
                if not done:
                    upcoming[a] = a_next if agent.sarsa else agent.act(after[a])
            observations, actions = after, upcoming
        for agent in agents:
            agent.end_episode()


class SharedPolicy:
    """A trained SB3 model acting for every AUV of a fleet: ``act(observations)`` maps the
    fleet env's per-agent observations to per-agent actions (deterministic by default)."""

    def __init__(self, model: Any, deterministic: bool = True):
        self.model = model
        self.deterministic = deterministic

    def act(self, observations: Mapping[str, Any]) -> dict[str, int]:
        if not observations:
            return {}
        agents = list(observations)
        batch = np.stack([observations[a] for a in agents])
        actions, _ = self.model.predict(batch, deterministic=self.deterministic)
        return {a: int(x) for a, x in zip(agents, np.asarray(actions).reshape(-1))}


def _step_copy(vec: Any, c: int, rewards: np.ndarray, dones: np.ndarray, infos: list[dict[str, Any]]) -> None:
    """Step copy ``c`` of the shared vector env ``vec`` with its AUVs' actions, writing their
    rewards, dones, infos and next observations (the module docstring gives the rules)."""
    env = vec.fleets[c]
    n = vec.n_auvs
    live = set(env.agents)
    acts = {a: int(vec._actions[c * n + k]) for k, a in enumerate(env.possible_agents) if a in live}
    observations, rew, term, trunc, step_infos = env.step(acts)
    ended = not env.agents
    for k, agent in enumerate(env.possible_agents):
        i = c * n + k
        if agent in live:
            rewards[i] = rew[agent]
            vec._returns[i] += rew[agent]
            vec._lengths[i] += 1
            vec._obs[i] = observations[agent]
            if term[agent] or trunc[agent]:
                dones[i] = True
                infos[i] = {
                    "terminal_observation": observations[agent].copy(),
                    "TimeLimit.truncated": bool(trunc[agent] and not term[agent]),
                    INFO_KEY: step_infos[agent][INFO_KEY],
                    "episode": {"r": float(vec._returns[i]), "l": int(vec._lengths[i])},
                }
                vec._obs[i] = 0.0  # it waits, if the others go on
        elif ended:  # an AUV that left earlier: its waiting ends with the fleet's episode
            dones[i] = True
            infos[i] = {"terminal_observation": vec._obs[i].copy(), "TimeLimit.truncated": False}
    if ended:
        vec._start(c, None, None)


# the class is built on first use, so that Stable-Baselines3 loads only then: ruff counts its
# methods' branches as this builder's, each method itself is short
@functools.lru_cache(maxsize=1)
def _shared_class() -> type:  # noqa: C901
    from stable_baselines3.common.vec_env import VecEnv

    class FleetSharedVecEnv(VecEnv):
        """SB3's ``VecEnv`` with one sub-environment per AUV of each fleet copy (the module
        docstring gives the rules)."""

        def __init__(self, fleets: list[AuvFleetEnv]):
            self.fleets = fleets
            first = fleets[0]
            self.n_auvs = n = first.fleet.n_auvs
            agent = first.possible_agents[0]
            super().__init__(len(fleets) * n, first.observation_space(agent), first.action_space(agent))
            self._obs = np.zeros((self.num_envs, *self.observation_space.shape), dtype=np.float32)
            self._returns = np.zeros(self.num_envs)
            self._lengths = np.zeros(self.num_envs, dtype=np.int64)
            self._actions: Any = None

        def _start(self, c: int, seed: int | None, options: Any) -> None:
            observations, _ = self.fleets[c].reset(seed=seed, options=options)
            n = self.n_auvs
            for k, agent in enumerate(self.fleets[c].possible_agents):
                self._obs[c * n + k] = observations[agent]
            self._returns[c * n : (c + 1) * n] = 0.0
            self._lengths[c * n : (c + 1) * n] = 0

        def reset(self) -> np.ndarray:
            n = self.n_auvs
            for c in range(len(self.fleets)):
                self._start(c, self._seeds[c * n], self._options[c * n] or None)
            self._reset_seeds()
            self._reset_options()
            return self._obs.copy()

        def step_async(self, actions: np.ndarray) -> None:
            self._actions = np.asarray(actions).reshape(-1)

        def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
            rewards = np.zeros(self.num_envs, dtype=np.float32)
            dones = np.zeros(self.num_envs, dtype=bool)
            infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
            for c in range(len(self.fleets)):
                _step_copy(self, c, rewards, dones, infos)
            return self._obs.copy(), rewards, dones, infos

        def close(self) -> None:
            for env in self.fleets:
                env.close()

        def _fleet_of(self, indices: Any) -> list[AuvFleetEnv]:
            return [self.fleets[i // self.n_auvs] for i in self._get_indices(indices)]

        def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
            return [getattr(env, attr_name) for env in self._fleet_of(indices)]

        def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
            for env in self._fleet_of(indices):
                setattr(env, attr_name, value)

        def env_method(self, method_name: str, *args: Any, indices: Any = None, **kwargs: Any) -> list[Any]:
            return [getattr(env, method_name)(*args, **kwargs) for env in self._fleet_of(indices)]

        def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
            return [False] * len(self._get_indices(indices))

    FleetSharedVecEnv.__module__ = __name__
    FleetSharedVecEnv.__qualname__ = "FleetSharedVecEnv"
    return FleetSharedVecEnv


def __getattr__(name: str) -> Any:
    if name == "FleetSharedVecEnv":
        return _shared_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["FleetSharedVecEnv", "IndependentAgents", "SharedPolicy", "make_shared_vec_env", "train_independent"]  # noqa: F822
