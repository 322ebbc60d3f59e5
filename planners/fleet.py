"""k-means hover points shared out among a fleet of AUVs by vehicle routing.

:class:`FleetRoutingPlanner` plans for :class:`~swiptopt.env_fleet.AuvFleetEnv` the way
:class:`~planners.policies.KMeansTspPlanner` plans for one AUV:

1. hover points: :func:`~planners.clustering.kmeans_hover_points` over the nodes coverable
   from the cells that some AUV can reach from its start cell;
2. routes: OR-Tools' routing library splits the hover points among the AUVs and orders
   each AUV's share (:func:`route_fleet`, below);
3. dwells: each route's stops get their service steps from the dwell program, through
   :func:`planners.policies.route_plan`, the function the single-AUV planner uses, with the
   AUV's own start cell;
4. execution: each AUV follows its route with :class:`~planners.policies.PlanExecutor`'s
   rules (move along shortest grid paths, hover for the dwell, linger while covered nodes
   hold data, skip stops whose nodes are served, by whichever AUV). A move another AUV
   blocks is tried again at the next step.

The routing model (:func:`route_fleet`). One vehicle per AUV, starting at its own start
cell; the routes are open: each ends at a dummy node reached at cost 0 from everywhere.
An arc costs the grid moves between its cells (breadth-first search over the kernel's
``next_cell``). A time dimension counts a route's steps: the moves to each stop plus the
stop's estimated service steps less one (its arrival step serves), up to the episode's
length. The estimate (:func:`service_steps`) is the steps the stop needs to collect the data
of its k-means group at each link's mean rate; charging is left out, since the dwell program
later shares all the steps left after the moves among the stops, charging included. Each
stop sits in a disjunction with a penalty larger than any route's cost, so a stop is left
out only when it fits in no route; the plan lists those (``dropped_stops``).

``balance="distance"`` minimises the total moves. ``balance="makespan"`` (the default)
starts from the distance routes and minimises the longest route's steps first (the time
dimension's global span, with a coefficient larger than any total of moves), the total
moves second. Because that search starts from the distance routes and keeps the best it
finds, its longest route is never longer than theirs unless it serves more stops.
``balance="return"`` collects prizes instead: a stop's disjunction costs its estimated
value (what its service steps earn in the planners' per-step model,
:class:`planners.service.StepModel`: the reward of the data and energy they deliver), an
arc its moves' movement penalty beyond hovering's, so the routes maximise the estimated
return, value served less propulsion, and leave out a stop that is not worth its detour
(also from the distance routes; its estimate is never below theirs).

Reproducibility follows :mod:`planners.tsp`: a fixed first-solution strategy
(PATH_CHEAPEST_ARC), guided local search stopped by deterministic budgets (``solution_limit``
solutions, and :data:`FAILURES_PER_SOLUTION` failed neighbours per solution of it), the wall
clock (``time_limit_s``) only a safety net whose hitting the status reports (``time_limit``).

OR-Tools and the dwell program's solver load inside the functions that use them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from planners.clustering import HoverPoints, hover_link, kmeans_hover_points
from planners.grid import distance_matrix
from planners.policies import (
    KMEANS_TSP_PARAMETERS,
    LINGER_STEPS,
    Plan,
    PlanExecutor,
    Reach,
    _with_reach,
    reachable,
    route_plan,
)
from planners.tsp import ARGUMENTS as TSP_ARGUMENTS
from planners.tsp import DEFAULT_SOLUTION_LIMIT, DEFAULT_TIME_LIMIT_S, routing_search_parameters
from swiptopt import kernel as K
from swiptopt.acoustics import shannon_rate_bps
from swiptopt.errors import ConfigError
from swiptopt.scenario import Scenario
from swiptopt.validation import Param, Parameterised, Spec, check_value

BALANCES = ("makespan", "distance", "return")
"""What the routes optimise: the longest route's steps, then the total moves; the total
moves alone; or the estimated return (stops' values served less their moves' penalty)."""

RETURN_SCALE = 1_000_000
"""``balance="return"``: the routing's integer costs are the return in units of the most
valuable stop's value over this."""

