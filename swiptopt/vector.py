"""A Gymnasium vector environment that steps N copies of either world in one compiled call.

:class:`AuvSwiptVectorEnv` is ``gymnasium.vector.SyncVectorEnv`` over N single envs
(:class:`~swiptopt.env.AuvSwiptEnv`, :class:`~swiptopt.env_continuous.AuvSwiptContinuousEnv`)
with the loop over the copies moved into compiled code: one call of
:func:`step_grid_copies` (or its tabular and continuous siblings) steps every copy by
calling the single envs' own step function, :func:`swiptopt.kernel.step_vector` (or
:func:`~swiptopt.kernel.step_tabular`, :func:`swiptopt.continuous.step_observe`), on that
copy's rows of 2D arrays. There is no second implementation of the world's rules, and the
same seeds and actions give the same episodes as ``SyncVectorEnv`` over the single envs,
bit for bit (a test holds it to that).

Each copy keeps one single env, its *controller*, for everything that happens between
steps: seeding and its ``np_random``, the reset (the layout drawn per episode, the layout's
tables built and cached), the draw-buffer refills and the episode's metrics. A controller's
``state`` arrays are views of its row of the vector env's state arrays (from its first reset
on), so its own reset, ``episode_metrics()`` and ``state`` always see what the compiled step
wrote. Its layout tables are copied into per-copy padded rows when its layout changes
(``cov_ptr`` offsets into the copy's own row of ``cov_node``, ``cov_snr``, ``cov_pav``,
whose width grows when a layout covers more pairs). Controllers are never stepped
themselves: their ``path`` (and, in the continuous world, ``position``) stay as they were
at the episode's start; :attr:`AuvSwiptVectorEnv.positions` has the AUVs' positions.

Registered as the ``vector_entry_point`` of ``swiptopt/AuvSwipt-v1`` and
``swiptopt/AuvSwiptContinuous-v0`` (:func:`grid_vector_env`, :func:`continuous_vector_env`):
``gymnasium.make_vec(id, num_envs=8, vectorization_mode="vector_entry_point", **kwargs)``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from swiptopt import continuous as C
from swiptopt import kernel as K
from swiptopt.continuous import step_observe
from swiptopt.env import BACKENDS, INFO_KEY, RESET_OPTIONS, AuvSwiptEnv, check_layout_seeds
from swiptopt.env_continuous import AuvSwiptContinuousEnv
from swiptopt.errors import ConfigError, did_you_mean
from swiptopt.jit import numba_available
from swiptopt.kernel import StepArrays, step_tabular, step_vector
from swiptopt.scenario import Scenario
from swiptopt.validation import Spec, check_value
from swiptopt.worlds import CONTINUOUS, GRID, OBSERVATIONS, check_world

#: The default preset of each world (the single envs' defaults).
DEFAULT_PRESETS = {GRID: "paper", CONTINUOUS: "harbour"}

#: ``reset(options=...)`` keys: the single envs' (``layout_seed``), and Gymnasium's
#: ``reset_mask`` ((num_envs,) bool: reset only those copies).
VECTOR_RESET_OPTIONS = (*RESET_OPTIONS, "reset_mask")

#: The fields of :class:`swiptopt.kernel.EpisodeState`, each a row of one (num_envs, ...) array.
STATE_FIELDS = ("where", "data_left", "energy", "delivered", "collected", "acc", "parts")


# ------------------------------------------------------------------ the compiled loops


def _copy_arrays(rows, i):  # type: ignore[no-untyped-def]
    """Copy i's :class:`swiptopt.kernel.StepArrays`: row i of every per-copy array of ``rows``
    (whose ``next_cell`` and ``propulsion_j`` are shared: the layout does not change them)."""
    return StepArrays(
        rows.next_cell, rows.propulsion_j, rows.cov_ptr[i], rows.cov_node[i], rows.cov_snr[i], rows.cov_pav[i],
        rows.capacity[i], rows.fail_prob[i], rows.params[i], rows.where[i], rows.data_left[i], rows.energy[i],
        rows.delivered[i], rows.collected[i], rows.acc[i], rows.parts[i],
    )


def step_grid_copies(  # type: ignore[no-untyped-def]
    actions, active, uniforms, normals, rows, data0, cells_norm, nodes_norm, out, codes, refills,
):
    """:func:`swiptopt.kernel.step_vector` on copy i's arrays (:func:`_copy_arrays` of
    ``rows``, a :class:`~swiptopt.kernel.StepArrays` of per-copy rows), for each copy with
    ``active[i]``; its return code and refill flag into ``codes[i]``, ``refills[i]``.
    ``cells_norm`` is shared."""
    for i in range(actions.shape[0]):
        if active[i]:
            code, refill = step_vector(
                actions[i], uniforms[i], normals[i], _copy_arrays(rows, i), data0[i], cells_norm, nodes_norm[i], out[i],
            )
            codes[i] = code
            refills[i] = refill


def step_grid_tabular_copies(actions, active, uniforms, normals, rows, out, codes, refills):  # type: ignore[no-untyped-def]
    """:func:`step_grid_copies` with :func:`swiptopt.kernel.step_tabular`: the tabular
    observation of copy i into ``out[i]``."""
    for i in range(actions.shape[0]):
        if active[i]:
            code, obs, refill = step_tabular(actions[i], uniforms[i], normals[i], _copy_arrays(rows, i))
            out[i] = obs
            codes[i] = code
            refills[i] = refill


def step_continuous_copies(  # type: ignore[no-untyped-def]
    actions, active, uniforms, normals, world, boxes, spheres, seabed, nodes_m, cov_node, cov_snr, cov_pav,
    capacity, fail_prob, params, pos, where, data_left, energy, delivered, collected, acc, parts,
    data0, nodes_norm, out, codes, blocked, refills,
):
    """:func:`swiptopt.continuous.step_observe` on row i of every per-copy array, for each
    copy with ``active[i]`` (``actions`` (num_envs, 3) float64); code, stopped-short flag and
    refill flag into ``codes[i]``, ``blocked[i]``, ``refills[i]``. ``world``, ``boxes``,
    ``spheres`` and ``seabed`` are shared."""
    for i in range(actions.shape[0]):
        if active[i]:
            code, stopped, refill = step_observe(
                actions[i], uniforms[i], normals[i], world, boxes, spheres, seabed, nodes_m[i], cov_node[i],
                cov_snr[i], cov_pav[i], capacity[i], fail_prob[i], params[i], pos[i], where[i], data_left[i],
                energy[i], delivered[i], collected[i], acc[i], parts[i], data0[i], nodes_norm[i], out[i],
            )
            codes[i] = code
            blocked[i] = stopped
            refills[i] = refill


_FUNCTIONS = ("_copy_arrays", "step_grid_copies", "step_grid_tabular_copies", "step_continuous_copies")
_COMPILED: dict[str, Callable] = {}


def compiled(name: str) -> Callable:
    """The numba-compiled version of one of this module's loops over the copies, compiled
    from the same source against the kernels' compiled step functions (which numba inlines
    into the loop)."""
    if not _COMPILED:
        from swiptopt.jit import compile_family

        shared = {
            "step_vector": K.compiled("step_vector"),
            "step_tabular": K.compiled("step_tabular"),
            "step_observe": C.compiled("step_observe"),
        }
        _COMPILED.update(compile_family({n: globals()[n] for n in _FUNCTIONS}, shared))
    return _COMPILED[name]


# ------------------------------------------------------------------ per-copy rows


def _rows(n: int, shape: tuple[int, ...], dtype: Any = np.float64) -> np.ndarray:
    return np.zeros((n, *shape), dtype=dtype)


class _Copies:
    """The arrays of N copies, one row per copy: the episode state, the draw buffers, the
    observations and the step's outputs; a world subclass adds its layout's rows and the
    loop that steps them."""

    def __init__(self, envs: Sequence[gym.Env], layout: Any, obs_shape: tuple[int, ...], obs_dtype: Any):
        n, nodes = len(envs), layout.n_nodes
        self.n_nodes = nodes
        self.where = _rows(n, (4,), np.int64)
        self.where[:, K.W_UPTR:] = 2**62  # no draws yet (as kernel.new_state)
        self.data_left, self.energy, self.delivered, self.collected = (_rows(n, (nodes,)) for _ in range(4))
        self.acc = _rows(n, (K.N_ACC,))
        self.parts = _rows(n, (3,))
        self.states = [K.EpisodeState(*(getattr(self, f)[i] for f in STATE_FIELDS)) for i in range(n)]
        n_u, n_z = K.buffer_sizes(layout)
        self.uniforms, self.normals = np.ones((n, n_u)), np.zeros((n, n_z))
        self.obs = _rows(n, obs_shape, obs_dtype)
        self.codes = np.zeros(n, dtype=np.int64)
        self.refills = np.ones(n, dtype=bool)
        self.loaded: list[Any] = [None] * n  # the layout object whose tables each row holds
        self._args: tuple | None = None

    @staticmethod
    def layout_of(env: gym.Env) -> Any:
        """The controller's current layout tables (``Tables`` or ``World``)."""
        raise NotImplementedError

    def adopt(self, i: int, env: gym.Env) -> None:
        """After the controller of copy i reset: its state into row i (the controller's
        ``state`` then views the row) and its layout's tables, if they changed."""
        state = self.states[i]
        if env.state is not state:  # a fresh state (first or seeded reset): copy, then view
            for f in STATE_FIELDS:
                getattr(state, f)[...] = getattr(env.state, f)
            env.state = state
        layout = self.layout_of(env)
        if layout is not self.loaded[i]:
            self.load(i, env, layout)
            self.loaded[i] = layout
        self.refills[i] = K.needs_refill(
            state.where, self.n_nodes, self.uniforms.shape[1], self.normals.shape[1], layout.normal_rows
        )

    def refill(self, i: int, env: gym.Env) -> None:
        """Refill copy i's draw buffers from its controller's generator (as the single env does)."""
        K.refill_noise(env.np_random, self.layout_of(env), self.uniforms[i], self.normals[i], self.where[i])

    def load(self, i: int, env: gym.Env, layout: Any) -> None:
        raise NotImplementedError

    def args(self) -> tuple:
        raise NotImplementedError

    def step(self, fn: Callable, actions: np.ndarray, active: np.ndarray) -> None:
        if self._args is None:
            self._args = self.args()
        fn(actions, active, self.uniforms, self.normals, *self._args)


