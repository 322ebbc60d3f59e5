"""The Gymnasium environment: an AUV collecting data from and recharging underwater nodes.

Registered as ``swiptopt/AuvSwipt-v1`` (``import swiptopt`` registers it). Every step goes
through :func:`swiptopt.kernel.step`, the same function the fast trainer and the planners'
plan executor use.
"""

from __future__ import annotations

import dataclasses
import math
from collections import OrderedDict
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec

from swiptopt import kernel as K
from swiptopt.errors import ConfigError
from swiptopt.jit import numba_available
from swiptopt.metrics import episode_metrics
from swiptopt.scenario import Scenario
from swiptopt.validation import Spec, check_value

OBSERVATIONS = ("tabular", "vector")
BACKENDS = ("auto", "compiled", "python")

#: The ``info`` key of the episode's metrics at its last step. Gymnasium's
#: ``RecordEpisodeStatistics`` and SB3's ``Monitor`` own ``info["episode"]``.
INFO_KEY = "episode_metrics"

#: The keys ``reset(options=...)`` accepts.
RESET_OPTIONS = ("layout_seed",)

#: How many layouts an env keeps built, least recently used dropped first: training on up to
#: this many layouts builds each once.
LAYOUT_CACHE_SIZE = 64

#: Layout seeds are those of :attr:`Scenario.layout_seed`.
_MAX_LAYOUT_SEED = 2**63 - 1


def _grid_action(action: Any) -> int:
    """``action`` as a move index; a one-line ValueError for anything but one integer (or
    integral float) in [0, N_ACTIONS): 2.7 or "3" are refused, never truncated or parsed."""
    try:
        a = np.asarray(action)
    except (TypeError, ValueError):
        a = None
    ok = a is not None and a.size == 1 and a.dtype.kind in "iuf"
    value = a.reshape(-1)[0].item() if ok else None
    if not ok or not math.isfinite(value) or value != math.floor(value) or not 0 <= value < K.N_ACTIONS:
        shown = repr(action) if ok or (a is not None and a.size <= 8) else f"an array of shape {np.shape(a)}"
        raise ValueError(f"action must be an integer in [0, {K.N_ACTIONS - 1}], got {shown[:80]}")
    return int(value)


class EpisodeMetrics(Mapping):
    """The metrics of one episode (:func:`swiptopt.metrics.episode_metrics`), read-only:
    ``m["return"]``, ``dict(m)``.

    A mapping, not a ``dict``, so that Gymnasium's vector environments keep it whole (an
    object per sub-environment under ``infos["episode_metrics"]``) instead of stacking each
    metric into a typed array, which fails when a step count meets ``None`` (a target not
    reached).
    """

    __slots__ = ("_values",)

    def __init__(self, values: Mapping[str, Any]):
        self._values = dict(values)

    def __getitem__(self, name: str) -> Any:
        return self._values[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __repr__(self) -> str:
        return f"EpisodeMetrics({self._values!r})"

    def __reduce__(self):  # type: ignore[no-untyped-def]
        return EpisodeMetrics, (self._values,)


#: What a layout seed may hold (:func:`swiptopt.validation.check_value`).
LAYOUT_SEED = Spec(kind="int", lo=0, hi=_MAX_LAYOUT_SEED, strict=True, doc="the seed of a node layout")


def _layout_seed(value: Any, name: str) -> int:
    return check_value(name, value, LAYOUT_SEED, field="layout_seed")


def check_layout_seeds(value: Any) -> Sequence[int] | None:
    """Validated layout seeds (a :class:`~swiptopt.ConfigError` naming ``layout_seeds``
    otherwise): a ``range`` as it is (never materialised), other sequences as an int64 array."""
    if value is None:
        return None
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, (Sequence, np.ndarray)):
        raise ConfigError(
            f"layout_seeds = {value!r} must be a sequence of layout seeds, e.g. range(0, 1000)", "layout_seeds"
        )
    if len(value) == 0:
        raise ConfigError("layout_seeds is empty: give at least one layout seed", "layout_seeds")
    if isinstance(value, range):
        if min(value[0], value[-1]) < 0 or max(value[0], value[-1]) > _MAX_LAYOUT_SEED:
            raise ConfigError(f"layout_seeds = {value!r} must hold integers in [0, 2**63 - 1]", "layout_seeds")
        return value
    return np.array([_layout_seed(v, "layout_seeds[...]") for v in value], dtype=np.int64)


