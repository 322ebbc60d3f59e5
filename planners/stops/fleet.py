"""The stop-choosing environment for a fleet: one policy makes every AUV's stop decisions, one
decision at a time, on :class:`swiptopt.env_fleet.AuvFleetEnv` (the grid world).

Each AUV runs the single AUV's decision process (:class:`~planners.stops.base.StopEpisode` over
the fleet's candidate stops, :class:`~planners.stops.grid.GridStops`) on its own view of the
fleet env (:class:`planners.fleet.AuvView`: its cell, the shared nodes). :class:`FleetStopEpisode` interleaves
them: it asks the AUVs whose assignment is done for a decision, in AUV order, and otherwise hands
out every AUV's next kernel action. :class:`FleetStopChoiceEnv` (Gymnasium) and
:class:`FleetStopChoicePolicy` (a trained model as a fleet policy) both drive one, so the model
plays the same episodes in either.

``import planners.stops`` does not need the ``fleet`` extra: PettingZoo loads when a
:class:`FleetStopChoiceEnv` is built.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from planners.fleet import AuvView
from planners.stops.base import CANDIDATE_FEATURES, DWELLS, Dwell, StopEnvBase, StopEpisode, cached_layout
from planners.stops.grid import GridMove, GridStops, GridStopSettings, build_grid_stops
from swiptopt import kernel as K
from swiptopt.env import INFO_KEY
from swiptopt.errors import ConfigError
from swiptopt.scenario import Scenario
from swiptopt.validation import Spec

#: Features per other AUV after the single AUV's stop observation: its position minus the
#: deciding AUV's (x, y, depth, over the extent), its target stop's cell minus the deciding
#: AUV's position (its own position when it has no assignment), the fraction of its
#: assignment left, and 1.0 while it is in the fleet (all eight 0 once it has left).
OTHER_AUV_STOP_FEATURES = 8


@dataclass(frozen=True)
class FleetStopSettings(GridStopSettings):
    """The choices of :class:`FleetStopChoiceEnv`: the single grid env's, and ``give_up_after``."""

    give_up_after: int | None = 3
    """An AUV whose move another AUV has blocked this many steps in a row gives its
    assignment up and decides again (None: it keeps trying)."""

    FIELDS: ClassVar[dict[str, Spec]] = {
        **GridStopSettings.FIELDS,
        "give_up_after": Spec(kind="int", lo=1, optional=True, strict=True, unit="steps"),
    }


# ----------------------------------------------------------------------------- one AUV


class AuvStopEpisode(StopEpisode):
    """One AUV's decisions in a fleet: the single AUV's :class:`StopEpisode` on its
    :class:`AuvView`, with the candidates other AUVs are heading to or dwelling at
    (``claimed``, set by :class:`FleetStopEpisode` before each decision) masked as well, and
    what the observation of the other AUVs needs (the assignment's target and length)."""

    def __init__(self, layout: GridStops, view: AuvView, dwells: tuple[Dwell, ...], masked_action: str):
        super().__init__(layout, view, dwells, masked_action)
        self.claimed = np.zeros(self.n_candidates, dtype=bool)
        self.planned = 1
        """The steps the current assignment takes at most, counted when it was decided."""
        self.blocked = 0
        """Steps in a row another AUV has blocked this AUV's move."""

    def _table(self) -> tuple[np.ndarray, np.ndarray]:
        table, reach = super()._table()
        if self.claimed.any():
            table = table & ~self.claimed[:, None]
        return table, reach

    def _why_masked(self, action: int) -> str:
        if action != self.fallback:
            c, d = self.decode(action)
            if self.layout.valid[c] and self.claimed[c]:
                return f"(stop {c}, dwell {self.dwells[d].label}): another AUV is heading to or dwelling at stop {c}"
        return super()._why_masked(action)

    def start(self, action: Any) -> bool:
        masked = super().start(action)
        c, d = self.last_decision
        if c < 0:
            self.planned = 1
        else:
            reach = int(self.layout.dist_to[c, self.env.state.cell])
            self.planned = reach + self.dwells[d].steps - (reach > 0)
        self.blocked = 0
        return masked

    def target(self) -> int:
        """The candidate of the current assignment; -1 when there is none (or it is the hover
        fallback)."""
        return self.last_decision[0] if self.move is not None else -1

    def fraction_left(self) -> float:
        """The steps the current assignment still takes at most, over :attr:`planned`; 0 with
        no assignment. Read while others decide, when the AUV's action for the coming step has
        been handed out already (:meth:`FleetStopEpisode.poll`): that step is counted. A
        blocked move does not shorten the way; an ``until`` dwell counts its longest."""
        move = self.move
        if move is None:
            return 0.0
        if not isinstance(move, GridMove):  # the hover fallback: its one step is the coming one
            return 1.0
        cell = self.env.state.cell
        if cell != move.target:
            left = int(self.layout.dist_to[self.last_decision[0], cell]) + move.dwell.steps - 1
        else:
            left = move.dwell.steps - move.service + 1
        return float(min(1.0, max(0.0, left / self.planned)))

    def give_up(self) -> None:
        """End the current assignment where the AUV is."""
        if self.move is not None:
            self.site = self.move.site_after
            self.move = None