#: The fleet routing planner's settings (:class:`FleetRoutingPlanner`); ``k``, ``seed`` and
#: ``linger_steps`` are k-means + TSP's own declarations.
FLEET_ROUTING_PARAMETERS = {
    "k": KMEANS_TSP_PARAMETERS["k"],
    "seed": KMEANS_TSP_PARAMETERS["seed"],
    "balance": Param(default="makespan", kind="str", choices=BALANCES,
                     doc="what the routes optimise: the longest route's steps, the total moves, or the "
                         "estimated return"),
    "solution_limit": Param(default=DEFAULT_SOLUTION_LIMIT, kind="int", lo=1, hi=10_000_000, strict=True,
                            doc="guided local search's solution budget, per search"),
    "time_limit_s": Param(default=DEFAULT_TIME_LIMIT_S, lo=0, lo_open=True, hi=3600, unit="s",
                          doc="routing's wall-clock safety net (the search stops on deterministic budgets)"),
    "linger_steps": LINGER_STEPS,
}

FAILURES_PER_SOLUTION = 100
"""Guided local search also stops after this many failed neighbours per solution of its
budget. When no other arrangement of the stops it serves fits (one AUV with one stop, or
an episode so short that one order fits), it finds no new solution and would run until the
clock; this count stops it as deterministically as the solutions do. Searches on the paper's
scenarios fail a few neighbours per solution, so the solutions decide there."""

#: What :func:`route_fleet`'s ``horizon`` and ``move_cost`` may hold.
HORIZON = Spec(kind="int", lo=0, strict=True, unit="steps", doc="the steps a route may take")
MOVE_COST = Spec(lo=0, doc="a move's penalty, in the units of the stops' values")

ROUTING_STATUSES = ("feasible", "time_limit", "no_solution")
"""Values of :attr:`FleetRoutes.status`: routes found within the deterministic budgets (any
run gives the same), routes found but the clock stopped a search first, no routes."""


@dataclass(frozen=True)
class FleetRoutes:
    """Routes found by :func:`route_fleet`."""

    routes: list[list[int]]
    """Per vehicle, its stops (indices into the stop list) in visiting order."""
    dropped: list[int]
    """Stops in no route (they fit in none)."""
    times: list[int]
    """Each route's estimated steps: its moves plus its stops' service steps, less one per
    stop (the arrival step serves)."""
    moves: list[int]
    """Each route's grid moves."""
    status: str
    """One of :data:`ROUTING_STATUSES`."""


@dataclass
class FleetPlan:
    """One plan per AUV (its route's stops) and how they were made."""

    plans: list[Plan]
    status: str = "ok"
    """How the plans were made: the routing's status, each route's dwell program's, what was
    dropped or out of reach."""
    details: dict[str, Any] = field(default_factory=dict)


def service_steps(scenario: Scenario, tables: K.Tables, hover: HoverPoints) -> np.ndarray:
    """(K,) estimated steps each hover point needs, its arrival step included, at least one:
    the steps to collect all the data of the nodes of its k-means group that it covers, at
    each link's mean rate (the downlink at the scenario's split ratio, without fading or link
    failures); the slowest node decides, since a step serves every covered node at once.
    Charging is left out (the dwell program shares the time left among the stops)."""
    snr, _ = hover_link(scenario, hover.cells, tables)
    bits = scenario.step_duration_s * shannon_rate_bps(scenario.bandwidth_hz, scenario.split_ratio * snr)
    data = scenario.layout.data_bits
    out = np.ones(len(hover.cells), dtype=np.int64)
    for g in range(len(hover.cells)):
        mine = (hover.labels == g) & (bits[g] > 0)
        if mine.any():
            out[g] = max(1, int(np.ceil(np.max(data[mine] / bits[g, mine]))))
    return out


class _Model(NamedTuple):
    manager: Any
    routing: Any
    time: Any
    failures: int