class Layouts:
    """A layout per episode (``layout_seeds``, ``reset(options=...)``) with the last
    :data:`LAYOUT_CACHE_SIZE` layouts kept built, for an environment with ``np_random`` and
    ``metadata`` (both worlds' Gymnasium envs and the fleet's PettingZoo env). A subclass
    sets ``scenario``, ``_scenario0``, ``layout_seeds`` and ``_layouts`` (layout seed ->
    (scenario, built)) and defines :meth:`_build_layout` and :meth:`_set_layout`."""

    #: Whether the environment runs a fleet (a scenario with ``n_auvs > 1``).
    _fleet = False

    #: Whether ``reset`` refuses options other than :data:`RESET_OPTIONS` (PettingZoo's API
    #: test resets with options of its own, which a PettingZoo env must ignore).
    _strict_options = True

    def _episode_layout_seed(self, options: Mapping[str, Any] | None) -> int:
        if options:
            if not isinstance(options, Mapping):
                raise ConfigError(f"reset options must be a dict, got {options!r}", "options")
            unknown = sorted(set(options) - set(RESET_OPTIONS), key=str)
            if unknown and self._strict_options:
                raise ConfigError(
                    f"unknown reset option {unknown[0]!r}: allowed options are {list(RESET_OPTIONS)}", "options"
                )
            if "layout_seed" in options:
                return _layout_seed(options["layout_seed"], "options['layout_seed']")
        if self.layout_seeds is not None:
            return int(self.layout_seeds[int(self.np_random.integers(len(self.layout_seeds)))])
        return self._scenario0.layout_seed

    def _setup(
        self, scenario: Scenario | None, preset: str, overrides: dict[str, Any], render_mode: str | None,
        backend: str, layout_seeds: Sequence[int] | None,
    ) -> str:
        """Set ``scenario`` (a preset with field overrides, or the scenario with them),
        ``render_mode`` and ``layout_seeds`` after checking them; returns the kernel backend
        (``"auto"`` resolved)."""
        if scenario is None:
            scenario = Scenario.preset(preset, **overrides)
        elif overrides:
            scenario = scenario.replace(**overrides)
        if scenario.n_auvs > 1 and not self._fleet:
            raise ConfigError(
                f"n_auvs = {scenario.n_auvs}: this environment runs one AUV; run a fleet in "
                "swiptopt.env_fleet.AuvFleetEnv (docs/fleet.md)", "n_auvs",
            )
        render_modes = Spec(kind="str", choices=tuple(self.metadata["render_modes"]), optional=True)
        check_value("render_mode", render_mode, render_modes)
        check_value("backend", backend, Spec(kind="str", choices=BACKENDS))
        self.layout_seeds = check_layout_seeds(layout_seeds)
        self.scenario = scenario
        self._scenario0 = scenario  # the layouts of other episodes are variations of it
        self.render_mode = render_mode
        if backend == "auto":
            backend = "compiled" if numba_available() else "python"
        return backend

    def _use_layout(self, layout_seed: int) -> None:
        """Switch to another layout of the same scenario, rebuilding only what it changes
        (once for each of the last :data:`LAYOUT_CACHE_SIZE` layouts used)."""
        built = self._layouts.pop(layout_seed, None)
        if built is None:
            scenario = self._scenario0.replace(layout_seed=layout_seed)
            built = (scenario, self._build_layout(scenario))
        self._layouts[layout_seed] = built  # the most recently used last
        if len(self._layouts) > LAYOUT_CACHE_SIZE:
            self._layouts.popitem(last=False)
        self.scenario = built[0]
        self._set_layout(built[1])

    def _build_layout(self, scenario: Scenario) -> Any:
        """The layout-dependent arrays for ``scenario`` (another layout of ``_scenario0``)."""
        raise NotImplementedError

    def _set_layout(self, built: Any) -> None:
        """Start using the arrays :meth:`_build_layout` made."""
        raise NotImplementedError