# ----------------------------------------------------------------------------- the fleet


class FleetStopEpisode:
    """One episode of a fleet's stop decisions on an :class:`~swiptopt.env_fleet.AuvFleetEnv`
    (already reset): which AUV decides next, its observation and masks, and every AUV's next
    kernel action.

    :meth:`poll` before each fleet step: it returns the first AUV (in AUV order) whose
    assignment is done, which must then :meth:`decide`; once it returns None, :meth:`actions`
    gives every live AUV's kernel action for the step. :meth:`poll` asks every AUV for its
    next action before naming one to decide (a decision changes no AUV's next action), so
    all the AUVs waiting at a step are known before the first of them decides. The environment
    and :class:`FleetStopChoicePolicy` both drive one of these, so they decide from the same
    numbers.
    """

    def __init__(self, layout: GridStops, env: Any, settings: FleetStopSettings):
        self.layout = layout
        self.env = env
        self.give_up_after = settings.give_up_after
        n = env.fleet.n_auvs
        self.auvs = [AuvStopEpisode(layout, AuvView(env, k), settings.dwells, settings.masked_action)
                     for k in range(n)]
        self._next: list[Any] = [None] * n
        """Each AUV's kernel action for the coming step (None: not asked yet, or waiting)."""
        self._waiting = np.zeros(n, dtype=bool)
        self._t = -1
        """The step count :attr:`_next` is for."""
        self._sent: tuple[np.ndarray, list[Any]] | None = None
        """The cells and actions handed out for the step at ``_t``."""
        self.deciding: int | None = None
        """The AUV that must decide now (None: none)."""
        self.observer = 0
        """The AUV :meth:`observation` is for: the deciding one, else the last that decided."""
        self.given_up: list[int] = []
        """The AUVs that have given up a blocked assignment (the env clears it per decision)."""

    # ------------------------------------------------------------------ time

    def _sync(self) -> None:
        """After a fleet step: count blocked moves (give up after ``give_up_after``), drop the
        assignments of AUVs that have left the fleet, and forget the handed-out actions."""
        s = self.env.fleet_state
        if s.t == self._t:
            return
        if self._sent is not None:
            cells, actions = self._sent
            for k, auv in enumerate(self.auvs):
                if actions[k] is None or actions[k] == K.HOVER:
                    continue
                auv.blocked = auv.blocked + 1 if s.cells[k] == cells[k] else 0
                if self.give_up_after is not None and auv.blocked >= self.give_up_after and auv.move is not None:
                    auv.give_up()
                    auv.blocked = 0
                    self.given_up.append(k)
        for k, auv in enumerate(self.auvs):
            if not s.active[k]:
                auv.give_up()
        self._next = [None] * len(self.auvs)
        self._waiting[:] = False
        self._t, self._sent = s.t, None

    def poll(self) -> int | None:
        """The AUV that must decide before the fleet's next step (the first in AUV order whose
        assignment is done), or None when every AUV in the fleet has its next kernel action."""
        self._sync()
        active = self.env.fleet_state.active
        for k, auv in enumerate(self.auvs):
            if active[k] and self._next[k] is None and not self._waiting[k]:
                action = auv.next_action()
                if action is None:
                    self._waiting[k] = True
                else:
                    self._next[k] = action
        waiting = np.flatnonzero(self._waiting & active)
        self.deciding = int(waiting[0]) if waiting.size else None
        if self.deciding is not None:
            self.observer = self.deciding
        return self.deciding

    def actions(self) -> dict[str, int]:
        """Every live AUV's kernel action for the coming step (once :meth:`poll` returns None)."""
        if self.deciding is not None:
            raise RuntimeError(f"AUV {self.deciding} must decide first (poll() named it)")
        s = self.env.fleet_state
        self._sent = (s.cells.copy(), list(self._next))
        live = set(self.env.agents)
        return {a: int(self._next[k]) for k, a in enumerate(self.env.possible_agents) if a in live}

    # ------------------------------------------------------------------ deciding

    def _claim(self, k: int) -> AuvStopEpisode:
        """AUV ``k``'s episode with ``claimed`` set to the other AUVs' targets."""
        active = self.env.fleet_state.active
        auv = self.auvs[k]
        auv.claimed[:] = False
        for j, other in enumerate(self.auvs):
            c = other.target()
            if j != k and active[j] and c >= 0:
                auv.claimed[c] = True
        return auv

    def decide(self, action: Any) -> bool:
        """Start the deciding AUV's ``action``; returns whether it was masked (as
        :meth:`StopEpisode.start`)."""
        k = self.deciding
        if k is None:
            raise RuntimeError("no AUV waits for a decision (call poll() first)")
        auv = self._claim(k)
        masked = auv.start(action)
        first = auv.next_action()
        if first is None:  # the masks allow only decisions that take a step
            raise AssertionError(f"decision {action!r} took no kernel step")  # pragma: no cover
        self._next[k], self._waiting[k] = first, False
        self.deciding = None
        return masked

    def action_masks(self) -> np.ndarray:
        """The allowed actions of the AUV :attr:`observer` (the single env's masks, the
        candidates other AUVs are heading to or dwelling at masked too)."""
        return self._claim(self.observer).action_masks()

    def observation(self) -> np.ndarray:
        """The single AUV's stop observation for :attr:`observer` (from its cell), then
        :data:`OTHER_AUV_STOP_FEATURES` per other AUV, in the order k + 1, k + 2, ... (wrapping)."""
        k = self.observer
        own = self._claim(k).observation()
        return np.concatenate([own, self._others(k)]).astype(np.float32)

    def _others(self, k: int) -> np.ndarray:
        s = self.env.fleet_state
        norm = self.layout.cells_norm
        here = norm[s.cells[k]]
        n = len(self.auvs)
        out = np.zeros((n - 1, OTHER_AUV_STOP_FEATURES), dtype=np.float32)
        for i in range(1, n):
            j = (k + i) % n
            if not s.active[j]:
                continue
            there = norm[s.cells[j]]
            c = self.auvs[j].target()
            out[i - 1, 0:3] = there - here
            out[i - 1, 3:6] = (norm[self.layout.cells[c]] if c >= 0 else there) - here
            out[i - 1, 6] = self.auvs[j].fraction_left()
            out[i - 1, 7] = 1.0
        return out.ravel()

    def targets(self) -> list[int]:
        """Each AUV's current target candidate (-1: none)."""
        active = self.env.fleet_state.active
        return [auv.target() if active[k] else -1 for k, auv in enumerate(self.auvs)]


