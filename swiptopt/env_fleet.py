"""The fleet as a multi-agent environment: PettingZoo's ``ParallelEnv`` API over
:mod:`swiptopt.fleet` (docs/fleet.md). Needs the ``fleet`` extra (``pettingzoo``)."""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv

from swiptopt import fleet as F
from swiptopt import kernel as K
from swiptopt.env import INFO_KEY, OBSERVATIONS, EpisodeMetrics, Layouts, _grid_action
from swiptopt.scenario import Scenario
from swiptopt.validation import Spec, check_value


def agent_name(k: int) -> str:
    """The name of AUV ``k`` among the env's agents."""
    return f"auv_{k}"


class AuvFleetEnv(Layouts, ParallelEnv):
    """
    ``n_auvs`` AUVs serving one network, every AUV an agent acting at every step
    (PettingZoo's ``ParallelEnv``: ``reset`` and ``step`` take and give one entry per live
    agent). The rules are :mod:`swiptopt.fleet`'s, the physics the single AUV's
    (:class:`~swiptopt.env.AuvSwiptEnv`), through the same kernel.

    - **Agents**: ``auv_0``, ``auv_1``, ...; an AUV whose battery is spent is terminated
      and leaves ``agents`` (the others go on); the whole fleet ends together when every
      node is served (terminated) or after ``episode_steps`` (truncated).
    - **Actions**: ``Discrete(7)`` per AUV, the single AUV's moves.
    - **Observations**: ``observation="vector"``: the single AUV's vector observation from
      the AUV's own cell, then for each other AUV its relative position over the extent
      and whether it is still in the fleet (``Box(-1, 1, (4 + 6 n_nodes + 4 (n_auvs - 1),))``).
      ``observation="tabular"``: the single AUV's tabular state of the AUV's own cell
      (``Discrete(n_cells * 4)``), for independent tabular learners.
    - **Rewards**: each AUV's own share, the single AUV's reward (paper eq. 23) of the data
      it collected, the energy it delivered and its own motion; the fleet's reward is their
      sum. ``infos[agent]["reward_parts"]`` holds the three parts.
    - **Episode end**: every agent's last info holds the fleet's metrics under
      ``"episode_metrics"`` (:func:`swiptopt.fleet.fleet_metrics`), as do
      :meth:`episode_metrics` and :attr:`state` (the global observation: every AUV's
      observation, concatenated).

    ``AuvFleetEnv(scenario=None, *, preset="paper", observation="vector", render_mode=None,
    backend="auto", layout_seeds=None, **overrides)`` as :class:`~swiptopt.env.AuvSwiptEnv`
    (``n_auvs=2`` and the other fleet fields among the overrides). With ``n_auvs = 1`` its
    episodes are the single AUV's, bit for bit, for the same seed and actions.
    """

    metadata = {"name": "swiptopt_fleet_v0", "render_modes": ["ansi"], "is_parallelizable": True}
    _fleet = True
    _strict_options = False

    def __init__(
        self,
        scenario: Scenario | None = None,
        *,
        preset: str = "paper",
        observation: str = "vector",
        render_mode: str | None = None,
        backend: str = "auto",
        layout_seeds: Sequence[int] | None = None,
        **overrides: Any,
    ):
        check_value("observation", observation, Spec(kind="str", choices=OBSERVATIONS))
        self.backend = self._setup(scenario, preset, overrides, render_mode, backend, layout_seeds)
        scenario = self.scenario
        self.observation = observation
        self.fleet = F.fleet_tables(scenario)
        self._layouts = OrderedDict([(scenario.layout_seed, (scenario, self.fleet))])
        if self.backend == "compiled":
            self._step, self._observe = F.compiled("fleet_step"), F.compiled("fleet_observations")
        else:
            self._step, self._observe = F.fleet_step, F.fleet_observations
        n = self.fleet.n_auvs
        self.possible_agents = [agent_name(k) for k in range(n)]
        self.agents: list[str] = []
        if observation == "tabular":
            space: spaces.Space = spaces.Discrete(scenario.n_cells * (K.TABULAR_COUNT_CAP + 1))
        else:
            size = 4 + K.VECTOR_NODE_FEATURES * scenario.n_nodes + F.OTHER_AUV_FEATURES * (n - 1)
            space = spaces.Box(-1.0, 1.0, (size,), dtype=np.float32)
            self._obs = np.zeros((n, size), dtype=np.float32)
            self._cells_norm = np.ascontiguousarray(scenario.cell_centers_m / scenario.extent_m)
            self._nodes_norm = self._node_positions()
        self.observation_spaces = {a: space for a in self.possible_agents}
        self.action_spaces = {a: spaces.Discrete(K.N_ACTIONS) for a in self.possible_agents}
        self._uniforms, self._normals = K.noise_buffers(self.fleet.tables, n)
        self._actions = np.full(n, K.HOVER, dtype=np.int64)
        self.np_random, _ = seeding.np_random()
        self.fleet_state: F.FleetState | None = None
        self.paths: list[list[int]] = []

    def observation_space(self, agent: str) -> spaces.Space:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Space:
        return self.action_spaces[agent]

    # ----------------------------------------------------------------- layouts

    def _build_layout(self, scenario: Scenario) -> F.FleetTables:
        return F.fleet_tables(scenario, K.with_layout(self.fleet.tables, scenario))

    def _node_positions(self) -> np.ndarray:
        """The layout's node positions over the extent (what the vector observation reads)."""
        return np.ascontiguousarray(self.scenario.layout.positions_m / self.scenario.extent_m)

    def _set_layout(self, fleet: F.FleetTables) -> None:
        self.fleet = fleet
        if self.observation == "vector":
            self._nodes_norm = self._node_positions()
        if self.fleet_state is not None:
            self._args = F.fleet_args(fleet, self.fleet_state)

    # ----------------------------------------------------------------- API

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode (``options={"layout_seed": k}`` as the single AUV's env; other
        options are ignored, as PettingZoo's API test expects); returns every AUV's
        observation and ``{"cell", "layout_seed"}`` per AUV."""
        if seed is not None:
            self.np_random, _ = seeding.np_random(seed)
        layout_seed = self._episode_layout_seed(options)
        if layout_seed != self.scenario.layout_seed:
            self._use_layout(layout_seed)
        if self.fleet_state is None or seed is not None:
            self.fleet_state = F.new_fleet_state(self.fleet)
            self._args = F.fleet_args(self.fleet, self.fleet_state)
        else:
            F.reset_fleet(self.fleet, self.fleet_state)
        self._refill = F.needs_refill(self.fleet, self.fleet_state, self._uniforms, self._normals)
        self.agents = list(self.possible_agents)
        self.paths = [[int(c)] for c in self.fleet_state.cells]
        observations = self._observations()
        infos = {
            a: {"cell": int(self.fleet_state.cells[k]), "layout_seed": self.scenario.layout_seed}
            for k, a in enumerate(self.possible_agents)
        }
        return observations, infos

    def step(self, actions: Mapping[str, Any]):
        if not self.agents:
            raise RuntimeError("call reset() before step() (the episode has ended)")
        if not isinstance(actions, Mapping):
            raise ValueError(f"actions must be a dict of agent name -> action, got {type(actions).__name__}")
        unknown = sorted(set(actions) - set(self.agents), key=str)
        if unknown:
            raise ValueError(f"actions for {unknown[0]!r}, which is not a live agent: live agents are {self.agents}")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"no action for {missing[0]!r}: step() takes one action per live agent")
        for k, a in enumerate(self.possible_agents):
            self._actions[k] = _grid_action(actions[a]) if a in actions else K.HOVER
        state = self.fleet_state
        if self._refill:
            K.refill_noise(self.np_random, self.fleet.tables, self._uniforms, self._normals, state.where)
        live = list(self.agents)  # the AUVs in the fleet before this step
        code = self._step(self._actions, self._uniforms, self._normals, self._args)
        self._refill = F.needs_refill(self.fleet, state, self._uniforms, self._normals)
        observations = self._observations(live)
        rewards, terminations, truncations, infos = {}, {}, {}, {}
        metrics = self.episode_metrics() if code else None
        for k, a in enumerate(self.possible_agents):
            if a not in observations:
                continue
            self.paths[k].append(int(state.cells[k]))
            throughput, harvest, movement = state.auv_parts[k].tolist()
            rewards[a] = throughput + harvest + movement
            terminations[a] = code == K.TERMINATED or not state.active[k]
            truncations[a] = code == K.TRUNCATED and not terminations[a]
            infos[a] = {"reward_parts": {"throughput": throughput, "harvest": harvest, "movement": movement}}
            if metrics is not None or terminations[a]:
                infos[a][INFO_KEY] = metrics if metrics is not None else self.episode_metrics()
        self.agents = [a for a in live if not (terminations[a] or truncations[a])]
        return observations, rewards, terminations, truncations, infos

    def _observations(self, agents: Sequence[str] | None = None) -> dict[str, Any]:
        agents = self.possible_agents if agents is None else agents
        s, t = self.fleet_state, self.fleet.tables
        if self.observation == "tabular":
            gamma = t.named.reward_weight
            return {
                a: int(K.tabular_observation(
                    int(s.cells[k]), t.cov_ptr, t.cov_node, s.data_left, s.energy, t.capacity, gamma
                ))
                for k, a in enumerate(self.possible_agents) if a in agents
            }
        self._observe(
            s.where[K.W_T], s.cells, s.active, t.cov_ptr, t.cov_node, s.data_left, s.energy, t.data0, t.capacity,
            t.params, self._cells_norm, self._nodes_norm, self._obs,
        )
        return {a: self._obs[k].copy() for k, a in enumerate(self.possible_agents) if a in agents}

    def state(self) -> np.ndarray:
        """The global state: every AUV's vector observation, concatenated (for centralised
        critics); the vector observation only."""
        if self.observation != "vector":
            raise RuntimeError("state() is the vector observations concatenated: use observation='vector'")
        if self.fleet_state is None:
            raise RuntimeError("call reset() before state()")
        self._observations()
        return self._obs.reshape(-1).copy()

    def episode_metrics(self) -> EpisodeMetrics:
        """The fleet's metrics of the episode so far (:func:`swiptopt.fleet.fleet_metrics`)."""
        if self.fleet_state is None:
            raise RuntimeError("call reset() before episode_metrics()")
        return EpisodeMetrics(F.fleet_metrics(self.fleet, self.fleet_state))

    def render(self) -> str | None:
        if self.render_mode is None:
            return None
        if self.fleet_state is None:
            raise RuntimeError("call reset() before render()")
        m = self.episode_metrics()
        cells = [tuple(int(v) for v in self.scenario.cell_of_index(int(c))) for c in self.fleet_state.cells]
        return (
            f"t={self.fleet_state.t}/{self.scenario.episode_steps}  cells={cells}  in fleet="
            f"{self.fleet_state.active.astype(int).tolist()}\n"
            f"data {m['data_bits'] / 1e3:.1f} kbit (each {[round(x / 1e3, 1) for x in m['data_bits_each']]}); "
            f"nodes served {m['nodes_served']}/{self.scenario.n_nodes}; return {m['return']:.3f}\n"
        )

    def close(self) -> None:
        pass