def _routing_model(travel: np.ndarray, service: np.ndarray, horizon: int, span_coefficient: int,
                   failures: int, prizes: tuple[np.ndarray, np.ndarray] | None = None) -> _Model:
    """The routing model (module docstring): nodes 0..V-1 the vehicles' starts, V..V+m-1 the
    stops, V+m the dummy end; ``travel`` (V + m, V + m) int moves. ``prizes``: (arc costs
    (V + m, V + m), drop penalties (m,)), integers, for ``balance="return"``; else an arc
    costs its moves and dropping a stop more than any routes could."""
    from ortools.constraint_solver import pywrapcp

    m = len(service)
    v = travel.shape[0] - m
    n = v + m + 1
    moves = np.zeros((n, n), dtype=np.int64)
    moves[: v + m, v : v + m] = travel[:, v:]  # into a stop: its moves; into a start or the end: 0
    time = moves.copy()
    time[:, v : v + m] += np.asarray(service, dtype=np.int64) - 1
    cost = moves
    # more than anything serving a stop could cost: moves <= horizon per route, span <= horizon
    penalties = np.full(m, (int(span_coefficient) + v) * (int(horizon) + 1), dtype=np.int64)
    if prizes is not None:
        cost = np.zeros_like(moves)
        cost[: v + m, v : v + m] = prizes[0][:, v:]
        penalties = prizes[1]
    manager = pywrapcp.RoutingIndexManager(n, v, list(range(v)), [n - 1] * v)
    routing = pywrapcp.RoutingModel(manager)
    routing.SetArcCostEvaluatorOfAllVehicles(routing.RegisterTransitMatrix(cost.tolist()))
    routing.AddDimension(routing.RegisterTransitMatrix(time.tolist()), 0, int(horizon), True, "time")
    dimension = routing.GetDimensionOrDie("time")
    if span_coefficient:
        dimension.SetGlobalSpanCostCoefficient(int(span_coefficient))
    for s in range(m):
        index = manager.NodeToIndex(v + s)
        routing.AddDisjunction([index], int(penalties[s]))
        barred = [k for k in range(v) if travel[k, v + s] > horizon]  # vehicles that cannot reach the stop
        if barred:
            routing.VehicleVar(index).RemoveValues(barred)
    routing.AddSearchMonitor(routing.solver().FailuresLimit(failures))
    return _Model(manager, routing, dimension, failures)


def _search(model: _Model, solution_limit: int, time_limit_s: float,
            initial: list[list[int]] | None = None) -> tuple[Any, str]:
    """Solve ``model`` (from the routes ``initial``, in node numbers, when given): PATH_CHEAPEST_ARC
    then guided local search, as :func:`planners.tsp.solve_tsp`'s routing; (solution or None,
    status)."""
    from ortools.constraint_solver import routing_enums_pb2

    params = routing_search_parameters(solution_limit, time_limit_s)
    routing = model.routing
    if initial is None:
        solution = routing.SolveWithParameters(params)
    else:
        start = routing.ReadAssignmentFromRoutes(initial, True)
        if start is None:  # not a solution of this model (the caller keeps its routes)
            return None, "no_solution"
        solution = routing.SolveFromAssignmentWithParameters(start, params)
    if solution is None:
        return None, "no_solution"
    solver = routing.solver()
    finished = routing.status() == routing_enums_pb2.RoutingSearchStatus.ROUTING_OPTIMAL
    budget = solver.Solutions() >= solution_limit or solver.Failures() >= model.failures
    return solution, ("feasible" if finished or budget else "time_limit")


def _routes_of(model: _Model, solution: Any) -> tuple[list[list[int]], list[int]]:
    """Each vehicle's nodes in visiting order (starts and end left out), and its end time."""
    routing, manager = model.routing, model.manager
    routes, times = [], []
    for k in range(manager.GetNumberOfVehicles()):
        route, index = [], solution.Value(routing.NextVar(routing.Start(k)))
        while not routing.IsEnd(index):
            route.append(manager.IndexToNode(index))
            index = solution.Value(routing.NextVar(index))
        routes.append(route)
        times.append(int(solution.Value(model.time.CumulVar(routing.End(k)))))
    return routes, times


