"""Planners that run in the environment: plans turned into env actions.

Each planner is a policy with ``predict(obs, deterministic=True)`` and
``begin_episode(env, obs, info)``, so :func:`swiptopt.evaluate` scores it exactly like an RL
agent, through the same simulator kernel. A plan is a list of stops (hover cell, service
steps); the AUV moves between stops along shortest 6-connected grid paths (which respect
obstacles) and hovers at each stop. ``begin_episode`` hands the planner the unwrapped
environment, whose state it reads to react: it lingers while covered nodes still hold data
(a link failure delayed them) and skips stops whose nodes are already served.

A planner plans only over the cells the AUV can reach from its start cell (obstacles may
wall part of the volume off, or box the start in): nodes covered only from cells it cannot
reach, and survey stops it cannot reach, are skipped and listed in the plan's ``details``
(``unreachable_nodes``, ``unreachable_stops``) with the reason in its ``status``. The planner
still serves what it can reach, and hovers when that is nothing.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from planners.clustering import coverage_tables, hover_link, kmeans_hover_points
from planners.grid import bfs_distances
from planners.tsp import METHODS as TSP_METHODS
from swiptopt import kernel as K
from swiptopt.errors import ConfigError
from swiptopt.scenario import Scenario
from swiptopt.validation import Param, Parameterised

TOUR_COSTS = ("auto", "euclidean", "grid", "ompl")

#: The settings the grid's planners share, declared once (:class:`swiptopt.validation.Param`).
LINGER_STEPS = Param(default=2, kind="int", lo=0, hi=1_000_000, strict=True, unit="steps",
                     doc="extra hover steps while covered nodes hold data")
#: k-means + TSP's settings (:class:`KMeansTspPlanner`).
KMEANS_TSP_PARAMETERS = {
    "k": Param(default=None, kind="int", lo=1, optional=True, strict=True,
               doc="hover groups (default: the fewest that fit the coverage cone)"),
    "tsp_method": Param(default="auto", kind="str", choices=TSP_METHODS, doc="the TSP solver (planners.tsp)"),
    "tsp_time_limit_s": Param(default=60.0, lo=0, lo_open=True, hi=3600, unit="s",
                              doc="TSP wall-clock safety net (the search stops on a deterministic budget)"),
    "tour_costs": Param(default="auto", kind="str", choices=TOUR_COSTS, doc="what the tour's arc costs measure"),
    "ompl_time_limit_s": Param(default=0.2, lo=0, lo_open=True, hi=600, unit="s",
                               doc="OMPL time limit per pair of stops (tour_costs = 'ompl')"),
    "seed": Param(default=0, kind="int", lo=0, strict=True, doc="k-means' seed"),
    "linger_steps": LINGER_STEPS,
}

# the move that undoes each move (used to walk a BFS tree grown from the target)
_REVERSE = np.array([1, 0, 3, 2, 5, 4, 6])


@dataclass(frozen=True)
class Stop:
    """Hover at ``cell`` for ``steps`` service steps (the arrival step counts as the first)."""

    cell: int
    steps: int


@dataclass
class Plan:
    """An ordered list of stops and how it was made."""

    stops: list[Stop]
    status: str = "ok"
    """How the plan was made, e.g. which solver statuses it rests on, and what it skipped."""
    details: dict[str, Any] = field(default_factory=dict)


UNREACHABLE = "unreachable from the start cell"


@dataclass(frozen=True, eq=False)
class Reach:
    """What the AUV can reach from its start cell, and what that leaves out."""

    cells: np.ndarray
    """(n_cells,) bool: cells a path of moves leads to from the start cell."""
    tables: K.Tables
    """The kernel tables with coverage from reachable cells only."""
    unreachable_nodes: np.ndarray
    """Nodes some cell covers, but only cells the AUV cannot reach."""


def reachable(tables: K.Tables, starts: Iterable[int] | None = None) -> Reach:
    """The cells reachable from ``tables.start_cell`` (or from any of the cells ``starts``:
    a fleet's start cells) through the kernel's own moves, and the tables restricted to them
    (the coverage of every other cell removed)."""
    cells = np.zeros(tables.n_cells, dtype=bool)
    for start in [tables.start_cell] if starts is None else starts:
        dist, _ = bfs_distances(tables.next_cell, int(start))
        cells |= dist >= 0
    counts = np.diff(tables.cov_ptr)
    keep = np.repeat(cells, counts)
    cov_ptr = np.zeros_like(tables.cov_ptr)
    np.cumsum(np.where(cells, counts, 0), out=cov_ptr[1:])
    reachable = dataclasses.replace(
        tables, cov_ptr=cov_ptr, cov_node=tables.cov_node[keep], cov_snr=tables.cov_snr[keep],
        cov_pav=tables.cov_pav[keep],
    )
    lost = np.setdiff1d(np.unique(tables.cov_node), np.unique(reachable.cov_node))
    return Reach(cells, reachable, lost)


def _with_reach(plan: Plan, where: Reach, unreachable_stops: list[int] | None = None) -> Plan:
    """``plan`` with what ``where`` left out recorded in its details and status."""
    skipped = []
    if where.unreachable_nodes.size:
        plan.details["unreachable_nodes"] = [int(i) for i in where.unreachable_nodes]
        skipped.append(f"{where.unreachable_nodes.size} nodes")
    if unreachable_stops:
        plan.details["unreachable_stops"] = unreachable_stops
        skipped.append(f"{len(unreachable_stops)} stops")
    if skipped:
        plan.status += f"; skipped {' and '.join(skipped)} {UNREACHABLE}"
    return plan


class PlanExecutor(Parameterised):
    """Follows a :class:`Plan` in the environment, one action per ``predict``; a planner
    declares its settings in :attr:`parameters` (``linger_steps`` among them, or fixed)."""

    parameters = {"linger_steps": LINGER_STEPS}
    linger_steps: int

    def __init__(self, **settings: Any):
        super().__init__(**settings)
        self._env: Any = None
        self._trees: dict[int, np.ndarray] = {}

    # the planning itself, per subclass
    def make_plan(self, env: Any) -> Plan:  # pragma: no cover - abstract
        raise NotImplementedError

    def begin_episode(self, env: Any, obs: Any = None, info: Any = None) -> None:
        """Plan for ``env`` (the unwrapped :class:`~swiptopt.env.AuvSwiptEnv`) after a reset."""
        if env is not self._env:
            self._env = env
            self._trees = {}
            self.plan_ = self.make_plan(env)
        self._stop = 0
        self._served_steps = 0
        self._lingered = 0

    def _toward(self, cell: int, target: int) -> int | None:
        """The first move of a shortest path from ``cell`` to ``target`` (None: no path)."""
        tree = self._trees.get(target)
        if tree is None:
            _, tree = bfs_distances(self._env.tables.next_cell, target)
            self._trees[target] = tree
        via = tree[0, cell]
        return None if via < 0 else int(_REVERSE[via])

    def _pending_here(self, cell: int) -> bool:
        """Whether a node covered from ``cell`` still holds data."""
        nodes = self._env.tables.covered(cell)
        return bool(np.any(self._env.state.data_left[nodes] > 0))

    def _needs_service(self, cell: int) -> bool:
        t, s = self._env.tables, self._env.state
        gamma = t.named.reward_weight
        return any(not K.is_served(s.data_left, s.energy, t.capacity, gamma, i) for i in t.covered(cell))

    def predict(self, obs: Any, deterministic: bool = True) -> int:
        if self._env is None or self._env.state is None:
            raise RuntimeError("call begin_episode(env, obs, info) after each reset (swiptopt.evaluate does)")
        cell = self._env.state.cell
        stops = self.plan_.stops
        while self._stop < len(stops):
            stop = stops[self._stop]
            if cell != stop.cell:
                move = self._toward(cell, stop.cell)
                if move is None or (self._served_steps == 0 and not self._needs_service(stop.cell)):
                    self._stop += 1  # nothing left to do there, or no way there
                    self._served_steps = 0
                    self._lingered = 0
                    continue
                return move
            if self._served_steps == 0:
                self._served_steps = 1  # the arrival step served
            if self._served_steps < stop.steps:
                self._served_steps += 1
                return K.HOVER
            if self._lingered < self.linger_steps and self._pending_here(cell):
                self._lingered += 1
                return K.HOVER
            self._stop += 1
            self._served_steps = 0
            self._lingered = 0
        return K.HOVER


def route_plan(scenario: Scenario, tables: K.Tables, start: int, order: list[int]) -> Plan:
    """The stops of a route that leaves ``start`` and visits the hover cells ``order`` in turn.

    The AUV moves between consecutive cells along shortest grid paths (``tables.next_cell``);
    stops at the tail whose moves do not fit in the episode are dropped. The steps left after
    the moves (with each stop's arrival step, which serves too) are shared among the stops by
    the dwell program (:func:`planners.power_split.dwell_steps`, at the scenario's split
    ratio) over the links from each cell (``tables``' coverage). Returns the plan with status
    ``"dwell <program status>"`` and details ``travel_moves`` and ``power_split`` (the
    program's result), or no stops with status ``"no stop within the episode"``.
    """
    from planners.power_split import dwell_steps, stop_inputs

    # moves along the grid between consecutive stops; drop the tail that does not fit
    moves = []
    here = start
    for c in order:
        dist, _ = bfs_distances(tables.next_cell, here)
        moves.append(int(dist[c]))
        here = c
    steps = scenario.episode_steps
    keep = len(order)
    while keep and sum(moves[:keep]) > steps:
        keep -= 1
    order, moves = order[:keep], moves[:keep]
    if not order:
        return Plan([], status="no stop within the episode")
    service_steps = steps - sum(moves) + len(order)  # arrival steps serve too

    snr, p_av = hover_link(scenario, np.asarray(order), tables)
    inputs = stop_inputs(scenario, snr, p_av, mission_time_s=service_steps * scenario.step_duration_s)
    dwell, result = dwell_steps(inputs, scenario.step_duration_s, service_steps, service_steps,
                                split_ratio=scenario.split_ratio)
    stops = [Stop(c, int(d)) for c, d in zip(order, dwell)]
    return Plan(stops, status=f"dwell {result.status}", details={"travel_moves": sum(moves), "power_split": result})


class KMeansTspPlanner(PlanExecutor):
    """k-means hover points -> TSP tour -> convex dwell times -> grid moves and hovers.

    ``tour_costs``: ``"euclidean"`` (3D distances between cell centres), ``"grid"``
    (shortest obstacle-avoiding grid paths: the moves the AUV will make), ``"ompl"`` (OMPL
    path lengths around the obstacles, :func:`planners.paths3d.plan_path_3d`), or ``"auto"``:
    euclidean without obstacles, grid with them. OMPL's random generator is process-wide
    (see :mod:`planners.paths3d`), so ``"ompl"`` costs are reproducible only in a fresh
    process; the benchmark keeps the deterministic default. The dwell time at each
    stop comes from :func:`planners.power_split.optimise_dwell_and_split` under the time
    left after travel, with the split ratio fixed at the scenario's (the one the simulator
    applies): a linear program, solved at any number of nodes.
    ``tsp_time_limit_s`` is the TSP's wall-clock safety net (the search itself stops on a
    deterministic budget, :func:`planners.tsp.solve_tsp`); when it hits, the plan's status
    says ``tsp time_limit``.
    """

    parameters = KMEANS_TSP_PARAMETERS

    def make_plan(self, env: Any) -> Plan:
        from planners.tsp import solve_tsp

        scenario = env.scenario
        where = reachable(env.tables)
        tables = where.tables
        # k above the nodes left to group (some may be out of reach) is capped there
        n_coverable = np.unique(tables.cov_node).size
        k = None if self.k is None else min(self.k, n_coverable)
        if n_coverable == 0:
            return _with_reach(Plan([], status="no coverable nodes"), where)
        hover = kmeans_hover_points(scenario, k, rng=self.seed, tables=tables)
        start = tables.start_cell
        cells = [start] + [int(c) for c in hover.cells]
        centres = scenario.cell_centers_m[cells]
        kind = self.tour_costs
        if kind == "auto":
            kind = "grid" if (scenario.obstacles or scenario.seabed_height_m) else "euclidean"
        if kind == "ompl":
            costs = self._ompl_costs(scenario, cells, tables.next_cell)
        elif kind == "grid":
            from planners.grid import distance_matrix

            costs = distance_matrix(tables.next_cell, cells) * scenario.cell_size_m
        else:
            costs = np.linalg.norm(centres[:, None, :] - centres[None, :, :], axis=-1)
        tour = solve_tsp(costs, start=0, closed=False, time_limit_s=self.tsp_time_limit_s, method=self.tsp_method)
        order = [cells[i] for i in tour.order[1:]]

        route = route_plan(scenario, tables, start, order)
        if not route.stops:
            return _with_reach(Plan([], status=route.status), where)
        plan = Plan(
            route.stops,
            status=f"tsp {tour.status}, {route.status}",
            details={"hover_k": hover.k, "tour_length": tour.length, "travel_moves": route.details["travel_moves"],
                     "tour_costs": kind, "power_split": route.details["power_split"]},
        )
        return _with_reach(plan, where)

    def _ompl_costs(self, scenario: Scenario, cells: list[int], next_cell: np.ndarray) -> np.ndarray:
        """OMPL path lengths between the stops; where OMPL finds no exact path in its time
        limit, the grid's shortest path length (always exact for the executed moves)."""
        from planners.grid import distance_matrix
        from planners.paths3d import plan_path_3d

        centres = scenario.cell_centers_m[cells]
        grid = distance_matrix(next_cell, cells) * scenario.cell_size_m
        costs = grid.copy()
        for i in range(len(cells)):
            for j in range(i + 1, len(cells)):
                result = plan_path_3d(centres[i], centres[j], scenario, time_limit_s=self.ompl_time_limit_s)
                if result.exact:
                    costs[i, j] = costs[j, i] = result.length_m
        return costs




class LawnmowerPlanner(PlanExecutor):
    """The standard survey sweep: parallel lanes along x at one depth, lanes spaced by the
    coverage footprint, lingering where covered nodes still hold data."""

    parameters = {
        "depth_cell": Param(default=0, kind="int", lo=0, strict=True, doc="depth of the survey, cells"),
        "lane_spacing_cells": Param(default=None, kind="int", lo=1, hi=100_000, optional=True, strict=True,
                                    doc="lane spacing, cells (default: the cone's footprint)"),
        "linger_steps": LINGER_STEPS,
    }

    def make_plan(self, env: Any) -> Plan:
        scenario = env.scenario
        nx, ny, nz = scenario.grid_shape
        if not 0 <= self.depth_cell < nz:
            raise ConfigError(f"depth_cell = {self.depth_cell} is outside the grid's 0..{nz - 1}", "depth_cell")
        spacing = self.lane_spacing_cells
        if spacing is None:
            depth = (self.depth_cell + 0.5) * scenario.cell_size_m
            nodes = scenario.layout.positions_m[:, 2]
            below = nodes[nodes > depth]
            reach = (np.median(below) - depth) if below.size else scenario.cell_size_m
            radius = reach * math.tan(math.radians(scenario.cone_half_angle_deg))
            spacing = max(1, int(2 * radius // scenario.cell_size_m))
        lanes = list(range(min(spacing // 2, ny - 1), ny, spacing))
        free = ~scenario.blocked_cells
        where = reachable(env.tables)
        stops, unreachable = [], []
        for n, j in enumerate(lanes):
            xs = range(nx) if n % 2 == 0 else range(nx - 1, -1, -1)
            for i in xs:
                c = int(scenario.cell_index((i, j, self.depth_cell)))
                if free[c] and where.cells[c]:
                    stops.append(Stop(c, 1))
                elif free[c]:
                    unreachable.append(c)
        plan = Plan(stops, details={"lane_spacing_cells": spacing, "lanes": lanes})
        return _with_reach(plan, where, unreachable)

    def _needs_service(self, cell: int) -> bool:
        return True  # a survey visits every waypoint


class GreedyPlanner(PlanExecutor):
    """Go to the nearest node still to serve (by grid moves to its best hover cell), hover
    until it is served or ``max_dwell_steps`` pass, repeat."""

    parameters = {"max_dwell_steps": Param(default=8, kind="int", lo=1, hi=1_000_000, strict=True, unit="steps",
                                           doc="hover steps before giving up on a node")}
    linger_steps = 0  # it moves on as soon as a node is served or given up

    def make_plan(self, env: Any) -> Plan:
        where = reachable(env.tables)
        covered, power = coverage_tables(env.scenario, where.tables)
        # each node's best hover cell: the reachable covering cell with the most received power
        self._best_cell = np.where(covered.any(axis=0), np.argmax(np.where(covered, power, -1.0), axis=0), -1)
        return _with_reach(Plan([], status="online"), where)

    def begin_episode(self, env: Any, obs: Any = None, info: Any = None) -> None:
        super().begin_episode(env, obs, info)
        self._target = -1
        self._dwell = 0
        self._given_up: set[int] = set()

    def predict(self, obs: Any, deterministic: bool = True) -> int:
        if self._env is None or self._env.state is None:
            raise RuntimeError("call begin_episode(env, obs, info) after each reset (swiptopt.evaluate does)")
        t, s = self._env.tables, self._env.state
        gamma = t.named.reward_weight
        cell = s.cell
        if self._target >= 0:
            done = K.is_served(s.data_left, s.energy, t.capacity, gamma, self._target)
            if done or self._dwell >= self.max_dwell_steps:
                if not done:
                    self._given_up.add(self._target)
                self._target = -1
        if self._target < 0:
            dist, _ = bfs_distances(t.next_cell, cell)
            best, best_d = -1, None
            for i in range(t.n_nodes):
                c = self._best_cell[i]
                if c < 0 or i in self._given_up or K.is_served(s.data_left, s.energy, t.capacity, gamma, i):
                    continue
                if dist[c] >= 0 and (best_d is None or dist[c] < best_d):
                    best, best_d = i, dist[c]
            if best < 0:
                return K.HOVER
            self._target, self._dwell = best, 0
        target_cell = int(self._best_cell[self._target])
        if cell != target_cell:
            move = self._toward(cell, target_cell)
            if move is not None:
                return move
            self._given_up.add(self._target)  # no way there (the plan keeps to reachable cells)
            self._target = -1
            return K.HOVER
        self._dwell += 1
        return K.HOVER