class LayoutEnv(Layouts, gym.Env):
    """What both worlds' environments share: the registration spec with the scenario's
    episode length, and a layout per episode (:class:`Layouts`)."""

    _spec: EnvSpec | None = None

    @property
    def spec(self) -> EnvSpec | None:
        """The registration spec (set by ``gymnasium.make``), its ``max_episode_steps`` the
        scenario's ``episode_steps``."""
        return self._spec

    @spec.setter
    def spec(self, value: EnvSpec | None) -> None:
        # gymnasium.make sets the spec after construction, without an episode length: the
        # scenario knows it (the env truncates itself, so no TimeLimit is needed)
        if value is not None and value.max_episode_steps is None:
            value = dataclasses.replace(value, max_episode_steps=self.scenario.episode_steps)
        self._spec = value


class AuvSwiptEnv(LayoutEnv):
    """
    ## Description

    An AUV moves in unit steps on a 3D grid of cells above ``n_nodes`` underwater sensor
    nodes. From each cell it covers the nodes inside a downward acoustic cone (within range
    and above the SNR threshold); from each covered node it collects data and, by acoustic
    SWIPT with power-splitting ratio alpha, delivers energy to the node's storage. With the
    scenario's ``link = "uplink"`` the data instead travels on each node's own transmission
    (the paper's eq. 13), in packets paid from its storage, and all of the AUV's received
    power charges it. The model is Omeke et al.'s (Sections II and III; docs/design.md, 'The
    model'): Thorp absorption, Stojanovic's noise, the passive sonar equation, a linear or
    logistic harvester, REMUS-100-like propulsion.

    ## Action Space

    ``Discrete(7)``: 0 +x, 1 -x, 2 +y, 3 -y, 4 +z (deeper), 5 -z (shallower), 6 hover. A move
    out of the volume or into an obstacle leaves the AUV in place and still costs the move.

    ## Observation Space

    - ``observation="tabular"``: ``Discrete(n_cells * 4)``, the integer
      ``cell * 4 + min(covered nodes still to serve, 3)`` (the paper's position and residual
      state made finite).
    - ``observation="vector"``: ``Box(-1, 1, (4 + 6 n_nodes,), float32)``: the AUV position
      divided by the volume's extent, the fraction of the episode left, and per node its
      position relative to the AUV divided by the extent, the fraction of its data left, its
      state of charge and whether it is covered now.

    ## Starting State

    The AUV in the scenario's start cell (default: the surface cell at the centre), every
    node with its data and its initial charge from the scenario's layout.

    ## Rewards

    ``r = Gamma bits / D_ref + (1 - Gamma) joules / E_ref - lambda E_move / E_move_ref``
    (paper eq. 23, normalised), where only data still to deliver and energy still storable
    count, so hovering over served nodes earns only the movement part. The three weighted
    parts are in ``info["reward_parts"]`` (``throughput``, ``harvest``, ``movement``) and sum
    to the reward.

    ## Episode End

    Terminated when every node is served (its data delivered and, for Gamma < 1, its storage
    full) or the AUV's battery is spent; truncated after ``episode_steps`` steps, which
    ``spec.max_episode_steps`` reports (the env truncates itself: ``gymnasium.make`` adds no
    ``TimeLimit``). The last step's ``info["episode_metrics"]`` (:data:`INFO_KEY`) holds the
    episode's metrics (:class:`EpisodeMetrics`, see :mod:`swiptopt.metrics`); standard
    wrappers (``Monitor``, ``RecordEpisodeStatistics``, ``TimeLimit``, ``FlattenObservation``,
    vector environments) pass it through. When a wrapper ends the episode first (a shorter
    ``TimeLimit``), :meth:`episode_metrics` of the unwrapped env gives the metrics so far;
    :func:`swiptopt.evaluate` reads them from there.

    ## Layouts

    By default every episode uses the scenario's layout (``layout_seed``). With
    ``layout_seeds=range(0, 1000)`` each reset draws one of them from the env's
    ``np_random``; ``reset(options={"layout_seed": k})`` sets episode's layout directly
    (and draws nothing). The reset's ``info["layout_seed"]`` says which layout the episode
    runs on, and ``env.scenario`` is that layout's scenario. A new layout rebuilds only the
    layout's part of the kernel tables (:func:`swiptopt.kernel.with_layout`); the grid, the
    moves and the spaces stay, and the last :data:`LAYOUT_CACHE_SIZE` layouts stay built.
    Other reset options are errors.

    ## Arguments

    ``AuvSwiptEnv(scenario=None, *, preset="paper", observation="tabular",
    render_mode=None, backend="auto", layout_seeds=None, **overrides)``: a
    :class:`~swiptopt.Scenario`, or a preset name with :class:`~swiptopt.Scenario` field
    overrides (``n_nodes=50``, ``layout_seed=3``, ``split_ratio=0.3``, ...). ``backend``
    chooses the compiled (numba) or the Python kernel; both give identical episodes.
    ``render_mode``: ``"ansi"`` (a text summary) or ``"rgb_array"`` (a top view and a depth
    view). ``layout_seeds``: the layouts to draw one from at each reset (see Layouts).

    ## Version History

    - v1: the episode's metrics moved from ``info["episode"]`` (which Gymnasium's
      ``RecordEpisodeStatistics`` and SB3's ``Monitor`` own) to ``info["episode_metrics"]``;
      a layout per episode (``layout_seeds``, ``reset(options={"layout_seed": k})``);
      unknown reset options are errors; ``spec.max_episode_steps`` is the scenario's
      ``episode_steps``; the reset's info holds ``layout_seed``.
    - v0: initial version.
    """

    metadata = {"render_modes": ["ansi", "rgb_array"], "render_fps": 4}

    def __init__(
        self,
        scenario: Scenario | None = None,
        *,
        preset: str = "paper",
        observation: str = "tabular",
        render_mode: str | None = None,
        backend: str = "auto",
        layout_seeds: Sequence[int] | None = None,
        **overrides: Any,
    ):
        check_value("observation", observation, Spec(kind="str", choices=OBSERVATIONS))
        backend = self._setup(scenario, preset, overrides, render_mode, backend, layout_seeds)
        scenario = self.scenario
        self.observation = observation
        self.tables = K.build_tables(scenario)
        self._layouts = OrderedDict([(scenario.layout_seed, (scenario, self.tables))])
        self.backend = backend
        if backend == "compiled":
            self._step_tabular = K.compiled("step_tabular")
            self._step_vector = K.compiled("step_vector")
            self._observe_vector = K.compiled("vector_observation")
        else:
            self._step_tabular = K.step_tabular
            self._step_vector = K.step_vector
            self._observe_vector = K.vector_observation

        n, cells = scenario.n_nodes, scenario.n_cells
        self.action_space = spaces.Discrete(K.N_ACTIONS)
        if observation == "tabular":
            self.observation_space = spaces.Discrete(cells * (K.TABULAR_COUNT_CAP + 1))
        else:
            self.observation_space = spaces.Box(-1.0, 1.0, (4 + K.VECTOR_NODE_FEATURES * n,), dtype=np.float32)
            self._obs = np.empty(self.observation_space.shape, dtype=np.float32)
            self._cells_norm = np.ascontiguousarray(scenario.cell_centers_m / scenario.extent_m)
            self._set_layout_features()
        self._uniforms, self._normals = K.noise_buffers(self.tables)
        self._vector = observation == "vector"
        self._done = True  # until the first reset
        self.state: K.EpisodeState | None = None
        self.path: list[int] = []

    def _set_layout_features(self) -> None:
        """What the kernel's vector observation reads besides the state (the layout's initial
        data and node positions over the extent) and its output array."""
        s = self.scenario
        self._obs_args = (
            self.tables.data0,
            self._cells_norm,
            np.ascontiguousarray(s.layout.positions_m / s.extent_m),
            self._obs,
        )

    # ----------------------------------------------------------------- layouts

    def _build_layout(self, scenario: Scenario) -> K.Tables:
        return K.with_layout(self.tables, scenario)

    def _set_layout(self, tables: K.Tables) -> None:
        self.tables = tables
        if self._vector:
            self._set_layout_features()
        if self.state is not None:
            self._args = K.step_args(self.tables, self.state)

    # ----------------------------------------------------------------- gym API

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode; ``options={"layout_seed": k}`` runs it on layout ``k`` (see
        Layouts in the class docstring). Returns the observation and ``{"cell",
        "layout_seed"}``."""
        super().reset(seed=seed)
        layout_seed = self._episode_layout_seed(options)
        if layout_seed != self.scenario.layout_seed:
            self._use_layout(layout_seed)
        t = self.tables
        if self.state is None or seed is not None:
            # a seeded reset starts with fresh draws from the reseeded generator
            self.state = K.new_state(t)
            self._args = K.step_args(t, self.state)
        else:
            # an unseeded one goes on with the draws left in the buffers
            K.reset_state(t.start_cell, t.data0, t.energy0, t.params, *K._state_arrays(self.state))
        self._refill = K.needs_refill(
            self.state.where, t.n_nodes, self._uniforms.shape[0], self._normals.shape[0], t.normal_rows
        )
        self._done = False
        self.path = [self.state.where[0]]
        if self.observation == "tabular":
            obs = int(
                K.tabular_observation(
                    self.state.cell,
                    self.tables.cov_ptr,
                    self.tables.cov_node,
                    self.state.data_left,
                    self.state.energy,
                    self.tables.capacity,
                    self.tables.named.reward_weight,
                )
            )
        else:
            obs = self._vector_observation()
        return obs, {"cell": self.state.cell, "layout_seed": self.scenario.layout_seed}

    def step(self, action):
        if self._done:
            raise RuntimeError("call reset() before step() (the episode has ended)")
        a = _grid_action(action)
        if self._refill:
            K.refill_noise(self.np_random, self.tables, self._uniforms, self._normals, self.state.where)
        if self._vector:
            code, self._refill = self._step_vector(a, self._uniforms, self._normals, self._args, *self._obs_args)
            obs = self._obs.copy()  # a fresh array per step: callers may keep observations
        else:
            code, obs, self._refill = self._step_tabular(a, self._uniforms, self._normals, self._args)
        throughput, harvest, movement = self.state.parts.tolist()
        self.path.append(self.state.where[0])
        info: dict[str, Any] = {"reward_parts": {"throughput": throughput, "harvest": harvest, "movement": movement}}
        if code:
            self._done = True
            info[INFO_KEY] = self.episode_metrics()
        return obs, throughput + harvest + movement, code == K.TERMINATED, code == K.TRUNCATED, info

    def episode_metrics(self) -> EpisodeMetrics:
        """The metrics of the episode so far (at its end, those of ``info["episode_metrics"]``).

        For an episode a wrapper ended early (a ``TimeLimit`` shorter than the scenario's
        ``episode_steps``): call it on ``env.unwrapped`` before the next reset.
        """
        if self.state is None:
            raise RuntimeError("call reset() before episode_metrics()")
        return EpisodeMetrics(episode_metrics(self.tables, self.state))

    def _vector_observation(self) -> np.ndarray:
        """The vector observation of the current state (the kernel's, compiled or not)."""
        s, t = self.state, self.tables
        data0, cells_norm, nodes_norm, out = self._obs_args
        self._observe_vector(
            s.where[K.W_CELL], s.where[K.W_T], t.cov_ptr, t.cov_node, s.data_left, s.energy, data0,
            t.capacity, t.params, cells_norm, nodes_norm, out,
        )
        return out.copy()

    # ----------------------------------------------------------------- rendering

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='ansi' or 'rgb_array'")
            return None
        if self.state is None:
            raise RuntimeError("call reset() before render()")
        if self.render_mode == "ansi":
            return self._render_text()
        return self._render_rgb()

    def _render_text(self) -> str:
        s = self.scenario
        m = self.episode_metrics()
        cell = tuple(int(v) for v in s.cell_of_index(self.state.cell))
        covered = self.tables.covered(self.state.cell)
        position = tuple(np.round(s.cell_centers_m[self.state.cell], 1))
        lines = [
            f"t={self.state.t}/{s.episode_steps}  cell={cell}  position={position} m",
            f"covered nodes: {list(map(int, covered)) or 'none'}",
            f"data collected {m['data_bits'] / 1e3:.1f} kbit of {self.tables.data0.sum() / 1e3:.1f} kbit; "
            f"energy delivered {m['energy_delivered_j'] * 1e3:.1f} mJ; nodes served {m['nodes_served']}/{s.n_nodes}",
            f"AUV energy {m['auv_energy_j'] / 1e3:.2f} kJ (propulsion {m['auv_propulsion_j'] / 1e3:.2f}, "
            f"hotel {m['auv_hotel_j'] / 1e3:.2f}, projector {m['auv_projector_j'] / 1e3:.2f}); "
            f"return {m['return']:.3f}",
        ]
        return "\n".join(lines) + "\n"

    def _render_rgb(self) -> np.ndarray:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        s, t, st = self.scenario, self.tables, self.state
        nodes = s.layout.positions_m
        served = np.array(
            [K.is_served(st.data_left, st.energy, t.capacity, t.named.reward_weight, i) for i in range(t.n_nodes)]
        )
        covered = np.zeros(t.n_nodes, dtype=bool)
        covered[t.covered(st.cell)] = True
        path = s.cell_centers_m[np.asarray(self.path, dtype=np.int64)]
        here = s.cell_centers_m[st.cell]
        fig = Figure(figsize=(8, 4), dpi=80)
        canvas = FigureCanvasAgg(fig)
        top, side = fig.subplots(1, 2)
        for ax, (i, j), title, ylabel in (
            (top, (0, 1), "top view", "y (m)"),
            (side, (0, 2), "depth view", "depth (m)"),
        ):
            blocked = s.cell_centers_m[s.blocked_cells]
            if len(blocked):
                ax.scatter(blocked[:, i], blocked[:, j], marker="s", s=30, c="0.8", label="obstacle")
            colours = np.where(served, "tab:green", np.where(covered, "tab:orange", "tab:blue"))
            ax.scatter(nodes[:, i], nodes[:, j], c=colours, s=18)
            ax.plot(path[:, i], path[:, j], "-", c="k", lw=1, alpha=0.6)
            ax.scatter([here[i]], [here[j]], marker="^", s=80, c="tab:red")
            ax.set_xlim(0, s.extent_m[i])
            ax.set_ylim(0, s.extent_m[j])
            ax.set_xlabel("x (m)")
            ax.set_ylabel(ylabel)
            ax.set_title(title)
        side.invert_yaxis()
        fig.suptitle(f"t = {st.t}: blue to serve, orange covered, green served")
        fig.tight_layout()
        canvas.draw()
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()