def route_fleet(
    travel: np.ndarray,
    service: np.ndarray,
    horizon: int,
    *,
    balance: str = "makespan",
    values: np.ndarray | None = None,
    move_cost: float = 0.0,
    solution_limit: int = DEFAULT_SOLUTION_LIMIT,
    time_limit_s: float = DEFAULT_TIME_LIMIT_S,
) -> FleetRoutes:
    """Open routes for V vehicles through m stops (the module docstring's model).

    ``travel``: (V + m, V + m) grid moves between the vehicles' start cells (first) and the
    stops' cells, ``inf`` (or above ``horizon``) where there is no path; ``service``: (m,)
    each stop's service steps, its arrival step included; ``horizon``: the steps a route
    may take. ``balance``: one of :data:`BALANCES`; ``"return"`` needs ``values`` (m,), each
    stop's estimated value, and ``move_cost``, a move's penalty in the same units (both
    non-negative). Raises ConfigError on arguments of the wrong shape or range.
    """
    began = time.perf_counter()
    travel = np.asarray(travel, dtype=float)
    service = np.asarray(service, dtype=np.int64).reshape(-1)
    m = len(service)
    v = travel.shape[0] - m
    if travel.ndim != 2 or travel.shape[0] != travel.shape[1] or v < 1:
        raise ConfigError(f"travel must be (V + m, V + m) with V >= 1 vehicles and m = {m} stops, got shape "
                          f"{travel.shape}", "travel")
    if (service < 1).any():
        raise ConfigError("every stop's service steps must be at least 1 (its arrival step)", "service")
    balance = check_value("balance", balance, FLEET_ROUTING_PARAMETERS["balance"])
    horizon = check_value("horizon", horizon, HORIZON)
    solution_limit = check_value("solution_limit", solution_limit, TSP_ARGUMENTS["solution_limit"])
    time_limit_s = check_value("time_limit_s", time_limit_s, TSP_ARGUMENTS["time_limit_s"])
    if balance == "return":
        if values is None:
            raise ConfigError('balance="return" needs values: each stop\'s estimated value', "values")
        values = np.asarray(values, dtype=float).reshape(-1)
        if values.shape != (m,) or not np.isfinite(values).all() or (values < 0).any():
            raise ConfigError(f"values must be {m} finite non-negative numbers, one per stop", "values")
        move_cost = check_value("move_cost", move_cost, MOVE_COST)
    if m == 0:
        return FleetRoutes([[] for _ in range(v)], [], [0] * v, [0] * v, "feasible")
    moves = np.where(np.isfinite(travel) & (travel <= horizon), travel, horizon + 1).astype(np.int64)
    failures = FAILURES_PER_SOLUTION * solution_limit
    model = _routing_model(moves, service, horizon, 0, failures)
    solution, status = _search(model, solution_limit, time_limit_s)
    if solution is None:
        return FleetRoutes([[] for _ in range(v)], list(range(m)), [0] * v, [0] * v, status)
    nodes, times = _routes_of(model, solution)
    if balance != "distance":
        left_s = time_limit_s - (time.perf_counter() - began)
        if left_s <= 0:
            status = "time_limit"  # the distance search used up the safety net
        else:
            if balance == "makespan":
                # one step of the longest route outweighs every route's moves together
                model = _routing_model(moves, service, horizon, v * horizon + 1, failures)
            else:
                model = _routing_model(moves, service, horizon, 0, failures,
                                       prizes=_prizes(moves, values, move_cost))
            solution, second = _search(model, solution_limit, left_s, initial=nodes)
            if solution is not None:
                nodes, times = _routes_of(model, solution)
            status = "time_limit" if "time_limit" in (status, second) else status
    routes = [[node - v for node in route] for route in nodes]
    served = {s for route in routes for s in route}
    return FleetRoutes(
        routes=routes,
        dropped=[s for s in range(m) if s not in served],
        times=times,
        moves=[int(sum(moves[a, b] for a, b in zip([k, *route], route))) for k, route in enumerate(nodes)],
        status=status,
    )