# ----------------------------------------------------------------------------- the env


class FleetStopChoiceEnv(StopEnvBase):
    """
    ## Description

    A fleet of AUVs (:class:`swiptopt.env_fleet.AuvFleetEnv`, grid world) decided one stop at
    a time by one policy, as :class:`~planners.stops.StopChoiceEnv` decides for one AUV. Each
    AUV carries out its own assignment (a candidate stop and a dwell): it moves along a
    shortest grid path to the stop, then hovers for the dwell, each move and hover its action
    in a step of the fleet env (the same kernel, the fleet's rules: AUVs move in index order,
    a move into another AUV's cell is blocked unless ``share_cells``).

    At reset every AUV needs a decision; the env asks for them in AUV order. After a decision
    the env steps the fleet, every AUV with an assignment executing it, until some AUV's
    assignment is done (it then needs a decision) or the fleet's episode ends. Decisions
    needed at the same step are asked one after another, in AUV order, without stepping, so
    no AUV waits for its decision through a step.
    ``info["next_auv"]`` (and :attr:`deciding_auv`) names the AUV the returned observation
    and :meth:`action_masks` are for.

    ## Action Space and Masks

    The single env's: ``Discrete(C * D + 1)``, action ``c * D + d`` sends the deciding AUV to
    candidate c with dwell ``dwells[d]``, the last action hovers one step. Masked as the single
    env's for the deciding AUV (from its cell: stops that do not exist, that it cannot reach,
    whose nodes are all served, or whose way and dwell do not fit the steps left), and also the
    candidates another AUV in the fleet is heading to or dwelling at, so two AUVs never have
    the same target. ``masked_action`` as the single env's.

    ## Observation Space

    ``Box(-1, 1, (4 + 6 n_nodes + 4 C + 8 (n_auvs - 1),), float32)``: the single env's
    observation for the deciding AUV k (the kernel's vector observation from its cell, then
    the 4 features per candidate, the "allowed" one after the claims above), then per other
    AUV j = k + 1, k + 2, ... (mod n_auvs) :data:`OTHER_AUV_STOP_FEATURES` = 8 values: its
    position minus AUV k's (x, y, depth over the extent), its target stop's cell minus AUV k's
    position (its own position when it has no assignment), the fraction of its assignment
    left (the steps it still takes at most, the coming step counted, over the steps it would
    take when it was decided; 0 without one) and 1.0 while it is in the fleet (all 8 are 0
    once it has left). With ``n_auvs = 1`` the observation is the single env's.

    ## Rewards and Episode End

    The reward of a decision is the fleet's reward (the sum of its AUVs' rewards) over the
    steps taken after it (0 when another AUV decides at the same step), so an episode's
    rewards sum to the fleet's return. The episode ends with the fleet's (every node served or
    every battery spent: terminated; ``episode_steps``: truncated), possibly in the middle of
    assignments. An AUV whose battery is spent leaves the fleet and is asked nothing more.
    ``info``: ``auv`` (who decided), ``next_auv``, ``kernel_steps``, the summed
    ``reward_parts``, ``stop``, ``dwell`` (-1 for the fallback), ``masked``, ``given_up``
    (whether some AUV gave a blocked assignment up in these steps) and ``given_up_auvs``;
    ``episode_metrics`` (the fleet's) at the end. :attr:`kernel_actions` lists each step's
    ``{agent: action}``.

    A move another AUV blocks is tried again at the next step; after ``give_up_after`` blocked
    steps in a row (default 3; None: never) the AUV gives its assignment up and decides again,
    so two AUVs meeting head-on on their paths do not wait for each other to the episode's end.

    ## Arguments

    ``FleetStopChoiceEnv(scenario=None, *, preset="paper", layout_seeds=None, backend="auto",
    render_mode=None, dwells=DWELLS, candidates="own+shared", shared_fraction=0.5,
    masked_action="raise", give_up_after=3, **overrides)``: the wrapped
    :class:`~swiptopt.env_fleet.AuvFleetEnv`'s scenario, preset, overrides (``n_auvs``,
    ``auv_start_cells``, ...), layouts, backend and render mode; :class:`FleetStopSettings`.
    The candidate stops are the single env's (:func:`~planners.stops.build_grid_stops`) over
    the cells some AUV can reach from its start cell. ``reset(seed=s)`` resets the fleet env
    with seed s, its only randomness: the same seed and actions give the same episode.
    """

    def __init__(
        self,
        scenario: Scenario | None = None,
        *,
        preset: str = "paper",
        layout_seeds: Sequence[int] | None = None,
        backend: str = "auto",
        render_mode: str | None = None,
        dwells: Sequence[Dwell | int] = DWELLS,
        candidates: str = "own+shared",
        shared_fraction: float = 0.5,
        masked_action: str = "raise",
        give_up_after: int | None = 3,
        **overrides: Any,
    ):
        from swiptopt.env_fleet import AuvFleetEnv

        self.settings = FleetStopSettings(tuple(dwells), candidates, shared_fraction, masked_action, give_up_after)
        self.env = AuvFleetEnv(scenario, preset=preset, observation="vector", render_mode=render_mode,
                               backend=backend, layout_seeds=layout_seeds, **overrides)
        self._init_spaces()

    @property
    def n_candidates(self) -> int:
        return self.env.scenario.n_nodes * self.settings.candidates_per_node

    @property
    def n_auvs(self) -> int:
        return self.env.fleet.n_auvs

    def _observation_size(self) -> int:
        single = 4 + K.VECTOR_NODE_FEATURES * self.env.scenario.n_nodes + CANDIDATE_FEATURES * self.n_candidates
        return single + OTHER_AUV_STOP_FEATURES * (self.n_auvs - 1)

    @classmethod
    def build_layout(cls, env: Any, settings: GridStopSettings) -> GridStops:
        """The candidate stops of the fleet env's layout, over the cells its AUVs can reach."""
        fleet = env.fleet
        return build_grid_stops(fleet.tables, env.scenario, settings, starts=[int(c) for c in fleet.start_cells])

    @property
    def deciding_auv(self) -> int:
        """The AUV the last observation and :meth:`action_masks` are for."""
        if self._episode is None:
            raise RuntimeError("call reset() first")
        return self._episode.observer

    def targets(self) -> list[int]:
        """Each AUV's current target candidate (-1: none)."""
        if self._episode is None:
            raise RuntimeError("call reset() first")
        return self._episode.targets()

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Reset the fleet env (the same seed and options) and return AUV 0's first
        observation; ``info``: ``layout_seed``, the AUVs' ``cells`` and ``next_auv``."""
        gym.Env.reset(self, seed=seed)
        _, infos = self.env.reset(seed=seed, options=options)
        self.scenario = self.env.scenario
        self._episode = FleetStopEpisode(self.stops_layout(), self.env, self.settings)
        self._done = False
        self.kernel_actions = []
        self._episode.poll()
        first = infos[self.env.possible_agents[0]]
        info = {"layout_seed": first["layout_seed"], "cells": [int(i["cell"]) for i in infos.values()],
                "next_auv": self._episode.observer}
        return self._episode.observation(), info

    def step(self, action: Any):
        if self._done or self._episode is None:
            raise RuntimeError("call reset() before step() (the episode has ended)")
        episode = self._episode
        episode.given_up = []
        auv = episode.deciding
        masked = episode.decide(action)
        stop, dwell = episode.auvs[auv].last_decision
        total, parts, steps, truncated, metrics = self._advance()
        info: dict[str, Any] = {
            "auv": auv,
            "next_auv": episode.observer,
            "kernel_steps": steps,
            "reward_parts": parts,
            "stop": stop,
            "dwell": dwell,
            "masked": masked,
            "given_up": bool(episode.given_up),
            "given_up_auvs": list(episode.given_up),
        }
        if metrics is not None:
            info[INFO_KEY] = metrics
        terminated = self._done and not truncated
        return episode.observation(), total, terminated, truncated, info

    def _advance(self) -> tuple[float, dict[str, float], int, bool, Any]:
        """Step the fleet until some AUV must decide or the episode ends: (the fleet's reward
        over those steps, its parts, the steps, whether the episode was truncated, the
        episode's metrics at its end, else None)."""
        episode = self._episode
        total = 0.0
        parts = dict.fromkeys(K.REWARD_PART_NAMES, 0.0)
        steps = 0
        while episode.poll() is None:
            actions = episode.actions()
            _, rewards, _, truncations, infos = self.env.step(actions)
            self.kernel_actions.append(actions)
            steps += 1
            for agent, reward in rewards.items():
                total += reward
                for name, value in infos[agent]["reward_parts"].items():
                    parts[name] += value
            if not self.env.agents:
                self._done = True
                metrics = next(i[INFO_KEY] for i in infos.values() if INFO_KEY in i)
                return total, parts, steps, any(truncations.values()), metrics
        return total, parts, steps, False, None


