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
5. **K**: K groups for K from ``k_max`` down (or the given ``k``) are planned, and the plan
   whose whole trajectory earns most in the per-step model is kept; the search stops once
   ``k_patience`` K's in a row earn less than the best so far (``k_patience=None``: every K
   from 1 to ``k_max``). The model return of a plan runs the executor itself (the same
   code, its reactions included) over model positions, with the env's own motion and
   propulsion functions (:func:`swiptopt.continuous.compiled`) and the model's expected
   service from where each step ends, on the model's own record of what each node still
   holds. With a deterministic channel and no link failures this is the env's return for
   the OMPL tour (a test replays it); with fading it is the expected-rate relaxation of
   :mod:`planners.service`.

**Executor.** Velocity actions from :func:`swiptopt.continuous.action_towards`: along each
route, straight at the next waypoint, at most one step's length at a time and never past the
waypoint (a sub-segment of a valid segment is valid, so the AUV stays on the planned path);
at a stop, its dwell as hover actions (zero velocity). Routes join every pair of *sites*
(the start and the hover points of the plan's K, pruned ones included), so the executor can
react to the nodes' state, read from the env (``adaptive=True``, the default):

- a stop whose covered nodes all need nothing more (the kernel's "served": data delivered,
  storage full) when the AUV is about to head for it is skipped: the AUV takes the route to
  the stop after it (unless that route is blocked, when it keeps the order);
- a dwell ends as soon as the stop's covered nodes are all served;
- after its dwell the AUV lingers up to ``linger_steps`` steps while a covered node still
  holds data (a link failure or a fade kept it), if the rest of the tour still fits the
  episode (its routes, arrivals and dwells, each dwell no longer than its nodes need in
  expectation);
- after the last stop, each step it picks the site where the steps left earn most in the
  model's expected amounts from the nodes' current state, less the route there and the
  hovering, and goes there or stays (the steps freed by the rules above end up here).

``adaptive=False`` follows the plan as planned and hovers after the last stop. A commanded
move that makes no progress (the env stopped it at an obstacle) gives up that stop: the
executor goes on to the next one, straight from where it is. This is the straight-line
planner's rule (its legs ignore obstacles and stop where they collide); the OMPL tour's
routes are free, so it never applies there (``given_up_`` records it if it does;
``skipped_`` and ``cut_`` record the stops skipped and the dwells cut).

Reproducibility. k-means and the compass search are seeded and counted; the TSP stops on a
deterministic budget; OMPL draws from one process-wide generator (:mod:`planners.paths3d`):
the planner passes ``seed + 1`` (what the benchmark's fresh OMPL process is seeded with) and
plans each layout once (cached), so the same seed and layouts give the same plans in a fresh
process. A second planner seed in the same process is refused by ``plan_path_3d``.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import numbers
from dataclasses import dataclass, field
from typing import Any, Callable

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

#: Under fading, the model prices the service of a position at the nearest point of a grid
#: this fine, m (:class:`_PointService`).
SERVICE_GRID_M = 1e-3


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
    sites_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """(N, 3) the points the executor moves between: the start, then every hover point of
    the plan's K (the stops and those pruned or dropped), m."""
    routes: dict[tuple[int, int], Leg] = field(default_factory=dict)
    """The leg from site i to site j (j >= 1), for every pair: the stops' legs are among them."""
    stop_sites: tuple[int, ...] = ()
    """The site of each stop, in tour order."""
    site_model: Any = None
    """:func:`point_model` of :attr:`sites_m`: what a step at each site earns (the executor's
    estimates)."""

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

    cover, _, propulsion_j = _step_functions()
    points = np.ascontiguousarray(np.asarray(points_m, dtype=float).reshape(-1, 3))
    m = len(points)
    n = int(world.n_nodes)
    nodes, snr, pav, counts = [], [], [], np.zeros(m, dtype=np.int64)
    hover_j = np.empty(m)
    scratch = (np.empty(n, dtype=np.int64), np.empty(n), np.empty(n))
    still = np.zeros(3)
    for c, p in enumerate(points):
        count = cover(world.world, world.nodes_m, p, *scratch)
        nodes.append(scratch[0][:count].copy())
        snr.append(scratch[1][:count].copy())
        pav.append(scratch[2][:count].copy())
        counts[c] = count
        hover_j[c] = propulsion_j(world.world, world.params, float(p[2]), still, 0.0)
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


@functools.lru_cache(maxsize=1)
def _step_functions() -> tuple[Callable[..., Any], Callable[..., Any], Callable[..., Any]]:
    """:mod:`swiptopt.continuous`'s ``cover``, ``command`` and ``propulsion_j``: the env's own
    compiled functions when numba is installed, else the Python originals."""
    from swiptopt import continuous as C
    from swiptopt.jit import numba_available

    if numba_available():
        return C.compiled("cover"), C.compiled("command"), C.compiled("propulsion_j")
    return C.cover, C.command, C.propulsion_j


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
    """Turns a plan into actions, one per call, from the current position and the nodes' state.

    One piece of code serves the env (:meth:`_ContinuousTourPlanner.predict`, with the env's
    state) and the model (:meth:`_ContinuousTourPlanner._rollout`, with the model's state), so
    the model scores what the executor does. The rules (module docstring, "Executor"): follow
    the route to the next stop; at a stop, hover its planned dwell; with ``adaptive``, skip a
    stop whose covered nodes need nothing more, cut a dwell once they are all served, linger
    up to ``linger_steps`` while a covered node still holds data and the rest of the tour
    leaves room, and after the last stop spend the steps left at the site that earns most.
    """

    def __init__(self, plan: ContinuousPlan, world: Any, *, adaptive: bool = True, linger_steps: int = 2):
        self.sites = plan.sites_m
        self.routes = plan.routes
        self.order = [int(s) for s in plan.stop_sites]
        self.dwell = [int(d) for d in plan.dwell_steps]
        self.max_step_m = float(world.max_step_m)
        self.steps = int(world.params[K.P_STEPS])
        self.full_j = np.asarray(world.capacity, dtype=float) * 1e-12  # the kernel's "full" margin
        self.needs_energy = bool(world.params[K.P_GAMMA] < 1.0)
        model = plan.site_model
        self.adaptive = adaptive and model is not None  # the reactions need the sites' model
        self.linger_steps = linger_steps
        if model is not None:
            self.cover = [model.cov_node[model.cov_ptr[s] : model.cov_ptr[s + 1]] for s in range(model.n_cells)]
            self.pair_site = model.cell_of_pair()
            self.pair_node = model.cov_node
            self.bits, self.joules = model.bits, model.joules
            self.data_weight, self.energy_weight = model.data_weight, model.energy_weight
            self.stay_cost = model.stay_cost
        # per site of departure: steps, movement penalty and usability of the route to each site
        n = len(self.sites)
        move_per_j = float(world.params[K.P_LAMBDA] / world.params[K.P_MOVE_REF])
        self.route_steps = np.zeros((n, n), dtype=np.int64)
        self.route_cost = np.zeros((n, n))
        self.route_ok = np.zeros((n, n), dtype=bool)
        for (i, j), route in self.routes.items():
            self.route_steps[i, j] = route.steps
            self.route_cost[i, j] = move_per_j * route.energy_j
            self.route_ok[i, j] = not route.source.startswith("straight (OMPL")
        self.route_ok[np.arange(1, n), np.arange(1, n)] = True  # staying
        used = self.route_steps > 0
        self.cost_per_step = float(self.route_cost[used].sum() / max(1, self.route_steps[used].sum()))
        # a bound on the state machine's passes in one call: every waypoint, site and stop once
        self.passes = 8 + 2 * (len(self.sites) + len(self.order)) + max(
            (len(r.waypoints_m) for r in self.routes.values()), default=0)
        self.next = 0  # index into order of the next planned stop
        self.stop = -1  # index into order of the stop being served (-1: none)
        self.site: int | None = 0  # the site the AUV is at (None: between sites, after giving up)
        self.target = -1  # the site being travelled to
        self.target_stop = -1  # its index into order (-1: a site of the end phase)
        self.waypoints: np.ndarray | None = None  # the route being followed
        self.waypoint = 1  # its next waypoint
        self.hovered = 0  # hover steps of the planned dwell spent at the current stop
        self.lingered = 0  # hover steps beyond it
        self.end_phase = False
        self.last: tuple[np.ndarray, int] | None = None  # (position, waypoint index) of the last move
        self.given_up: list[int] = []  # stops (indices into order) given up: a move made no progress
        self.skipped: list[int] = []  # stops skipped: their nodes needed nothing more
        self.cut: list[int] = []  # stops whose dwell was cut short: their nodes needed nothing more
        self.lingered_steps = 0  # hover steps beyond the planned dwells, over the episode
        self.excluded: set[int] = set()  # sites given up

    # ----------------------------------------------------------------- the state

    def _served(self, site: int, data_left: np.ndarray, room_left: np.ndarray) -> bool:
        """Whether every node covered from ``site`` needs nothing more (the kernel's rule)."""
        nodes = self.cover[site]
        if np.any(data_left[nodes] > 0.0):
            return False
        return not self.needs_energy or bool(np.all(room_left[nodes] <= self.full_j[nodes]))

    def _earnings(self, steps: np.ndarray, data_left: np.ndarray, room_left: np.ndarray) -> np.ndarray:
        """(N,) what hovering ``steps[s]`` steps at each site s would earn from the nodes' state,
        in the per-step model's expected amounts (service only)."""
        n = steps[self.pair_site]
        per_pair = self.data_weight * np.minimum(data_left[self.pair_node], n * self.bits) + self.energy_weight * (
            np.minimum(room_left[self.pair_node], n * self.joules)
        )
        return np.bincount(self.pair_site, weights=per_pair, minlength=len(self.sites))

    def _slack(self, steps_left: int, data_left: np.ndarray, room_left: np.ndarray) -> int:
        """Steps to spare after the next one: the steps left less what the rest of the tour
        needs (its routes, arrivals and dwells, each dwell no longer than its nodes need in
        expectation; stops already served skipped)."""
        need = 0
        at = self.site
        for i in range(self.next, len(self.order)):
            s = self.order[i]
            if self._served(s, data_left, room_left):
                continue
            need += self.routes[at, s].steps + 1 + min(self.dwell[i], self._steps_to_serve(s, data_left, room_left))
            at = s
        return steps_left - 1 - need

    def _steps_to_serve(self, site: int, data_left: np.ndarray, room_left: np.ndarray) -> int:
        """Expected hover steps after the arrival until the site's nodes are all served (a
        large number if some never are)."""
        sel = self.pair_site == site
        nodes = self.pair_node[sel]
        with np.errstate(divide="ignore", invalid="ignore"):
            data = np.where(data_left[nodes] > 0.0, data_left[nodes] / self.bits[sel], 0.0)
            energy = np.where(room_left[nodes] > self.full_j[nodes], room_left[nodes] / self.joules[sel], 0.0)
        worst = float(np.max(np.maximum(data, energy * self.needs_energy), initial=0.0))
        return max(0, int(min(math.ceil(worst), self.steps)) - 1) if math.isfinite(worst) else self.steps

    # ----------------------------------------------------------------- decisions

    def action(self, position_m: np.ndarray, data_left: np.ndarray, room_left: np.ndarray, t: int) -> np.ndarray:
        """The action of step ``t`` from ``position_m``, given each node's data left (bits) and
        free storage (J)."""
        from swiptopt.continuous import action_towards

        position = np.asarray(position_m, dtype=float)
        steps_left = self.steps - t
        for _ in range(self.passes):  # each pass moves the state machine on
            if self.waypoints is not None:
                if self.waypoint < len(self.waypoints):
                    target = self.waypoints[self.waypoint]
                    if math.dist(target, position) <= ARRIVAL_TOLERANCE_M:
                        self.waypoint += 1
                        continue
                    if self.last is not None and self.last[1] == self.waypoint and (
                        math.dist(position, self.last[0]) < NO_PROGRESS_M
                    ):
                        # the last move towards this waypoint was stopped by an obstacle: give up
                        if self.target_stop >= 0:
                            self.given_up.append(self.target_stop)
                        self.excluded.add(self.target)
                        self.waypoints, self.site, self.last = None, None, None
                        continue
                    self.last = (position.copy(), self.waypoint)
                    return np.asarray(action_towards(position, target, self.max_step_m), dtype=np.float32)
                # arrived: the arrival step has served the site
                self.site, self.stop, self.waypoints, self.last = self.target, self.target_stop, None, None
                self.hovered = self.lingered = 0
                continue
            if self.stop >= 0:
                if self._stay_at_stop(data_left, room_left, steps_left):
                    return np.zeros(3, dtype=np.float32)
                self.stop = -1
            site = self._next_site(position, data_left, room_left, steps_left)
            if site is None or site == self.site:
                return np.zeros(3, dtype=np.float32)
            self._travel_to(position, site)
        raise AssertionError("the executor's state machine did not settle")  # pragma: no cover

    def _stay_at_stop(self, data_left: np.ndarray, room_left: np.ndarray, steps_left: int) -> bool:
        if self.hovered < self.dwell[self.stop]:
            if not (self.adaptive and self._served(self.site, data_left, room_left)):
                self.hovered += 1
                return True
            self.cut.append(self.stop)
            return False
        if (
            self.adaptive
            and self.lingered < self.linger_steps
            and np.any(data_left[self.cover[self.site]] > 0.0)
            and self._slack(steps_left, data_left, room_left) >= 0
        ):
            self.lingered += 1
            self.lingered_steps += 1
            return True
        return False

    def _next_site(
        self, position: np.ndarray, data_left: np.ndarray, room_left: np.ndarray, steps_left: int
    ) -> int | None:
        """The next planned stop that still needs something (recorded in ``target_stop``),
        else, with ``adaptive``, the site of the end phase; None: hover."""
        while self.next < len(self.order):
            i = self.next
            self.next += 1
            s = self.order[i]
            if self.adaptive and self._served(s, data_left, room_left) and self._can_skip(i):
                self.skipped.append(i)
                continue
            self.target_stop = i
            return s
        self.target_stop = -1
        if not self.adaptive:
            return None
        self.end_phase = True
        return self._best_site(position, data_left, room_left, steps_left)

    def _can_skip(self, i: int) -> bool:
        """Whether stop i can be left out: the route from here to the stop after it is free
        (a blocked route is kept only in the planned order, where the tour put it)."""
        if i + 1 >= len(self.order) or self.site is None:
            return True
        return not self.routes[self.site, self.order[i + 1]].source.startswith("straight (OMPL")

    def _best_site(
        self, position: np.ndarray, data_left: np.ndarray, room_left: np.ndarray, steps_left: int
    ) -> int | None:
        """The end phase: the site where the steps left earn most, less the route there and
        the hovering; the current site when nothing beats staying. Away from every site (after
        giving up) the routes are straight, priced at the routes' mean cost per step."""
        here = self.site
        if here is None:
            travel = np.ceil(np.linalg.norm(self.sites - position, axis=1) / self.max_step_m - 1e-9).astype(np.int64)
            cost, ok = travel * self.cost_per_step, np.arange(len(self.sites)) >= 1
        else:
            travel, cost, ok = self.route_steps[here], self.route_cost[here], self.route_ok[here].copy()
        hover = np.maximum(steps_left - travel, 0)
        value = self._earnings(hover, data_left, room_left) - cost - hover * self.stay_cost
        ok[list(self.excluded)] = False
        value[~ok | (hover <= 0)] = -np.inf
        if here is not None and here >= 1:
            value[here] += 1e-12  # stay unless moving earns more
        best = int(np.argmax(value))
        return best if np.isfinite(value[best]) else None

    def _travel_to(self, position: np.ndarray, site: int) -> None:
        if self.site is None:  # after giving up: straight at it from here
            self.waypoints = np.stack([position, self.sites[site]])
        else:
            self.waypoints = self.routes[self.site, site].waypoints_m
        self.target, self.waypoint, self.site, self.last = site, 1, None, None


class _PointService:
    """The per-step model's service from single positions (:func:`point_model`), computed
    in batches and kept, for the model's rollouts.

    On a deterministic channel the amounts are the kernel's own, cheap to compute, and kept
    by exact position. Under fading each costs a quadrature, and the executor's positions
    differ by float rounding from run to run (where it arrives at a site depends on where it
    came from, within a micrometre), so the expected amounts are priced at the position
    rounded to :data:`SERVICE_GRID_M` and kept by that: the same few points serve every run.
    """

    def __init__(self, world: Any):
        self.world = world
        self.exact = point_model(world, np.zeros((0, 3))).exact
        self.known: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def _point(self, position_m: np.ndarray) -> np.ndarray:
        return position_m if self.exact else np.round(position_m / SERVICE_GRID_M) * SERVICE_GRID_M

    def get(self, position_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """(nodes, bits, joules) a step ending at the position serves, or None if not computed."""
        return self.known.get(self._point(position_m).tobytes())

    def compute(self, positions_m: list[np.ndarray]) -> None:
        points = [self._point(p) for p in positions_m]
        fresh = {p.tobytes(): p for p in points if p.tobytes() not in self.known}
        if not fresh:
            return
        model = point_model(self.world, np.stack(list(fresh.values())))
        for c, key in enumerate(fresh):
            lo, hi = model.cov_ptr[c], model.cov_ptr[c + 1]
            self.known[key] = (model.cov_node[lo:hi], model.bits[lo:hi], model.joules[lo:hi])


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
        k_max: int = 20,
        k_patience: int | None = 2,
        clearance_m: float = 1.0,
        search_evaluations: int = 120,
        prune: bool = True,
        tsp_time_limit_s: float = 60.0,
        adaptive: bool = True,
        linger_steps: int = 2,
    ):
        self.seed = _integer("seed", seed, low=0)
        if self.seed > MAX_SEED:
            raise ConfigError(f"seed = {seed!r} must be at most {MAX_SEED} (OMPL's seed is seed + 1 < 2**32)", "seed")
        self.k = _integer("k", k, low=1, optional=True)
        self.k_max = _integer("k_max", k_max, low=1)
        self.k_patience = _integer("k_patience", k_patience, low=1, optional=True)
        self.clearance_m = _real("clearance_m", clearance_m, unit="m")
        self.search_evaluations = _integer("search_evaluations", search_evaluations, low=0)
        if not isinstance(prune, bool):
            raise ConfigError(f"prune = {prune!r} must be true or false", "prune")
        self.prune = prune
        self.tsp_time_limit_s = _real("tsp_time_limit_s", tsp_time_limit_s, unit="s")
        if not isinstance(adaptive, bool):
            raise ConfigError(f"adaptive = {adaptive!r} must be true or false", "adaptive")
        self.adaptive = adaptive
        self.linger_steps = _integer("linger_steps", linger_steps, low=0)
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
        self._follower = self._follower_of(self.plan_, env.world)
        self.given_up_ = self._follower.given_up
        self.skipped_ = self._follower.skipped
        self.cut_ = self._follower.cut

    def predict(self, obs: Any, deterministic: bool = True) -> np.ndarray:
        """The next velocity action (3,) float32 (see the module docstring)."""
        if self._follower is None:
            raise RuntimeError("call begin_episode(env, obs, info) after each reset (swiptopt.evaluate does)")
        state = self._env.state
        room_left = np.asarray(self._env.world.capacity) - state.energy
        return self._follower.action(self._env.position, state.data_left, room_left, int(state.t))

    def _follower_of(self, plan: ContinuousPlan, world: Any) -> _Follower:
        return _Follower(plan, world, adaptive=self.adaptive, linger_steps=self.linger_steps)

    # ------------------------------------------------------------- planning

    def make_plan(self, world: Any, scenario: Any) -> ContinuousPlan:
        """Plan the tour for ``world`` (:func:`swiptopt.continuous.build_world` of ``scenario``)."""
        self._pair_cache: dict[tuple[bytes, bytes], tuple[np.ndarray, str]] = {}
        self._ompl_calls: list[OmplCall] = []
        self._service = _PointService(world)
        self._hover_cache: dict[tuple[int, ...], np.ndarray] = {}
        from swiptopt.continuous import coverable_nodes

        coverable = np.flatnonzero(coverable_nodes(scenario))
        if coverable.size == 0:
            return self._empty_plan(world, "no coverable nodes")
        from sklearn.cluster import KMeans

        seed = int(np.random.default_rng(self.seed).integers(2**31 - 1))  # as kmeans_hover_points
        top = min(self.k_max, coverable.size)
        if self.k is not None:
            ks: range | list[int] = [min(self.k, coverable.size)]
        elif self.k_patience is None:
            ks = range(1, top + 1)
        else:
            ks = range(top, 0, -1)
        best: ContinuousPlan | None = None
        candidates: dict[int, float] = {}
        for k in ks:
            if self.k_patience is not None and best is not None and best.k - k > self.k_patience:
                break  # k_patience K's in a row earned less than the best
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
        sites = np.asarray(world.start_m, dtype=float)[None, :].copy()
        plan = ContinuousPlan(
            0, np.zeros((0, 3)), (), (), np.zeros(0, dtype=np.int64), None, "no_coverage", 0.0, sites,
            np.zeros((0, 3), dtype=np.float32), status, sites_m=sites, site_model=point_model(world, sites),
        )
        return self._scored(world, plan)

    def _scored(self, world: Any, plan: ContinuousPlan) -> ContinuousPlan:
        """``plan`` with the executor's trajectory in the model and its return."""
        positions, actions, model_return = self._rollout(world, plan)
        return dataclasses.replace(plan, positions_m=positions, actions=actions, model_return=model_return)

    def _hover_point(self, world: Any, scenario: Any, group: np.ndarray) -> np.ndarray:
        """The group's hover point: the best start above it, then the compass search. Kept
        per group: neighbouring K share most groups, hence their hover points and the legs
        between them (planned once, :meth:`_pair`)."""
        key = tuple(int(i) for i in group)
        if key not in self._hover_cache:
            self._hover_cache[key] = self._search_hover_point(world, scenario, group)
        return self._hover_cache[key]

    def _search_hover_point(self, world: Any, scenario: Any, group: np.ndarray) -> np.ndarray:
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

        sites = np.concatenate([np.asarray(world.start_m, dtype=float)[None, :], points])
        n = len(sites)
        max_step = float(world.max_step_m)
        routes: dict[tuple[int, int], Leg] = {}
        cost = np.zeros((n, n))
        blocked = np.zeros((n, n), dtype=bool)
        for i in range(n):
            for j in range(1, n):
                if i == j:
                    continue
                waypoints, source = self._pair(world, scenario, sites[i], sites[j])
                leg = Leg(waypoints, path_energy_j(waypoints, scenario), _leg_steps(waypoints, max_step), source)
                routes[i, j] = leg
                if self.tour_cost == "length":
                    cost[i, j] = float(np.linalg.norm(np.diff(waypoints, axis=0), axis=1).sum())
                else:
                    cost[i, j] = leg.energy_j
                blocked[i, j] = source.startswith("straight (OMPL")
        if blocked.any():
            cost[blocked] = BLOCKED_COST_FACTOR * cost[~blocked].max(initial=1.0)
        tour = solve_tsp(cost, start=0, closed=False, time_limit_s=self.tsp_time_limit_s)
        order = list(tour.order[1:])
        network = (sites, routes, point_model(world, sites))

        plan = self._dwell_plan(world, k, network, order, groups, f"tsp {tour.status}")
        if self.prune:
            improved = True
            while improved and len(order) > 1:
                improved = False
                for j in range(len(order)):
                    fewer = order[:j] + order[j + 1 :]
                    other = self._dwell_plan(world, k, network, fewer, groups, f"tsp {tour.status}")
                    if other.model_return >= plan.model_return - 1e-12:
                        order, plan, improved = fewer, other, True
                        break
        return plan

    def _dwell_plan(
        self, world: Any, k: int, network: tuple[np.ndarray, dict[tuple[int, int], Leg], Any], order: list[int],
        groups: list[np.ndarray], status: str,
    ) -> ContinuousPlan:
        """The plan visiting ``order`` (site indices; 0 is the start): legs, the tail that fits
        the episode, dwells from the convex program, and the executor's model return."""
        sites, routes, site_model = network
        steps_total = int(world.params[K.P_STEPS])
        legs: list[Leg] = []
        used = 0
        here = 0
        for s in order:
            leg = routes[here, s]
            if used + leg.steps > steps_total:
                status += "; dropped the stops beyond the episode"
                break
            legs.append(leg)
            used += leg.steps
            here = s
        kept = order[: len(legs)]
        if not kept:
            return self._empty_plan(world, status + "; no stop within the episode")
        dwell, value, dwell_status = self._dwells(world, sites[kept], steps_total - used + len(kept))
        plan = ContinuousPlan(
            k=k,
            hover_points_m=sites[kept],
            groups=tuple(groups[s - 1] for s in kept),
            legs=tuple(legs),
            dwell_steps=dwell,
            dwell_value=value,
            dwell_status=dwell_status,
            model_return=0.0,
            positions_m=sites[:1],
            actions=np.zeros((0, 3), dtype=np.float32),
            status=f"{status}, dwell {dwell_status}",
            sites_m=sites,
            routes=routes,
            stop_sites=tuple(int(s) for s in kept),
            site_model=site_model,
        )
        return self._scored(world, plan)

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

    def _rollout(self, world: Any, plan: ContinuousPlan) -> tuple[np.ndarray, np.ndarray, float]:
        """The executor run in the per-step model: (T + 1, 3) positions, (T, 3) actions and the
        return, moving as the env moves an unobstructed AUV and serving with the model's
        expected amounts (:func:`trajectory_return`'s rules; T < the episode when every node
        is served).

        The executor reacts to the nodes' state, so the positions are not known before the
        run: a run looks up what each position serves among those already computed and
        collects the others, which are computed at once (:class:`_PointService`) for the next
        run; the run that finds every position known is the answer. Each run is exact up to
        the first position the one before it lacked, so the runs end.
        """
        _, command, propulsion_j = _step_functions()
        p = world.params
        steps = int(p[K.P_STEPS])
        move_weight = float(p[K.P_LAMBDA] / p[K.P_MOVE_REF])
        hotel_j = float(p[K.P_HOTEL_J])
        capacity = np.asarray(world.capacity, dtype=float)
        data0 = np.asarray(world.data0, dtype=float)
        room0 = np.maximum(capacity - np.asarray(world.energy0, dtype=float), 0.0)
        needs_energy = bool(p[K.P_GAMMA] < 1.0)
        data_weight, energy_weight = plan.site_model.data_weight, plan.site_model.energy_weight
        for _ in range(steps + 1):
            follower = self._follower_of(plan, world)
            data_left, room_left = data0.copy(), room0.copy()
            positions = np.empty((steps + 1, 3))
            actions = np.empty((steps, 3), dtype=np.float32)
            positions[0] = world.start_m
            total, ran, missing = 0.0, steps, []
            action, unit = np.empty(3), np.empty(3)
            for t in range(steps):
                actions[t] = follower.action(positions[t], data_left, room_left, t)
                # the env's step: the command, its propulsion from the depth it starts at, the move
                action[:] = actions[t]
                norm = command(action, unit)
                total -= move_weight * (propulsion_j(world.world, p, float(positions[t, 2]), unit, norm) + hotel_j)
                positions[t + 1] = positions[t] + unit * world.max_step_m
                served = self._service.get(positions[t + 1])
                if served is None:
                    missing.append(positions[t + 1].copy())
                    continue
                nodes, bits, joules = served
                if len(nodes) == 0:
                    continue
                bits = np.minimum(data_left[nodes], bits)
                joules = np.minimum(room_left[nodes], joules)
                data_left[nodes] -= bits
                room_left[nodes] -= joules
                gained = data_weight * float(bits.sum()) + energy_weight * float(joules.sum())
                total += gained
                if gained > 0.0 and not np.any(data_left > 0.0) and (
                    not needs_energy or bool(np.all(room_left <= capacity * 1e-12))
                ):
                    ran = t + 1  # every node served: the env ends the episode here
                    break
            if not missing:
                return positions[: ran + 1], actions[:ran], float(total)
            self._service.compute(missing)
        raise AssertionError("the model's rollout did not settle")  # pragma: no cover


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
        k: a fixed number of k-means groups; ``None`` searches K from ``k_max`` down [groups].
        k_max: the most groups tried (at most the coverable nodes) [groups]. On the harbour's
            12 layouts (20 nodes) the return grew with K up to about one group per coverable
            node (mean return 19.2 at k_max 8, 23.8 at 10, 26.5 at 12, 37.7 at 20): more,
            smaller groups serve more nodes within the episode. 20 with ``k_patience=2``
            plans in about 5 s a layout (at most 8 s), in the ~15 s budget.
        k_patience: stop the search once this many K's in a row earn less than the best so
            far [K's]; ``None`` plans every K from 1 to ``k_max`` (the return is close to
            increasing in K, so 2 keeps the best of the full search at a fraction of its time).
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
        adaptive: the executor reacts to the nodes' state (skips served stops, cuts served
            dwells, lingers for data, spends the steps left where they earn most: module
            docstring); ``False`` follows the plan as planned.
        linger_steps: the most hover steps after a stop's dwell while a covered node still
            holds data [steps].
    """

    def __init__(
        self,
        seed: int = 0,
        *,
        k: int | None = None,
        k_max: int = 20,
        k_patience: int | None = 2,
        ompl_iterations: int = 150,
        ompl_planner: str = "InformedRRTstar",
        ompl_legs: str = "blocked",
        clearance_m: float = 1.0,
        search_evaluations: int = 120,
        prune: bool = True,
        tsp_time_limit_s: float = 60.0,
        adaptive: bool = True,
        linger_steps: int = 2,
    ):
        super().__init__(seed, k=k, k_max=k_max, k_patience=k_patience, clearance_m=clearance_m, search_evaluations=search_evaluations,
                         prune=prune, tsp_time_limit_s=tsp_time_limit_s, adaptive=adaptive,
                         linger_steps=linger_steps)
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
    the hover points only. ``adaptive`` is off by default: the executor's reactions trust the
    model's routes, which here cross obstacles (the end phase would head for sites behind the
    pier), and on the harbour they cost this planner more than they earned (mean return 31.0
    with them, 31.8 without, at the default K search).
    """

    tour_cost = "length"

    def __init__(
        self,
        seed: int = 0,
        *,
        k: int | None = None,
        k_max: int = 20,
        k_patience: int | None = 2,
        clearance_m: float = 1.0,
        search_evaluations: int = 120,
        prune: bool = True,
        tsp_time_limit_s: float = 60.0,
        adaptive: bool = False,
        linger_steps: int = 2,
    ):
        super().__init__(seed, k=k, k_max=k_max, k_patience=k_patience, clearance_m=clearance_m,
                         search_evaluations=search_evaluations, prune=prune, tsp_time_limit_s=tsp_time_limit_s,
                         adaptive=adaptive, linger_steps=linger_steps)

    def _leg_between(self, world: Any, scenario: Any, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, str]:
        return np.stack([a, b]), "straight (obstacles ignored)"