def _prizes(moves: np.ndarray, values: np.ndarray, move_cost: float) -> tuple[np.ndarray, np.ndarray]:
    """``balance="return"``'s integer arc costs and drop penalties: the return in units of
    the largest of the values (and a route's moves' penalty) over :data:`RETURN_SCALE`, each
    arc one unit more per move, so that of two equally valued plans the shorter wins."""
    unit = max(float(values.max(initial=0.0)), move_cost * float(moves.max(initial=0)), 1e-300) / RETURN_SCALE
    arcs = np.rint(moves * (move_cost / unit)).astype(np.int64) + moves
    return arcs, np.rint(values / unit).astype(np.int64)


def stop_values(tables: K.Tables, stops: list[int], service: np.ndarray) -> tuple[np.ndarray, float]:
    """``balance="return"``'s estimates: (m,) what each stop's ``service`` steps earn on their
    own in the planners' per-step model (:func:`planners.service.step_model`: the reward of
    the data and energy delivered, each node capped), and a move's movement penalty beyond
    hovering's (the median over the cells' moves), in reward units."""
    from planners.service import step_model

    model = step_model(tables)
    values = np.zeros(len(stops))
    for s, (cell, steps) in enumerate(zip(stops, service)):
        counts = np.zeros(model.n_cells)
        counts[cell] = steps
        values[s] = model.service_value(counts)
    moving = model.next_cell != np.arange(model.n_cells)[:, None]
    extra = (model.step_cost - model.stay_cost[:, None])[moving]
    return values, float(max(np.median(extra), 0.0)) if extra.size else 0.0


class _AuvState(NamedTuple):
    """What the single AUV's planners read of a kernel state, for one AUV of a fleet."""

    where: np.ndarray
    """(4,) the fleet's ``where`` with this AUV's cell at ``K.W_CELL``."""
    data_left: np.ndarray
    energy: np.ndarray

    @property
    def t(self) -> int:
        return int(self.where[K.W_T])

    @property
    def cell(self) -> int:
        return int(self.where[K.W_CELL])


class AuvView:
    """AUV ``k``'s view of a fleet env, read as the single AUV's kernel env is (by
    :class:`~planners.policies.PlanExecutor` and the stop-choosing episodes): the fleet's
    kernel tables and scenario (the current layout's), and ``state`` (this AUV's cell and
    the step count, the nodes' shared data and energy; None before the first reset)."""

    def __init__(self, env: Any, k: int):
        self._env = env
        self.k = k

    @property
    def tables(self) -> K.Tables:
        return self._env.fleet.tables

    @property
    def scenario(self) -> Scenario:
        return self._env.scenario

    @property
    def state(self) -> _AuvState | None:
        s = self._env.fleet_state
        if s is None:
            return None
        where = s.where.copy()
        where[K.W_CELL] = s.cells[self.k]
        return _AuvState(where, s.data_left, s.energy)


class _RouteFollower(PlanExecutor):
    """Follows one AUV's route: a plan executor whose env is that AUV's :class:`AuvView`."""

    def __init__(self, route: Plan, linger_steps: int):
        super().__init__(linger_steps=linger_steps)
        self._route = route

    def make_plan(self, env: Any) -> Plan:
        return self._route