# ----------------------------------------------------------------------------- the adapter


class FleetStopChoicePolicy:
    """A stop-choice model trained on :class:`FleetStopChoiceEnv` (a ``sb3_contrib.MaskablePPO``,
    or anything with ``predict(obs, deterministic=..., action_masks=...)``) as a fleet policy
    on the plain :class:`~swiptopt.env_fleet.AuvFleetEnv`, for
    :func:`swiptopt.evaluation.evaluate_fleet`.

    ``begin_episode(env, observations, infos)`` takes the fleet env after its reset;
    ``act(observations)`` then returns every live AUV's kernel action: while AUVs carry out
    their assignments, their next moves or hovers; when some AUV's is done, the model decides
    for it from the same observation and masks the environment gives (the same
    :class:`FleetStopEpisode`), AUV by AUV. So ``evaluate_fleet(policy, fleet_env, ...)`` plays
    exactly the episodes the model plays in the environment on the same seeds. The fleet
    env's ``observations`` are not read.

    ``settings``: the environment's :class:`FleetStopSettings`; :meth:`from_env` copies them.
    """

    def __init__(self, model: Any, settings: FleetStopSettings, *, deterministic: bool = True):
        if not hasattr(model, "predict"):
            raise ConfigError(f"model {type(model).__name__} has no predict(obs, deterministic, action_masks)", "model")
        self.model = model
        self.settings = settings
        self.deterministic = deterministic
        self._layouts: dict[str, Any] = {}
        self._episode: FleetStopEpisode | None = None

    @classmethod
    def from_env(cls, model: Any, env: Any, *, deterministic: bool = True) -> FleetStopChoicePolicy:
        """The adapter for a model trained on ``env`` (a :class:`FleetStopChoiceEnv`, possibly wrapped)."""
        return cls(model, getattr(env, "unwrapped", env).settings, deterministic=deterministic)

    def begin_episode(self, env: Any, observations: Any = None, infos: Any = None) -> None:
        layout = cached_layout(self._layouts, env.scenario,
                               lambda: FleetStopChoiceEnv.build_layout(env, self.settings))
        self._episode = FleetStopEpisode(layout, env, self.settings)

    def act(self, observations: Any = None) -> dict[str, int]:
        """Every live AUV's kernel action (see the class docstring)."""
        episode = self._episode
        if episode is None:
            raise RuntimeError("call begin_episode(env, observations, infos) after each reset "
                               "(swiptopt.evaluation.evaluate_fleet does)")
        while episode.poll() is not None:
            decision = self.model.predict(
                episode.observation(), deterministic=self.deterministic, action_masks=episode.action_masks()
            )
            episode.decide(decision[0] if isinstance(decision, tuple) else decision)
        return episode.actions()
