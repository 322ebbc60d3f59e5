"""The continuous world's Gymnasium environment: the AUV at any 3D position, velocity commands.

Registered as ``swiptopt/AuvSwiptContinuous-v0`` (``import swiptopt`` registers it). Every
step goes through :func:`swiptopt.continuous.step`, the function the continuous planners'
executors use as well; it ends in the grid kernel's own serving code.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from swiptopt import continuous as C
from swiptopt import kernel as K
from swiptopt.env import INFO_KEY, EpisodeMetrics, LayoutEnv
from swiptopt.metrics import episode_metrics
from swiptopt.scenario import Scenario


class AuvSwiptContinuousEnv(LayoutEnv):
    """
    ## Description

    The model of ``swiptopt/AuvSwipt-v1`` in continuous space (docs/design.md, 'The two worlds'): the AUV
    has a 3D position and moves along straight segments in any direction, stopped by
    obstacles (boxes, spheres), the seabed and the volume's boundary. Coverage (cone, range,
    SNR threshold), the link budget, data and energy are computed from the actual position
    every step; propulsion energy from the speed through the water against the scenario's
    current at the AUV's depth. The default preset is ``harbour`` (a pier, a moored hull, a
    wreck, a sloping seabed and a tidal current), where straight lines are wrong.

    ## Action Space

    ``Box(-1, 1, (3,), float32)``: a move command (x, y, depth; depth grows downwards). The
    AUV moves by ``cell_size_m * a / max(1, |a|)``, i.e. at ground velocity
    ``speed_mps * a / max(1, |a|)`` for the step's duration ``cell_size_m / speed_mps``:
    ``cell_size_m`` is the reach of one step here, not a lattice. It stops
    :data:`~swiptopt.continuous.STOP_SHORT_M` before the first contact on the way; a
    stopped move still costs the whole attempt (as a blocked grid move does). ``a = 0``
    hovers (station keeping).

    ## Observation Space

    ``Box(-1, 1, (4 + 6 n_nodes,), float32)``: the grid env's ``vector`` observation at the
    actual position: the AUV position over the volume's extent, the fraction of the episode
    left, and per node its position relative to the AUV over the extent, the fraction of its
    data left, its state of charge and whether it is covered now.

    ## Starting State

    The AUV at the centre of the scenario's start cell (default: the surface cell at the
    centre of the area), every node with its data and initial charge from the layout.

    ## Rewards, Episode End, Layouts

    As ``swiptopt/AuvSwipt-v1``: the same reward parts (``info["reward_parts"]``), the same
    end of episode, the same metrics under ``info["episode_metrics"]`` at the last step, the
    same layouts per episode (``layout_seeds``, ``reset(options={"layout_seed": k})``). The
    steps-to-target metrics count the nodes some free position covers
    (:func:`swiptopt.continuous.coverable_nodes`). Each step's info also holds
    ``position`` (m) and ``blocked`` (the move stopped short).

    ## Arguments

    ``AuvSwiptContinuousEnv(scenario=None, *, preset="harbour", render_mode=None,
    backend="auto", layout_seeds=None, **overrides)``. ``render_mode="rgb_array"`` draws a
    top view and a depth view with the obstacles and the path.

    ## Version History

    - v0: initial version.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(
        self,
        scenario: Scenario | None = None,
        *,
        preset: str = "harbour",
        render_mode: str | None = None,
        backend: str = "auto",
        layout_seeds: Sequence[int] | None = None,
        **overrides: Any,
    ):
        self.backend = backend = self._setup(scenario, preset, overrides, render_mode, backend, layout_seeds)
        scenario = self.scenario
        self.world = C.build_world(scenario)
        self._layouts = OrderedDict([(scenario.layout_seed, (scenario, self.world))])
        if backend == "compiled":
            self._step, self._observe = C.compiled("step_observe"), C.compiled("observe")
        else:
            self._step, self._observe = C.step_observe, C.observe
        n = scenario.n_nodes
        self.action_space = spaces.Box(-1.0, 1.0, (C.ACTION_DIM,), dtype=np.float32)
        self.observation_space = spaces.Box(-1.0, 1.0, (4 + K.VECTOR_NODE_FEATURES * n,), dtype=np.float32)
        self._obs = np.empty(self.observation_space.shape, dtype=np.float32)
        self._cov = (np.empty(n, dtype=np.int64), np.empty(n), np.empty(n))
        self._action = np.zeros(C.ACTION_DIM)
        self._uniforms, self._normals = K.noise_buffers(self.world)
        self._pos = self.world.start_m.copy()
        self._done = True  # until the first reset
        self.state: K.EpisodeState | None = None
        self._path: list[np.ndarray] = []
        self._set_layout(self.world)

    # ----------------------------------------------------------------- layouts

    def _build_layout(self, scenario: Scenario) -> C.World:
        return C.with_layout(self.world, scenario)

    def _set_layout(self, world: C.World) -> None:
        self.world = world
        s = self.scenario
        self._nodes_norm = np.ascontiguousarray(s.layout.positions_m / s.extent_m)
        if self.state is not None:
            self._bind()

    def _bind(self) -> None:
        """The arguments of the step function after (action, uniforms, normals), in order."""
        w, st = self.world, self.state
        self._args = (
            w.world, w.boxes, w.spheres, w.seabed, w.nodes_m, *self._cov, w.capacity, w.fail_prob, w.params,
            self._pos, st.where, st.data_left, st.energy, st.delivered, st.collected, st.acc, st.parts,
            w.data0, self._nodes_norm, self._obs,
        )

    # ----------------------------------------------------------------- gym API

    @property
    def position(self) -> np.ndarray:
        """The AUV's position (x, y, depth), m (a copy)."""
        return self._pos.copy()

    @property
    def path(self) -> np.ndarray:
        """(k, 3) the positions of this episode so far, the start first, m."""
        return np.array(self._path).reshape(-1, 3)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode; ``options={"layout_seed": k}`` runs it on layout ``k``. Returns
        the observation and ``{"position", "layout_seed"}``."""
        super().reset(seed=seed)
        layout_seed = self._episode_layout_seed(options)
        if layout_seed != self.scenario.layout_seed:
            self._use_layout(layout_seed)
        w = self.world
        if self.state is None or seed is not None:
            self.state = K.new_state(w)  # fresh draws from the reseeded generator
        else:
            K.reset_state(w.start_cell, w.data0, w.energy0, w.params, *K._state_arrays(self.state))
        self._pos[:] = w.start_m
        self._bind()
        self._refill = K.needs_refill(
            self.state.where, w.n_nodes, self._uniforms.shape[0], self._normals.shape[0], w.normal_rows
        )
        self._done = False
        self._path = [self._pos.copy()]
        self._observe(w.world, w.nodes_m, self._pos, self.state.where, *self._cov, self.state.data_left,
                      self.state.energy, w.data0, w.capacity, w.params, self._nodes_norm, self._obs)
        return self._obs.copy(), {"position": self._pos.copy(), "layout_seed": self.scenario.layout_seed}

    def step(self, action):
        if self._done:
            raise RuntimeError("call reset() before step() (the episode has ended)")
        self._action[:] = C.real_actions(action, (C.ACTION_DIM,))
        if self._refill:
            K.refill_noise(self.np_random, self.world, self._uniforms, self._normals, self.state.where)
        code, blocked, self._refill = self._step(self._action, self._uniforms, self._normals, *self._args)
        throughput, harvest, movement = self.state.parts.tolist()
        self._path.append(self._pos.copy())
        info: dict[str, Any] = {
            "reward_parts": {"throughput": throughput, "harvest": harvest, "movement": movement},
            "position": self._pos.copy(),
            "blocked": bool(blocked),
        }
        if code:
            self._done = True
            info[INFO_KEY] = self.episode_metrics()
        return self._obs.copy(), throughput + harvest + movement, code == K.TERMINATED, code == K.TRUNCATED, info

    def episode_metrics(self) -> EpisodeMetrics:
        """The metrics of the episode so far (at its end, those of ``info["episode_metrics"]``)."""
        if self.state is None:
            raise RuntimeError("call reset() before episode_metrics()")
        return EpisodeMetrics(episode_metrics(self.world, self.state))

    # ----------------------------------------------------------------- rendering

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array'")
            return None
        if self.state is None:
            raise RuntimeError("call reset() before render()")
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        from swiptopt.plotting import draw_world

        fig = Figure(figsize=(8, 4), dpi=80)
        canvas = FigureCanvasAgg(fig)
        top, side = fig.subplots(1, 2)
        draw_world(self.scenario, top, side, paths={"AUV": self.path})
        fig.suptitle(f"t = {self.state.t}")
        fig.tight_layout()
        canvas.draw()
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()
