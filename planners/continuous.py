"""Planners in the continuous world (issue 16, SPEC 8): hover points anywhere in the water,
a tour over them, dwells from the convex program, and an executor of velocity actions.

:class:`OmplTourPlanner` and :class:`StraightLinePlanner` are policies for
:class:`swiptopt.env_continuous.AuvSwiptContinuousEnv` (``begin_episode`` + ``predict``), so
:func:`swiptopt.evaluate` scores them like any agent. They share every step but the legs:

1. **Hover points.** The nodes some position can cover
   (:func:`swiptopt.continuous.coverable_nodes`) are grouped by k-means (scikit-learn, seeded as
   :func:`planners.clustering.kmeans_hover_points` seeds it). Each group's hover point starts
   at the best of a few points above the group (its centroid and its members, at a few
   depths) and is then moved by a deterministic compass search (the six axis moves, the step
   halved when none improves, a fixed number of evaluations) to maximise what one step of
   hovering there earns from the group: the simulator's per-step reward, priced by
   :func:`planners.service.step_model` (the kernel's own rate and harvest functions, on the
   mean channel, link failures counted) on the SNR and available power that
   :func:`swiptopt.continuous.coverage_at` gives there, less the cost of holding station.
   Every hover point keeps ``clearance_m`` from the obstacles, the seabed and the volume's faces.
2. **Legs** between every pair of stops (the start and the hover points). OMPL tour: the
   straight segment when it keeps ``clearance_m`` from everything (``ompl_legs="blocked"``,
   the default: OMPL's own simplifier reduces such a leg to it anyway, up to the current's
   depth shear), else the AUV-energy path from :func:`planners.paths3d.plan_path_3d` around
   the obstacles and against the current, stopped after ``ompl_iterations`` iterations (a
   count, never the wall clock). ``ompl_legs="all"`` asks OMPL for every leg and keeps the
   cheaper of its path and the free straight segment. One plan per pair of stops serves both
   directions (its waypoints reversed); each direction is priced on its own, because the
   current makes the energy asymmetric. A pair OMPL cannot join exactly (an approximate path,
   a timeout) falls back to the straight segment, recorded in the leg's ``source``, at
   :data:`BLOCKED_COST_FACTOR` times the dearest leg, so that the tour avoids it.
   Straight line: the straight segment for every pair, obstacles and current ignored.
3. **Tour**: the open path from the start over the hover points minimising the legs' energy
   (OMPL tour) or length (straight line), by :func:`planners.tsp.solve_tsp`.
4. **Dwell**: the time left after travel (the legs' steps) goes to the stops by the convex
   program :func:`planners.power_split.optimise_dwell_and_split` with the split fixed at the
   one the simulator applies (the env's actions cannot set it), rounded to whole steps; the
   step that arrives at a stop serves it too and counts as its first. The program models the
   power-split downlink with the linear harvester; with the logistic harvester or the uplink
   its dwells are a heuristic (the model return still prices them as the simulator does). Stops beyond the
   episode are dropped; then stops are dropped one at a time while the plan earns no less
   without them (as :class:`planners.reward_tour.RewardKMeansTspPlanner` prunes on the grid).
5. **K**: every K from 1 to ``k_max`` (or the given ``k``) is planned and the plan whose whole
   trajectory earns most in the per-step model is kept. The model return of a plan runs the
   executor itself over model positions (the env's own motion rule, :func:`velocity_of`):
   each step's movement penalty from :func:`swiptopt.continuous.propulsion_energy_j`, each
   step's service from where it ends. With a deterministic channel and no link failures this
   is the env's return for the OMPL tour (a test replays it); with fading it is the
   expected-rate relaxation of :mod:`planners.service`.

**Executor.** Velocity actions from :func:`swiptopt.continuous.action_towards`: along each
leg, straight at the next waypoint, at most one step's length at a time and never past the
waypoint (a sub-segment of a valid segment is valid, so the AUV stays on the planned path);
then the stop's dwell as hover actions (zero velocity); after the last stop it hovers. A
commanded move that makes no progress (the env stopped it at an obstacle) gives up that stop:
the executor goes on to the next one, straight from where it is. This is the straight-line
planner's rule (its legs ignore obstacles and stop where they collide); the OMPL tour's legs
are free, so it never applies there (``given_up_`` records it if it does).

Reproducibility. k-means and the compass search are seeded and counted; the TSP stops on a
deterministic budget; OMPL draws from one process-wide generator (:mod:`planners.paths3d`):
the planner passes ``seed + 1`` (what the benchmark's fresh OMPL process is seeded with) and
plans each layout once (cached), so the same seed and layouts give the same plans in a fresh
process. A second planner seed in the same process is refused by ``plan_path_3d``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import numbers
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from planners.paths3d import CRASHING_PLANNERS, NO_PYTHON_OBJECTIVE_PLANNERS, PLANNERS
from swiptopt import kernel as K
from swiptopt.errors import ConfigError

OMPL_LEGS = ("blocked", "all")

#: The largest planner seed: OMPL is seeded with seed + 1, which must be below 2**32.
MAX_SEED = 2**32 - 2

#: A leg that stays blocked (OMPL found no exact path) costs this many times the dearest
#: leg in the tour's matrix, so that the tour uses it only when it must.
BLOCKED_COST_FACTOR = 100.0

#: A waypoint counts as reached within this distance, m. The env's actions are float32, so
#: a step aimed exactly at a waypoint lands within about 1e-6 m of it.
ARRIVAL_TOLERANCE_M = 1e-3

#: A commanded move shorter than this, m, is no progress (the env stopped it at contact).
NO_PROGRESS_M = 1e-6

#: When no start above a group keeps the clearance, its search starts from this many of the
#: free cell centres nearest the group's centroid.
FALLBACK_STARTS = 8

#: Depth levels tried above each starting (x, y) of a hover point's search.
START_DEPTH_LEVELS = 4

#: The compass search stops once its step is below this, m.
SEARCH_MIN_STEP_M = 0.25


# ----------------------------------------------------------------------------- plans


@dataclass(frozen=True, eq=False)
class Leg:
    """The way from one stop (or the start) to the next."""

    waypoints_m: np.ndarray
    """(k, 3) metres (x, y, depth), from the previous stop to this one."""
    energy_j: float
    """AUV energy along it at ground speed under the current (:func:`planners.paths3d.path_energy_j`), J."""
    steps: int
    """Steps the executor takes along it (each segment in steps of at most one step's length)."""
    source: str
    """``"straight"`` (the free straight segment), ``"ompl"`` (OMPL's exact path), ``"straight
    (OMPL <status>)"`` (OMPL found no exact path: the straight segment, blocked), or
    ``"straight (obstacles ignored)"`` (the straight-line planner)."""


@dataclass(frozen=True, eq=False)
class OmplCall:
    """One OMPL plan between two stops (:func:`planners.paths3d.plan_path_3d`)."""

    start_m: np.ndarray
    goal_m: np.ndarray
    status: str
    """``"exact"``, ``"approximate"``, ``"timeout"``, ... (:class:`planners.paths3d.PathResult`)."""
    energy_j: float
    """Energy of OMPL's path, J (``inf`` without one)."""
    used: bool
    """Whether the leg takes OMPL's path (else the straight segment: free and cheaper, or the
    blocked fallback when OMPL found no exact path)."""


@dataclass(frozen=True, eq=False)
class ContinuousPlan:
    """What a continuous planner planned for one layout."""

    k: int
    """Number of k-means groups of the kept plan (before pruning)."""
    hover_points_m: np.ndarray
    """(S, 3) the stops in tour order, m."""
    groups: tuple[np.ndarray, ...]
    """Per stop, the nodes its hover point was placed for."""
    legs: tuple[Leg, ...]
    """Per stop, the leg that reaches it."""
    dwell_steps: np.ndarray
    """(S,) hover steps at each stop after the arrival step."""
    dwell_value: float | None
    """The dwell program's objective (weighted service of the dwells, continuous time)."""
    dwell_status: str
    """The dwell program's status (:class:`planners.power_split.PowerSplitResult`)."""
    model_return: float
    """The planned trajectory's return in the per-step model (module docstring, step 5)."""
    positions_m: np.ndarray
    """(T + 1, 3) the planned position after each step, the start first, m."""
    actions: np.ndarray
    """(T, 3) float32 the planned actions."""
    status: str
    """How the plan was made: the tour's status, the dwell's, what was dropped."""
    candidates: dict[int, float] = field(default_factory=dict)
    """Model return of the best plan for every K tried."""
    ompl_plans: tuple[OmplCall, ...] = ()
    """Every OMPL plan made for this layout (over every K tried), in order."""

    @property
    def ompl_statuses(self) -> dict[str, int]:
        """How many of :attr:`ompl_plans` ended in each status."""
        counts: dict[str, int] = {}
        for call in self.ompl_plans:
            counts[call.status] = counts.get(call.status, 0) + 1
        return counts


# --------------------------------------------------------------------- the step model


def point_model(world: Any, points_m: np.ndarray, *, mean_channel: bool = False) -> Any:
    """The per-step model (:class:`planners.service.StepModel`) with the given points as its
    "cells": a step ending at point c serves the nodes :func:`swiptopt.continuous.coverage_at`
    covers from it, priced by the kernel's functions; staying there costs holding station.

    ``points_m``: (m, 3). Only the service amounts and the stay costs are meaningful (there
    are no moves between the points). ``mean_channel``: price the mean channel (no fading;
    link failures still scale the data) instead of the expectation over the fading, which
    costs a quadrature per call: the hover-point search ranks many points with it.
    """
    from planners.service import step_model
    from swiptopt.continuous import coverage_at, propulsion_energy_j

    points = np.asarray(points_m, dtype=float).reshape(-1, 3)
    m = len(points)
    nodes, snr, pav, counts = [], [], [], np.zeros(m, dtype=np.int64)
    hover_j = np.empty(m)
    for c, p in enumerate(points):
        covered, snr_c, pav_c = coverage_at(world, p)
        nodes.append(np.asarray(covered, dtype=np.int64))
        snr.append(np.asarray(snr_c, dtype=float))
        pav.append(np.asarray(pav_c, dtype=float))
        counts[c] = len(nodes[-1])
        hover_j[c] = propulsion_energy_j(world, p, np.zeros(3))
    cov_ptr = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(counts, out=cov_ptr[1:])
    params = np.asarray(world.params, dtype=float)
    if mean_channel:
        params = params.copy()
        params[K.P_CHANNEL] = K.CHANNEL_CODES["none"]
    tables = K.Tables(
        next_cell=np.repeat(np.arange(m, dtype=np.int64)[:, None], K.N_ACTIONS, axis=1),
        moved=np.zeros((m, K.N_ACTIONS), dtype=bool),
        propulsion_j=np.repeat(hover_j[:, None], K.N_ACTIONS, axis=1),
        cov_ptr=cov_ptr,
        cov_node=np.concatenate(nodes) if m else np.zeros(0, dtype=np.int64),
        cov_snr=np.concatenate(snr) if m else np.zeros(0),
        cov_pav=np.concatenate(pav) if m else np.zeros(0),
        data0=np.asarray(world.data0, dtype=float),
        energy0=np.asarray(world.energy0, dtype=float),
        capacity=np.asarray(world.capacity, dtype=float),
        fail_prob=np.asarray(world.fail_prob, dtype=float),
        params=params,
        start_cell=0,
        n_cells=m,
        n_nodes=int(world.n_nodes),
        draws_uniforms=bool(np.any(np.asarray(world.fail_prob) > 0)),
        normal_rows=int(world.params[K.P_NORMAL_ROWS]),
    )
    return step_model(tables)


def hover_values(world: Any, points_m: np.ndarray, group: np.ndarray) -> np.ndarray:
    """(m,) what one step of hovering at each point earns from the nodes of ``group`` (fresh:
    all their data and storage room left), less the cost of holding station there, on the
    mean channel (link failures counted, fading not: see :func:`point_model`)."""
    model = point_model(world, points_m, mean_channel=True)
    member = np.zeros(model.n_nodes)
    member[np.asarray(group, dtype=np.int64)] = 1.0
    per_pair = (model.data_weight * model.bits + model.energy_weight * model.joules) * member[model.cov_node]
    earned = np.bincount(model.cell_of_pair(), weights=per_pair, minlength=model.n_cells)
    return earned - model.stay_cost


def trajectory_return(world: Any, positions_m: np.ndarray, actions: np.ndarray) -> float:
    """The return of a trajectory in the per-step model: ``positions_m`` (T + 1, 3) the start
    and the position after each step, ``actions`` (T, 3) the actions taken.

    Each step costs the env's movement penalty (propulsion from the step's start at the
    commanded velocity, plus hotel) and earns the service of where it ends, each node capped
    at what it still holds and can store; the trajectory stops once every node is served, as
    the env does.
    """
    from swiptopt.continuous import propulsion_energy_j, velocity_of

    p = world.params
    model = point_model(world, positions_m[1:])
    data_left = model.data_bits.copy()
    room_left = model.room_j.copy()
    total = 0.0
    for t, action in enumerate(actions):
        velocity = velocity_of(action, world.speed_mps)
        move_j = propulsion_energy_j(world, positions_m[t], velocity) + p[K.P_HOTEL_J]
        total -= p[K.P_LAMBDA] * move_j / p[K.P_MOVE_REF]
        gained = model.serve(t, data_left, room_left)
        total += gained
        if gained > 0.0 and model.all_served(data_left, room_left):
            break
    return float(total)


# ------------------------------------------------------------------------- executor


class _Follower:
    """Turns a plan's legs and dwells into actions, one per call, from the current position.

    One piece of code serves the env (:meth:`_ContinuousTourPlanner.predict`) and the model
    (:meth:`_ContinuousTourPlanner._rollout`), so the model scores what the executor does.
    """

    def __init__(self, legs: tuple[Leg, ...], dwell_steps: np.ndarray, max_step_m: float):
        self.legs = legs
        self.dwell = [int(d) for d in dwell_steps]
        self.max_step_m = max_step_m
        self.stop = 0  # the stop being reached or served
        self.waypoint = 1  # next waypoint of the current leg
        self.hovered = 0  # hover steps spent at the current stop
        self.last: tuple[np.ndarray, np.ndarray] | None = None  # (position, target) of the last move
        self.given_up: list[int] = []

    def action(self, position_m: np.ndarray) -> np.ndarray:
        from swiptopt.continuous import action_towards

        position = np.asarray(position_m, dtype=float)
        while self.stop < len(self.legs):
            waypoints = self.legs[self.stop].waypoints_m
            if self.waypoint < len(waypoints):
                target = waypoints[self.waypoint]
                if np.linalg.norm(target - position) <= ARRIVAL_TOLERANCE_M:
                    self.waypoint += 1
                    continue
                if self.last is not None and np.array_equal(self.last[1], target) and (
                    np.linalg.norm(position - self.last[0]) < NO_PROGRESS_M
                ):
                    # the last move towards this waypoint was stopped by an obstacle: give up the stop
                    self.given_up.append(self.stop)
                    self._next_stop(from_here=True)
                    continue
                self.last = (position.copy(), target)
                return np.asarray(action_towards(position, target, self.max_step_m), dtype=np.float32)
            if self.hovered < self.dwell[self.stop]:
                self.hovered += 1
                self.last = None
                return np.zeros(3, dtype=np.float32)
            self._next_stop(from_here=False)
        self.last = None
        return np.zeros(3, dtype=np.float32)

    def _next_stop(self, *, from_here: bool) -> None:
        self.stop += 1
        self.hovered = 0
        self.last = None
        # after giving up, steer straight at the next stop (its leg starts where we did not get)
        self.waypoint = 1
        if from_here and self.stop < len(self.legs):
            self.waypoint = len(self.legs[self.stop].waypoints_m) - 1


# ------------------------------------------------------------------------- planners


def _integer(name: str, value: Any, *, low: int, optional: bool = False) -> int | None:
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < low:
        extra = " (or None)" if optional else ""
        raise ConfigError(f"{name} = {value!r} must be an integer >= {low}{extra}", name)
    return int(value)


def _real(name: str, value: Any, *, unit: str, positive: bool = True) -> float:
    ok = not isinstance(value, bool) and isinstance(value, numbers.Real) and math.isfinite(value)
    if not ok or value < 0 or (positive and value == 0):
        bound = "> 0" if positive else ">= 0"
        raise ConfigError(f"{name} = {value!r} must be a finite number {bound} ({unit})", name)
    return float(value)


class _ContinuousTourPlanner:
    """The shared pipeline (module docstring); subclasses choose the legs."""

    #: What the tour minimises over the legs: ``"energy_j"`` or ``"length"``.
    tour_cost = "energy_j"

    def __init__(
        self,
        seed: int = 0,
        *,
        k: int | None = None,
        k_max: int = 8,
        clearance_m: float = 1.0,
        search_evaluations: int = 120,
        prune: bool = True,
        tsp_time_limit_s: float = 60.0,
    ):
        self.seed = _integer("seed", seed, low=0)
        if self.seed > MAX_SEED:
            raise ConfigError(f"seed = {seed!r} must be at most {MAX_SEED} (OMPL's seed is seed + 1 < 2**32)", "seed")
        self.k = _integer("k", k, low=1, optional=True)
        self.k_max = _integer("k_max", k_max, low=1)
        self.clearance_m = _real("clearance_m", clearance_m, unit="m")
        self.search_evaluations = _integer("search_evaluations", search_evaluations, low=0)
        if not isinstance(prune, bool):
            raise ConfigError(f"prune = {prune!r} must be true or false", "prune")
        self.prune = prune
        self.tsp_time_limit_s = _real("tsp_time_limit_s", tsp_time_limit_s, unit="s")
        self._plans: dict[str, ContinuousPlan] = {}
        self._env: Any = None
        self._follower: _Follower | None = None

    # ------------------------------------------------------------- policy interface

    def begin_episode(self, env: Any, obs: Any = None, info: Any = None) -> None:
        """Plan for ``env``'s layout (once per layout: cached), then start following the plan."""
        key = json.dumps(env.scenario.to_dict(), sort_keys=True, default=str)
        if key not in self._plans:
            self._plans[key] = self.make_plan(env.world, env.scenario)
        self.plan_ = self._plans[key]
        self._env = env
        self._follower = _Follower(self.plan_.legs, self.plan_.dwell_steps, float(env.world.max_step_m))
        self.given_up_ = self._follower.given_up

    def predict(self, obs: Any, deterministic: bool = True) -> np.ndarray:
        """The next velocity action (3,) float32 (see the module docstring)."""
        if self._follower is None:
            raise RuntimeError("call begin_episode(env, obs, info) after each reset (swiptopt.evaluate does)")
        return self._follower.action(self._env.position)

    # ------------------------------------------------------------- planning

    def make_plan(self, world: Any, scenario: Any) -> ContinuousPlan:
        """Plan the tour for ``world`` (:func:`swiptopt.continuous.build_world` of ``scenario``)."""
        self._pair_cache: dict[tuple[bytes, bytes], tuple[np.ndarray, str]] = {}
        self._ompl_calls: list[OmplCall] = []
        from swiptopt.continuous import coverable_nodes

        coverable = np.flatnonzero(coverable_nodes(scenario))
        if coverable.size == 0:
            return self._empty_plan(world, "no coverable nodes")
        from sklearn.cluster import KMeans

        seed = int(np.random.default_rng(self.seed).integers(2**31 - 1))  # as kmeans_hover_points
        ks = [min(self.k, coverable.size)] if self.k is not None else range(1, min(self.k_max, coverable.size) + 1)
        best: ContinuousPlan | None = None
        candidates: dict[int, float] = {}
        for k in ks:
            labels = KMeans(n_clusters=k, n_init=4, random_state=seed).fit(world.nodes_m[coverable]).labels_
            groups = [coverable[labels == g] for g in range(k)]
            points = np.stack([self._hover_point(world, scenario, g) for g in groups])
            plan = self._plan_for(world, scenario, k, points, groups)
            candidates[k] = plan.model_return
            if best is None or plan.model_return > best.model_return + 1e-12:
                best = plan
        assert best is not None
        return dataclasses.replace(best, candidates=candidates, ompl_plans=tuple(self._ompl_calls))

    def _empty_plan(self, world: Any, status: str) -> ContinuousPlan:
        positions, actions = self._rollout(world, (), np.zeros(0, dtype=np.int64))
        return ContinuousPlan(
            0, np.zeros((0, 3)), (), (), np.zeros(0, dtype=np.int64), None, "no_coverage",
            trajectory_return(world, positions, actions), positions, actions, status,
        )

    def _hover_point(self, world: Any, scenario: Any, group: np.ndarray) -> np.ndarray:
        """The group's hover point: the best start above it, then the compass search."""
        from planners.paths3d import clearance_of_m

        members = world.nodes_m[group]
        top = float(members[:, 2].min())
        xy = np.concatenate([members[:, :2].mean(axis=0, keepdims=True), members[:, :2]])
        depths = np.linspace(self.clearance_m, max(self.clearance_m, top - 1.0), START_DEPTH_LEVELS)
        starts = np.array([[x, y, z] for x, y in xy for z in depths])
        starts = starts[clearance_of_m(starts, scenario) >= self.clearance_m]
        if len(starts) == 0:  # every start is too near something: the free cell centres nearest the group
            centres = scenario.cell_centers_m
            centres = centres[clearance_of_m(centres, scenario) >= self.clearance_m]
            if len(centres) == 0:
                raise ConfigError(f"no point of the volume keeps clearance_m = {self.clearance_m:g} m from "
                                  "the obstacles, the seabed and the faces", "clearance_m")
            near = np.argsort(np.linalg.norm(centres - members.mean(axis=0), axis=1), kind="stable")
            starts = centres[near[:FALLBACK_STARTS]]
        values = hover_values(world, starts, group)
        here = starts[int(np.argmax(values))]
        value = float(values.max())
        step = float(world.max_step_m)
        spent = len(starts)
        moves = np.concatenate([np.eye(3), -np.eye(3)])
        while step >= SEARCH_MIN_STEP_M and spent < len(starts) + self.search_evaluations:
            polls = here + step * moves
            polls = polls[clearance_of_m(polls, scenario) >= self.clearance_m]
            if len(polls) == 0:
                step /= 2.0
                continue
            got = hover_values(world, polls, group)
            spent += len(polls)
            if got.max() > value + 1e-12:
                here, value = polls[int(np.argmax(got))], float(got.max())
            else:
                step /= 2.0
        return here

    # subclass hook: the leg between two stops, (waypoints, source)
    def _leg_between(self, world: Any, scenario: Any, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, str]:
        raise NotImplementedError  # pragma: no cover

    def _pair(self, world: Any, scenario: Any, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, str]:
        """The leg a -> b, planned once per unordered pair (the reverse reuses it reversed)."""
        key = (a.tobytes(), b.tobytes())
        if key in self._pair_cache:
            return self._pair_cache[key]
        back = self._pair_cache.get((b.tobytes(), a.tobytes()))
        if back is not None:
            return back[0][::-1].copy(), back[1]
        leg = self._leg_between(world, scenario, a, b)
        self._pair_cache[key] = leg
        return leg

    def _plan_for(self, world: Any, scenario: Any, k: int, points: np.ndarray, groups: list[np.ndarray]) -> ContinuousPlan:
        from planners.paths3d import path_energy_j
        from planners.tsp import solve_tsp

        stops = np.concatenate([np.asarray(world.start_m, dtype=float)[None, :], points])
        n = len(stops)
        paths: dict[tuple[int, int], tuple[np.ndarray, str]] = {}
        cost = np.zeros((n, n))
        blocked = np.zeros((n, n), dtype=bool)
        for i in range(n):
            for j in range(1, n):
                if i == j:
                    continue
                waypoints, source = self._pair(world, scenario, stops[i], stops[j])
                paths[i, j] = (waypoints, source)
                if self.tour_cost == "length":
                    cost[i, j] = float(np.linalg.norm(np.diff(waypoints, axis=0), axis=1).sum())
                else:
                    cost[i, j] = path_energy_j(waypoints, scenario)
                blocked[i, j] = source.startswith("straight (OMPL")
        if blocked.any():
            cost[blocked] = BLOCKED_COST_FACTOR * cost[~blocked].max(initial=1.0)
        tour = solve_tsp(cost, start=0, closed=False, time_limit_s=self.tsp_time_limit_s)
        order = list(tour.order[1:])

        plan = self._dwell_plan(world, scenario, k, stops, order, paths, groups, f"tsp {tour.status}")
        if self.prune:
            improved = True
            while improved and len(order) > 1:
                improved = False
                for j in range(len(order)):
                    fewer = order[:j] + order[j + 1 :]
                    other = self._dwell_plan(world, scenario, k, stops, fewer, paths, groups, f"tsp {tour.status}")
                    if other.model_return >= plan.model_return - 1e-12:
                        order, plan, improved = fewer, other, True
                        break
        return plan

    def _dwell_plan(
        self, world: Any, scenario: Any, k: int, stops: np.ndarray, order: list[int],
        paths: dict[tuple[int, int], tuple[np.ndarray, str]], groups: list[np.ndarray], status: str,
    ) -> ContinuousPlan:
        """The plan visiting ``order`` (indices into ``stops``; 0 is the start): legs, the
        tail that fits the episode, dwells from the convex program, and the model return."""
        from planners.paths3d import path_energy_j

        steps_total = int(world.params[K.P_STEPS])
        max_step = float(world.max_step_m)
        legs: list[Leg] = []
        used = 0
        here = 0
        for s in order:
            waypoints, source = paths[here, s]
            steps = _leg_steps(waypoints, max_step)
            if used + steps > steps_total:
                status += "; dropped the stops beyond the episode"
                break
            legs.append(Leg(waypoints, path_energy_j(waypoints, scenario), steps, source))
            used += steps
            here = s
        kept = order[: len(legs)]
        if not kept:
            return self._empty_plan(world, status + "; no stop within the episode")
        dwell, value, dwell_status = self._dwells(world, stops[kept], steps_total - used + len(kept))
        positions, actions = self._rollout(world, tuple(legs), dwell)
        return ContinuousPlan(
            k=k,
            hover_points_m=stops[kept],
            groups=tuple(groups[s - 1] for s in kept),
            legs=tuple(legs),
            dwell_steps=dwell,
            dwell_value=value,
            dwell_status=dwell_status,
            model_return=trajectory_return(world, positions, actions),
            positions_m=positions,
            actions=actions,
            status=f"{status}, dwell {dwell_status}",
        )

    def _dwells(self, world: Any, points: np.ndarray, service_steps: int) -> tuple[np.ndarray, float | None, str]:
        """Hover steps after each arrival, from the convex program with the simulator's split."""
        from planners.policies import _integer_steps
        from planners.power_split import optimise_dwell_and_split
        from swiptopt.continuous import coverage_at

        p = world.params
        n = int(world.n_nodes)
        snr = np.zeros((len(points), n))
        pav = np.zeros((len(points), n))
        for s, point in enumerate(points):
            nodes, snr_s, pav_s = coverage_at(world, point)
            nodes = np.asarray(nodes, dtype=np.int64)
            snr[s, nodes] = snr_s
            pav[s, nodes] = pav_s
        result = optimise_dwell_and_split(
            snr_linear=snr,
            available_power_w=pav,
            data_bits=world.data0,
            storage_room_j=np.maximum(np.asarray(world.capacity) - np.asarray(world.energy0), 0.0),
            mission_time_s=service_steps * float(p[K.P_DT]),
            reward_weight=float(p[K.P_GAMMA]),
            bandwidth_hz=float(p[K.P_BW]),
            efficiency=float(p[K.P_ETA]),
            data_ref_bits=float(p[K.P_DATA_REF]),
            energy_ref_j=float(p[K.P_ENERGY_REF]),
            split_ratio=float(p[K.P_ALPHA]),
        )
        if result.dwell_s is not None:
            wanted = np.asarray(result.dwell_s) / float(p[K.P_DT])
        else:
            wanted = np.full(len(points), service_steps / len(points))
        steps = _integer_steps(wanted, max(service_steps, len(points)))
        return steps - 1, result.objective, result.status

    def _rollout(self, world: Any, legs: tuple[Leg, ...], dwell: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The executor run over model positions for the whole episode: (T + 1, 3) positions and
        (T, 3) actions, moving as the env moves an unobstructed AUV."""
        from swiptopt.continuous import velocity_of

        follower = _Follower(legs, dwell, float(world.max_step_m))
        steps = int(world.params[K.P_STEPS])
        positions = np.empty((steps + 1, 3))
        actions = np.empty((steps, 3), dtype=np.float32)
        positions[0] = world.start_m
        for t in range(steps):
            actions[t] = follower.action(positions[t])
            # the env's arithmetic: the unit command times the step's reach
            positions[t + 1] = positions[t] + velocity_of(actions[t], 1.0) * world.max_step_m
        return positions, actions


def _leg_steps(waypoints_m: np.ndarray, max_step_m: float) -> int:
    """Steps the executor takes along a polyline: each segment in whole steps of at most
    ``max_step_m`` (the last one shorter)."""
    lengths = np.linalg.norm(np.diff(np.asarray(waypoints_m, dtype=float), axis=0), axis=1)
    lengths = lengths[lengths > ARRIVAL_TOLERANCE_M]
    return int(np.ceil(lengths / max_step_m - 1e-9).sum())


class OmplTourPlanner(_ContinuousTourPlanner):
    """Hover points in continuous space, a tour over OMPL energy paths, convex dwells, and an
    executor that follows the paths (module docstring).

    Arguments (units in brackets):
        seed: k-means' seed, and OMPL's process-wide seed is ``seed + 1``.
        k: a fixed number of k-means groups; ``None`` tries 1 .. ``k_max`` [groups].
        k_max: the most groups tried [groups].
        ompl_iterations: OMPL's budget per leg, in planner iterations (deterministic) [count].
            On the harbour, 150 iterations (about 0.3 s a leg) gave the same tours as 300
            (about 1.7 s a leg round the pier: Informed RRT* rewires more the longer it runs).
        ompl_planner: the OMPL planner (:data:`planners.paths3d.PLANNERS`; it must take the
            energy objective).
        ompl_legs: ``"blocked"``: OMPL only for legs whose straight segment is not free;
            ``"all"``: for every leg.
        clearance_m: the distance legs and hover points keep from obstacles, seabed and (hover
            points) the volume's faces [m].
        search_evaluations: the compass search's budget per hover point [evaluations].
        prune: drop stops that do not pay for their detour.
        tsp_time_limit_s: the TSP's wall-clock safety net (it stops on a deterministic budget) [s].
    """

    def __init__(
        self,
        seed: int = 0,
        *,
        k: int | None = None,
        k_max: int = 8,
        ompl_iterations: int = 150,
        ompl_planner: str = "InformedRRTstar",
        ompl_legs: str = "blocked",
        clearance_m: float = 1.0,
        search_evaluations: int = 120,
        prune: bool = True,
        tsp_time_limit_s: float = 60.0,
    ):
        super().__init__(seed, k=k, k_max=k_max, clearance_m=clearance_m, search_evaluations=search_evaluations,
                         prune=prune, tsp_time_limit_s=tsp_time_limit_s)
        self.ompl_iterations = _integer("ompl_iterations", ompl_iterations, low=1)
        if ompl_planner not in PLANNERS or ompl_planner in CRASHING_PLANNERS or ompl_planner in NO_PYTHON_OBJECTIVE_PLANNERS:
            allowed = [p for p in PLANNERS if p not in CRASHING_PLANNERS and p not in NO_PYTHON_OBJECTIVE_PLANNERS]
            raise ConfigError(f"ompl_planner = {ompl_planner!r} is not one of {', '.join(allowed)}", "ompl_planner")
        self.ompl_planner = ompl_planner
        if ompl_legs not in OMPL_LEGS:
            raise ConfigError(f"ompl_legs = {ompl_legs!r} is not one of {', '.join(OMPL_LEGS)}", "ompl_legs")
        self.ompl_legs = ompl_legs

    def _leg_between(self, world: Any, scenario: Any, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, str]:
        from planners.paths3d import path_energy_j, plan_path_3d, segments_free

        straight = np.stack([a, b])
        free = bool(segments_free(a, b, scenario, clearance_m=self.clearance_m)[0])
        if free and self.ompl_legs == "blocked":
            return straight, "straight"
        result = plan_path_3d(
            a, b, scenario, planner=self.ompl_planner, objective="energy", seed=self.seed + 1,
            clearance_m=self.clearance_m, iterations=self.ompl_iterations,
        )
        use = result.exact and not (free and path_energy_j(straight, scenario) <= float(result.energy_j))
        self._ompl_calls.append(OmplCall(a.copy(), b.copy(), result.status, float(result.energy_j), bool(use)))
        if use:
            return result.waypoints, "ompl"
        if free:
            return straight, "straight"
        return straight, f"straight (OMPL {result.status})"


class StraightLinePlanner(_ContinuousTourPlanner):
    """The OMPL tour's pipeline (hover points, dwells, the choice of K) with straight legs
    that ignore obstacles and the current, so its model believes every leg is free: the tour
    minimises Euclidean length, the executor steers straight at each stop and, when a move
    makes no progress (the env stopped it at an obstacle), gives that stop up and heads for
    the next (module docstring). No OMPL.

    Arguments: as :class:`OmplTourPlanner`'s, without the OMPL ones. ``clearance_m`` applies to
    the hover points only.
    """

    tour_cost = "length"

    def _leg_between(self, world: Any, scenario: Any, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, str]:
        return np.stack([a, b]), "straight (obstacles ignored)"