class _GridCopies(_Copies):
    def __init__(self, envs: Sequence[AuvSwiptEnv], vector: bool):
        t = envs[0].tables
        space = envs[0].observation_space
        super().__init__(envs, t, space.shape, np.float32 if vector else np.int64)
        n, nodes = len(envs), t.n_nodes
        self.vector = vector
        self.next_cell, self.propulsion_j = t.next_cell, t.propulsion_j  # the same for every layout
        s = envs[0].scenario
        self.cells_norm = np.ascontiguousarray(s.cell_centers_m / s.extent_m)
        self.cov_ptr = _rows(n, (t.n_cells + 1,), np.int64)
        width = max(1, max(env.tables.cov_node.shape[0] for env in envs))
        self.cov_node = _rows(n, (width,), np.int64)
        self.cov_snr, self.cov_pav = _rows(n, (width,)), _rows(n, (width,))
        self.capacity, self.fail_prob, self.data0 = (_rows(n, (nodes,)) for _ in range(3))
        self.params = _rows(n, (K.N_PARAMS,))
        self.nodes_norm = _rows(n, (nodes, 3))

    @staticmethod
    def layout_of(env: AuvSwiptEnv) -> K.Tables:
        return env.tables

    def load(self, i: int, env: AuvSwiptEnv, t: K.Tables) -> None:
        nnz = t.cov_node.shape[0]
        width = self.cov_node.shape[1]
        if nnz > width:  # this layout covers more pairs than any so far: widen every row
            new = max(nnz, width + width // 2)
            for name in ("cov_node", "cov_snr", "cov_pav"):
                old = getattr(self, name)
                wider = np.zeros((old.shape[0], new), dtype=old.dtype)
                wider[:, :width] = old
                setattr(self, name, wider)
            self._args = None
        self.cov_ptr[i] = t.cov_ptr
        self.cov_node[i, :nnz] = t.cov_node
        self.cov_snr[i, :nnz] = t.cov_snr
        self.cov_pav[i, :nnz] = t.cov_pav
        self.capacity[i], self.fail_prob[i], self.data0[i], self.params[i] = t.capacity, t.fail_prob, t.data0, t.params
        s = env.scenario
        self.nodes_norm[i] = s.layout.positions_m / s.extent_m  # as AuvSwiptEnv computes it

    def args(self) -> tuple:
        rows = StepArrays(
            self.next_cell, self.propulsion_j, self.cov_ptr, self.cov_node, self.cov_snr, self.cov_pav,
            self.capacity, self.fail_prob, self.params, *(getattr(self, f) for f in STATE_FIELDS),
        )
        if self.vector:
            return (rows, self.data0, self.cells_norm, self.nodes_norm, self.obs, self.codes, self.refills)
        return (rows, self.obs, self.codes, self.refills)


class _ContinuousCopies(_Copies):
    def __init__(self, envs: Sequence[AuvSwiptContinuousEnv]):
        w = envs[0].world
        super().__init__(envs, w, envs[0].observation_space.shape, np.float32)
        n, nodes = len(envs), w.n_nodes
        self.world, self.boxes, self.spheres, self.seabed = w.world, w.boxes, w.spheres, w.seabed  # every layout's
        self.nodes_m, self.nodes_norm = _rows(n, (nodes, 3)), _rows(n, (nodes, 3))
        self.cov_node = _rows(n, (nodes,), np.int64)  # scratch: the nodes a step covers
        self.cov_snr, self.cov_pav = _rows(n, (nodes,)), _rows(n, (nodes,))
        self.capacity, self.fail_prob, self.data0 = (_rows(n, (nodes,)) for _ in range(3))
        self.params = _rows(n, (K.N_PARAMS,))
        self.pos = _rows(n, (3,))
        self.blocked = np.zeros(n, dtype=bool)

    @staticmethod
    def layout_of(env: AuvSwiptContinuousEnv) -> C.World:
        return env.world

    def adopt(self, i: int, env: AuvSwiptContinuousEnv) -> None:
        super().adopt(i, env)
        self.pos[i] = env.position

    def load(self, i: int, env: AuvSwiptContinuousEnv, w: C.World) -> None:
        self.nodes_m[i], self.capacity[i], self.fail_prob[i] = w.nodes_m, w.capacity, w.fail_prob
        self.data0[i], self.params[i] = w.data0, w.params
        s = env.scenario
        self.nodes_norm[i] = s.layout.positions_m / s.extent_m  # as AuvSwiptContinuousEnv computes it

    def args(self) -> tuple:
        return (
            self.world, self.boxes, self.spheres, self.seabed, self.nodes_m, self.cov_node, self.cov_snr,
            self.cov_pav, self.capacity, self.fail_prob, self.params, self.pos,
            *(getattr(self, f) for f in STATE_FIELDS), self.data0, self.nodes_norm, self.obs, self.codes,
            self.blocked, self.refills,
        )


# ------------------------------------------------------------------ checks


#: What the vector env's ``num_envs`` and ``backend`` may hold (:func:`swiptopt.validation.check_value`).
ARGUMENTS = {
    "num_envs": Spec(kind="int", lo=1, strict=True, doc="copies of the environment stepped together"),
    "backend": Spec(kind="str", choices=BACKENDS, doc="how the kernel runs: compiled by numba, in Python, or 'auto'"),
}


def _check_autoreset_mode(value: Any) -> AutoresetMode:
    if isinstance(value, AutoresetMode):
        return value
    key = value.replace("_", "").lower() if isinstance(value, str) else None
    for mode in AutoresetMode:  # "NextStep", "NEXT_STEP", "next_step", ...
        if key == mode.value.lower():
            return mode
    choices = [m.value for m in AutoresetMode]
    raise ConfigError(
        f"autoreset_mode = {value!r} is not an autoreset mode{did_you_mean(value, choices)}: choose "
        f"gymnasium.vector.AutoresetMode.NEXT_STEP, SAME_STEP or DISABLED (or {', '.join(map(repr, choices))})",
        "autoreset_mode",
    )


def _check_reset_options(options: Any) -> tuple[dict[str, Any] | None, np.ndarray | None]:
    """The options for the copies' resets and the reset mask (``None``: every copy)."""
    if options is None:
        return None, None
    if not isinstance(options, Mapping):
        raise ConfigError(f"reset options must be a dict, got {options!r}", "options")
    unknown = sorted(set(options) - set(VECTOR_RESET_OPTIONS), key=str)
    if unknown:
        raise ConfigError(
            f"unknown reset option {unknown[0]!r}: allowed options are {list(VECTOR_RESET_OPTIONS)}", "options"
        )
    rest = {k: v for k, v in options.items() if k != "reset_mask"}
    return rest, options.get("reset_mask")


# ------------------------------------------------------------------ the vector env


class AuvSwiptVectorEnv(VectorEnv):
    """
    ## Description

    ``num_envs`` independent copies of ``swiptopt/AuvSwipt-v1`` (the grid, ``world="grid"``)
    or ``swiptopt/AuvSwiptContinuous-v0`` (``world="continuous"``) on one scenario, stepped
    together in one compiled call of the single env's own step function (see the module
    docstring). It behaves as ``gymnasium.vector.SyncVectorEnv`` over ``num_envs`` single
    envs made with the same arguments and the same ``autoreset_mode``: the same observations,
    rewards, terminations, truncations and infos, bit for bit.

    ## Action Space

    ``single_action_space`` is the single env's (``Discrete(7)`` on the grid, ``Box(-1, 1,
    (3,), float32)`` in the continuous world); ``action_space`` batches it
    (``MultiDiscrete([7] * num_envs)``, ``Box(-1, 1, (num_envs, 3), float32)``). Grid actions
    must be integers in [0, 6].

    ## Observation Space

    ``single_observation_space`` is the single env's; ``observation_space`` batches it: the
    ``vector`` observation as ``Box(-1, 1, (num_envs, 4 + 6 n_nodes), float32)``, the grid's
    ``tabular`` one as ``MultiDiscrete`` (int64). Each call returns fresh arrays.

    ## Starting State, Rewards, Episode End, Layouts

    Per copy, as the single env's: rewards are float64 (num_envs,), the sum of the step's
    reward parts. ``reset(seed=s)`` seeds copy i with ``s + i``, ``reset(seed=[...])`` each
    copy with its own seed (``None``: unseeded), and ``options`` go to every copy's reset
    (``{"layout_seed": k}``), with Gymnasium's ``reset_mask`` ((num_envs,) bool) resetting
    only some copies. With ``layout_seeds`` each copy draws its layout per episode from its
    own ``np_random``, as the single env does.

    ## Autoreset

    ``autoreset_mode`` (``metadata["autoreset_mode"]``): ``NEXT_STEP`` (the default: the
    step after an episode's end resets that copy, returning the reset observation with a
    reward of 0), ``SAME_STEP`` (the copy resets in the step that ends it; that step's
    observation and info are ``infos["final_obs"]`` and ``infos["final_info"]``), or
    ``DISABLED`` (reset ended copies with ``reset(options={"reset_mask": mask})``; stepping
    one is an error).

    ## Infos

    As ``SyncVectorEnv`` aggregates the single envs' infos: each key holds an array over the
    copies and ``infos["_key"]`` the mask of copies that gave it. ``reward_parts`` (a dict of
    (num_envs,) arrays), in the continuous world ``position`` ((num_envs, 3), m) and
    ``blocked``; at an episode's end ``episode_metrics`` (an object array of
    :class:`~swiptopt.env.EpisodeMetrics`); from resets ``cell`` (grid) or ``position``
    (continuous) and ``layout_seed``.

    ## Arguments

    ``AuvSwiptVectorEnv(num_envs, world="grid", scenario=None, *, preset=None,
    observation=None, layout_seeds=None, backend="auto", autoreset_mode=NEXT_STEP,
    render_mode=None, **overrides)``: a :class:`~swiptopt.Scenario`, or a preset name
    (``None``: the world's own, ``paper`` or ``harbour``) with scenario field overrides, as
    the single envs take them. ``observation``: one of the world's
    (:data:`swiptopt.worlds.OBSERVATIONS`; ``None``: its default, the grid's ``tabular``).
    ``backend``: ``"compiled"`` (numba), ``"python"`` (the same loop over the Python kernel,
    for tests) or ``"auto"``. No render modes. :attr:`scenario` is the scenario the copies
    were made with; :attr:`envs` are the copies' controllers: read their ``scenario`` (the
    copy's current layout), ``tables``/``world`` and ``state``, never step them.

    ## Version History

    - v0: initial version.
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(
        self,
        num_envs: int,
        world: str = GRID,
        scenario: Scenario | None = None,
        *,
        preset: str | None = None,
        observation: str | None = None,
        layout_seeds: Sequence[int] | None = None,
        backend: str = "auto",
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        render_mode: str | None = None,
        **overrides: Any,
    ):
        self.num_envs = n = check_value("num_envs", num_envs, ARGUMENTS["num_envs"])
        self.world = world = check_world(world)
        self.autoreset_mode = _check_autoreset_mode(autoreset_mode)
        observation = OBSERVATIONS[world][0] if observation is None else observation
        if observation not in OBSERVATIONS[world]:
            raise ConfigError(
                f"observation = {observation!r} is not offered in the {world} world: choose one of "
                f"{', '.join(map(repr, OBSERVATIONS[world]))}",
                "observation",
            )
        check_value("backend", backend, ARGUMENTS["backend"])
        if render_mode is not None:
            raise ConfigError(
                f"render_mode = {render_mode!r}: the vector env does not render (use None)", "render_mode"
            )
        if "max_episode_steps" in overrides:
            raise ConfigError(
                "max_episode_steps: the copies truncate at the scenario's episode_steps; set episode_steps instead",
                "max_episode_steps",
            )
        try:
            layout_seeds = check_layout_seeds(layout_seeds)
        except ConfigError as exc:  # a bad entry names itself; the argument is layout_seeds
            raise ConfigError(str(exc), "layout_seeds") from None
        if scenario is not None and not isinstance(scenario, Scenario):
            raise ConfigError(f"scenario must be a Scenario or None, got {type(scenario).__name__}", "scenario")
        if scenario is None:
            scenario = Scenario.preset(DEFAULT_PRESETS[world] if preset is None else preset, **overrides)
        elif overrides:
            scenario = scenario.replace(**overrides)
        self.observation = observation
        self.backend = backend = ("compiled" if numba_available() else "python") if backend == "auto" else backend
        kwargs = {"backend": backend, "layout_seeds": layout_seeds}
        if world == GRID:
            self.envs: list[Any] = [AuvSwiptEnv(scenario, observation=observation, **kwargs) for _ in range(n)]
            self._copies: _Copies = _GridCopies(self.envs, observation == "vector")
            name = "step_grid_copies" if observation == "vector" else "step_grid_tabular_copies"
        else:
            self.envs = [AuvSwiptContinuousEnv(scenario, **kwargs) for _ in range(n)]
            self._copies = _ContinuousCopies(self.envs)
            name = "step_continuous_copies"
        self._step_copies = compiled(name) if backend == "compiled" else globals()[name]
        self.scenario = scenario
        self.layout_seeds = self.envs[0].layout_seeds

        self.single_observation_space = self.envs[0].observation_space
        self.single_action_space = self.envs[0].action_space
        self.observation_space = batch_space(self.single_observation_space, n)
        self.action_space = batch_space(self.single_action_space, n)
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        self.render_mode = None
        self._autoreset = np.zeros(n, dtype=bool)  # copies whose episode ended
        self._started = np.zeros(n, dtype=bool)  # copies reset at least once
        self._all_started = False
        self._everyone = np.ones(n, dtype=bool)  # every copy steps (read-only)

    # ----------------------------------------------------------------- properties

    @property
    def np_random(self) -> tuple[np.random.Generator, ...]:
        """The copies' generators (as ``SyncVectorEnv``'s)."""
        return tuple(env.np_random for env in self.envs)

    @property
    def np_random_seed(self) -> tuple[int | None, ...]:
        return tuple(env.np_random_seed for env in self.envs)

    @property
    def positions(self) -> np.ndarray:
        """(num_envs, 3) the AUVs' positions, m (a copy): cell centres on the grid."""
        if self.world == CONTINUOUS:
            return self._copies.pos.copy()
        return self.scenario.cell_centers_m[self._copies.where[:, K.W_CELL]]

    # ----------------------------------------------------------------- reset

    def _seeds(self, seed: Any) -> list[int | None]:
        n = self.num_envs
        if seed is None:
            return [None] * n
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            return [int(seed) + i for i in range(n)]
        if isinstance(seed, (str, bytes, Mapping)) or not isinstance(seed, (Sequence, np.ndarray)) or len(seed) != n:
            raise ConfigError(f"seed must be None, an int or a list of {n} seeds (one per copy), got {seed!r}", "seed")
        return [None if s is None else int(s) for s in seed]

    def _reset_copy(self, i: int, seed: int | None, options: Mapping[str, Any] | None) -> dict[str, Any]:
        """Reset copy i through its controller; its observation into row i. Returns its info."""
        env = self.envs[i]
        obs, info = env.reset(seed=seed, options=options)
        self._copies.adopt(i, env)
        self._copies.obs[i] = obs
        self._autoreset[i] = False
        self._started[i] = True
        self._all_started = bool(self._started.all())
        return info

    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every copy (or those of ``options["reset_mask"]``): copy i with ``seed + i``
        or ``seed[i]``, each with ``options`` (see the class docstring). Returns the batched
        observations and the copies' reset infos, aggregated."""
        seeds = self._seeds(seed)
        options, mask = _check_reset_options(options)
        if mask is None:
            indices = range(self.num_envs)
        else:
            if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_ and mask.shape == (self.num_envs,)):
                raise ConfigError(f"options['reset_mask'] must be a ({self.num_envs},) bool numpy array, got {mask!r}",
                                  "reset_mask")
            if not mask.any():
                raise ConfigError("options['reset_mask'] resets no copy: set at least one True", "reset_mask")
            indices = np.flatnonzero(mask).tolist()
        infos: dict[str, Any] = {}
        for i in indices:
            infos = self._add_info(infos, self._reset_copy(i, seeds[i], options), i)
        return self._copies.obs.copy(), infos

    def reset_copies(
        self, seeds: Sequence[int | None], options: Sequence[Mapping[str, Any] | None]
    ) -> tuple[np.ndarray, list[dict[str, Any]]]:
        """Reset every copy, copy i with ``seeds[i]`` and ``options[i]`` (as SB3's vector
        envs reset, each copy with its own options). Returns the batched observations and
        each copy's reset info, unaggregated."""
        if len(seeds) != self.num_envs or len(options) != self.num_envs:
            raise ConfigError(f"reset_copies takes {self.num_envs} seeds and {self.num_envs} options", "seeds")
        infos = [self._reset_copy(i, seeds[i], options[i]) for i in range(self.num_envs)]
        return self._copies.obs.copy(), infos

    # ----------------------------------------------------------------- step

    def _actions(self, actions: Any) -> np.ndarray:
        n = self.num_envs
        if self.world == GRID:
            a = np.asarray(actions)
            ok = a.shape == (n,) and a.dtype.kind in "iuf"
            if ok and a.dtype.kind == "f":
                ok = bool(np.all(a == np.floor(a)))  # integral floats are actions; NaN is not
            if not (ok and a.min() >= 0 and a.max() < K.N_ACTIONS):
                raise ValueError(f"actions must be ({n},) integers in [0, {K.N_ACTIONS - 1}], "
                                 f"got {C.describe_array(actions)}")
            return a.astype(np.int64)
        return C.real_actions(actions, (n, C.ACTION_DIM))

    def _advance(self, actions: np.ndarray, active: np.ndarray | None) -> None:
        """Step the ``active`` copies (``None``: all): refill the draw buffers that need it
        from each copy's generator, then one call of the loop over the copies."""
        copies = self._copies
        refills = copies.refills if active is None else copies.refills & active
        if refills.any():
            for i in np.flatnonzero(refills).tolist():
                copies.refill(i, self.envs[i])
        copies.step(self._step_copies, actions, self._everyone if active is None else active)

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every copy (see Autoreset in the class docstring); returns the batched
        observations, rewards, terminations, truncations and infos."""
        if not self._all_started:
            raise RuntimeError("call reset() before step() (some copies were never reset)")
        a = self._actions(actions)
        copies, mode = self._copies, self.autoreset_mode
        waiting = self._autoreset.any()  # copies whose episode ended at the last step
        if waiting and mode is AutoresetMode.DISABLED:
            raise RuntimeError(
                f"copies {np.flatnonzero(self._autoreset).tolist()} ended their episodes: reset them first "
                "(reset(options={'reset_mask': mask}); autoreset_mode is DISABLED)"
            )
        resetting = self._autoreset.copy() if waiting else None  # NEXT_STEP: they reset instead of stepping
        active = None if resetting is None else ~resetting
        if active is None or active.any():
            self._advance(a, active)
        codes, parts = copies.codes, copies.parts
        terminated, truncated = codes == K.TERMINATED, codes == K.TRUNCATED
        # the single env's reward, (throughput + harvest) + movement, in its order of additions
        rewards = (parts[:, 0] + parts[:, 1]) + parts[:, 2]
        if active is not None:  # the resetting copies did not step: no reward, no end
            terminated &= active
            truncated &= active
            rewards[resetting] = 0.0
        done = terminated | truncated
        ended = np.flatnonzero(done).tolist() if done.any() else []
        same_step = mode is AutoresetMode.SAME_STEP
        infos = self._step_infos(active, done if same_step and ended else None)
        for i in ended:
            if same_step:
                final = {"final_obs": copies.obs[i].copy(), "final_info": self._step_info(i)}
                infos = self._add_info(infos, final, i)
                infos = self._add_info(infos, self._reset_copy(i, None, None), i)
            else:
                infos = self._add_info(infos, {INFO_KEY: self.envs[i].episode_metrics()}, i)
        if resetting is not None:
            for i in np.flatnonzero(resetting).tolist():
                infos = self._add_info(infos, self._reset_copy(i, None, None), i)
        if ended and not same_step:
            self._autoreset[ended] = True
        return copies.obs.copy(), rewards, terminated, truncated, infos

    def _step_infos(self, active: np.ndarray | None, final: np.ndarray | None) -> dict[str, Any]:
        """The step infos of the copies that stepped (``active``; ``None``: all), less those
        whose infos go to ``final_info`` (``final``; ``None``: none), aggregated as
        ``SyncVectorEnv`` does (built from the rows at once: zeros where a copy gave none)."""
        stepped = self._everyone if active is None else active
        if final is not None:
            stepped = stepped & ~final
        every = stepped is self._everyone or bool(stepped.all())
        if not every and not stepped.any():
            return {}

        def rows(values: np.ndarray) -> np.ndarray:
            if every:
                return values.copy()
            return np.where(stepped.reshape(-1, *([1] * (values.ndim - 1))), values, np.zeros((), values.dtype))

        parts = self._copies.parts
        reward_parts: dict[str, Any] = {}
        for k, name in enumerate(K.REWARD_PART_NAMES):
            reward_parts[name], reward_parts[f"_{name}"] = rows(parts[:, k]), stepped.copy()
        infos = {"reward_parts": reward_parts, "_reward_parts": stepped.copy()}
        if self.world == CONTINUOUS:
            infos["position"], infos["_position"] = rows(self._copies.pos), stepped.copy()
            infos["blocked"], infos["_blocked"] = rows(self._copies.blocked), stepped.copy()
        return infos

    def _step_info(self, i: int) -> dict[str, Any]:
        """The info the single env gives at copy i's last step (the episode's end)."""
        copies = self._copies
        info: dict[str, Any] = {"reward_parts": dict(zip(K.REWARD_PART_NAMES, copies.parts[i].tolist()))}
        if self.world == CONTINUOUS:
            info["position"] = copies.pos[i].copy()
            info["blocked"] = bool(copies.blocked[i])
        info[INFO_KEY] = self.envs[i].episode_metrics()
        return info

    # ----------------------------------------------------------------- the controllers

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call a method of every copy's controller (or read an attribute), as ``SyncVectorEnv``."""
        out = []
        for env in self.envs:
            value = env.get_wrapper_attr(name)
            out.append(value(*args, **kwargs) if callable(value) else value)
        return tuple(out)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """An attribute of every copy's controller."""
        return self.call(name)

    def set_attr(self, name: str, values: Any) -> None:
        """Set an attribute of the controllers (a list or tuple: one value each). The compiled
        step reads the vector env's own rows: this changes what the controllers hold, not
        the world the copies step in."""
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"set_attr takes one value or {self.num_envs} values, got {len(values)}")
        for env, value in zip(self.envs, values):
            env.set_wrapper_attr(name, value)

    def close_extras(self, **kwargs: Any) -> None:
        for env in self.envs:
            env.close()


def grid_vector_env(num_envs: int = 1, **kwargs: Any) -> AuvSwiptVectorEnv:
    """:class:`AuvSwiptVectorEnv` of the grid world: the ``vector_entry_point`` of
    ``swiptopt/AuvSwipt-v1``."""
    if "world" in kwargs:
        raise ConfigError("world: swiptopt/AuvSwipt-v1 is the grid world; make the other id for another", "world")
    return AuvSwiptVectorEnv(num_envs, GRID, **kwargs)


def continuous_vector_env(num_envs: int = 1, **kwargs: Any) -> AuvSwiptVectorEnv:
    """:class:`AuvSwiptVectorEnv` of the continuous world: the ``vector_entry_point`` of
    ``swiptopt/AuvSwiptContinuous-v0``."""
    if "world" in kwargs:
        raise ConfigError(
            "world: swiptopt/AuvSwiptContinuous-v0 is the continuous world; make the other id for another", "world"
        )
    return AuvSwiptVectorEnv(num_envs, CONTINUOUS, **kwargs)


__all__ = ["AuvSwiptVectorEnv", "continuous_vector_env", "grid_vector_env"]