class FleetRoutingPlanner(Parameterised):
    """k-means hover points -> vehicle routes, one per AUV -> convex dwell times -> grid moves
    and hovers, for a fleet env (:class:`~swiptopt.env_fleet.AuvFleetEnv`); the module
    docstring gives the model.

    A fleet policy: ``begin_episode(env, observations, infos)`` after each reset (plans on
    the first episode of a layout, that is whenever ``env.fleet`` is not the one it planned
    for), then ``act(observations)`` gives one action per live agent. ``plan_`` is a
    :class:`FleetPlan`: ``plans`` (one :class:`~planners.policies.Plan` per AUV), ``status``
    and ``details`` (``hover_k``, ``hover_cells``, ``service_steps``, ``routes`` as cell
    lists, ``route_times``, ``route_moves``, ``dropped_stops``, ``routing_status``,
    ``balance``; with ``balance="return"`` also ``stop_values`` and ``move_cost``, the
    routing's estimates (:func:`stop_values`); ``unreachable_nodes`` when some coverable
    nodes are out of every AUV's reach).
    """

    parameters = FLEET_ROUTING_PARAMETERS
    k: int | None
    seed: int
    balance: str
    solution_limit: int
    time_limit_s: float
    linger_steps: int

    def __init__(self, **settings: Any):
        super().__init__(**settings)
        self._env: Any = None
        self._fleet: Any = None
        self._followers: list[_RouteFollower] = []
        self._views: list[AuvView] = []

    def begin_episode(self, env: Any, observations: Any = None, infos: Any = None) -> None:
        """Plan for ``env`` (an :class:`~swiptopt.env_fleet.AuvFleetEnv` after its reset) when
        its layout is new, and start each AUV at the first stop of its route."""
        if env is not self._env or env.fleet is not self._fleet:
            self._env, self._fleet = env, env.fleet
            self.plan_ = self.make_plan(env)
            self._followers = [_RouteFollower(plan, self.linger_steps) for plan in self.plan_.plans]
            self._views = [AuvView(env, k) for k in range(len(self._followers))]
        for follower, view in zip(self._followers, self._views):
            follower.begin_episode(view)

    def act(self, observations: Any = None) -> dict[str, int]:
        """One action per live agent of the env (``observations`` is not read: the routes and
        the env's state decide)."""
        if self._env is None or self._env.fleet_state is None:
            raise RuntimeError("call begin_episode(env, observations, infos) after each reset "
                               "(swiptopt.evaluation.evaluate_fleet does)")
        live = set(self._env.agents)
        return {
            agent: follower.predict(None)
            for agent, follower in zip(self._env.possible_agents, self._followers)
            if agent in live
        }

    def make_plan(self, env: Any) -> FleetPlan:
        """Hover points, routes and dwells for the fleet env ``env`` (class docstring)."""
        scenario, fleet = env.scenario, env.fleet
        starts = [int(c) for c in fleet.start_cells]
        where = reachable(fleet.tables, starts)
        tables = where.tables
        n_coverable = np.unique(tables.cov_node).size
        if n_coverable == 0:
            summary = _with_reach(Plan([], status="no coverable nodes"), where)
            return FleetPlan([Plan([], status="no coverable nodes") for _ in starts], summary.status, summary.details)
        k = None if self.k is None else min(self.k, n_coverable)
        hover = kmeans_hover_points(scenario, k, rng=self.seed, tables=tables)
        stops = [int(c) for c in hover.cells]
        service = service_steps(scenario, tables, hover)
        values, move_cost = stop_values(tables, stops, service) if self.balance == "return" else (None, 0.0)
        found = route_fleet(distance_matrix(tables.next_cell, starts + stops), service, scenario.episode_steps,
                            balance=self.balance, values=values, move_cost=move_cost,
                            solution_limit=self.solution_limit, time_limit_s=self.time_limit_s)
        plans = []
        for start, route in zip(starts, found.routes):
            cells = [stops[s] for s in route]
            plans.append(route_plan(scenario, tables, start, cells) if cells else Plan([], status="no stops"))
        plan = self._summary(plans, where, hover, service, found)
        if values is not None:
            plan.details.update(stop_values=[float(x) for x in values], move_cost=move_cost)
        return plan

    def _summary(self, plans: list[Plan], where: Reach, hover: HoverPoints, service: np.ndarray,
                 found: FleetRoutes) -> FleetPlan:
        """The fleet plan: the AUVs' plans with the routing's status and details."""
        stops = [int(c) for c in hover.cells]
        status = f"routing {found.status}; " + ", ".join(f"auv {k}: {p.status}" for k, p in enumerate(plans))
        if found.dropped:
            status += f"; dropped {len(found.dropped)} stops that fit in no route"
        details = {
            "hover_k": int(hover.k),
            "hover_cells": stops,
            "service_steps": [int(s) for s in service],
            "routes": [[stops[s] for s in route] for route in found.routes],
            "route_times": found.times,
            "route_moves": found.moves,
            "dropped_stops": [stops[s] for s in found.dropped],
            "routing_status": found.status,
            "balance": self.balance,
        }
        summary = _with_reach(Plan([], status=status, details=details), where)
        return FleetPlan(plans, summary.status, summary.details)
