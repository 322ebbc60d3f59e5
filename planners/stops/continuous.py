"""The continuous world's stop-choice environment: the action is the next hover point and its
dwell, the legs between hover points planned once per layout.

Candidates (:func:`build_continuous_stops`): one hover point per coverable node, found by the
continuous tour planners' own search for a group of one node (:mod:`planners.continuous`,
step 1: the best start above the node, then the compass search on what one step there earns
from it, keeping ``clearance_m`` from obstacles, seabed and faces). Legs between every pair
of sites (the start and the hover points), with ``legs="ompl"`` (the default) by the OMPL
tour's leg logic (:class:`planners.continuous.OmplTourPlanner`): the straight segment when it
keeps the clearance, else OMPL's AUV-energy path around the obstacles after
``ompl_iterations`` iterations (a count, not the clock). OMPL's seed is process-wide
(:mod:`planners.paths3d`), so a path would depend on what the process planned before; the
blocked legs of a layout are therefore planned in a fresh child process (``spawn``), seeded
with ``planner_seed + 1`` as the tour planners seed OMPL, in a fixed order: a layout's legs are
a function of the scenario and the settings alone, whichever process asks and in whatever
order. A pair OMPL cannot join exactly has no usable leg (masked from that site). With
``legs="straight"`` every leg is the straight segment, obstacles ignored, and a move that
makes no progress (the env stopped it at contact) ends the decision where the AUV is, as the
straight-line planner's executor gives up a stop; the next legs then start from there, straight.

Execution (:class:`ContinuousMove`) is the continuous executor's: along the leg, straight at
the next waypoint with :func:`swiptopt.continuous.action_towards`, at most one step's length at
a time and never past the waypoint; then hovers (zero command) for the dwell.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from planners.continuous import (
    ARRIVAL_TOLERANCE_M,
    MAX_SEED,
    NO_PROGRESS_M,
    LegPath,
    OmplTourPlanner,
    leg_steps,
    point_model,
)
from planners.stops.base import (
    DWELLS,
    MASKED_ACTIONS,
    Dwell,
    StopEnvBase,
    check_dwells,
    layout_key,
    node_worth,
)
from swiptopt import kernel as K
from swiptopt.env import LAYOUT_CACHE_SIZE
from swiptopt.scenario import Scenario
from swiptopt.validation import Param, Spec, check_value

#: How the legs between sites are made (module docstring).
LEGS = ("ompl", "straight")


@dataclass(frozen=True)
class ContinuousStopSettings:
    """The choices of :class:`ContinuousStopChoiceEnv` (see its docstring, Arguments)."""

    dwells: tuple[Dwell, ...] = DWELLS
    legs: str = "ompl"
    """:data:`LEGS`."""
    clearance_m: float = 1.0
    """Distance hover points and OMPL legs keep from obstacles and seabed (hover points also
    from the faces), m."""
    ompl_iterations: int = 150
    """OMPL's budget per blocked leg, planner iterations."""
    ompl_planner: str = "InformedRRTstar"
    search_evaluations: int = 120
    """The hover-point search's budget per node, evaluations."""
    planner_seed: int = 0
    """k-means-free here; OMPL's seed in the legs' process is ``planner_seed + 1``."""
    masked_action: str = "raise"

    def __post_init__(self) -> None:
        object.__setattr__(self, "dwells", check_dwells(self.dwells))
        check_value("legs", self.legs, Spec(kind="str", choices=LEGS))
        check_value("masked_action", self.masked_action, Spec(kind="str", choices=MASKED_ACTIONS))
        # the tour planners' declarations of the settings they share with this env
        declared = OmplTourPlanner.parameters
        for name in ("clearance_m", "ompl_iterations", "ompl_planner", "search_evaluations"):
            object.__setattr__(self, name, check_value(name, getattr(self, name), declared[name]))
        seed = Param(kind="int", lo=0, hi=MAX_SEED)
        object.__setattr__(self, "planner_seed", check_value("planner_seed", self.planner_seed, seed))

    def layout_settings(self) -> tuple:
        """The settings the stops layout depends on (not the dwells, not the masked actions)."""
        return (self.legs, self.clearance_m, self.ompl_iterations, self.ompl_planner, self.search_evaluations,
                self.planner_seed)


@dataclass(frozen=True, eq=False)
class ContinuousStops:
    """The candidate hover points of one layout, the legs between them and what deciding
    among them needs, built once (:func:`build_continuous_stops`)."""

    points_m: np.ndarray
    """(C,) x 3: each candidate's hover point, m (the start where the stop does not exist)."""
    valid: np.ndarray
    """(C,) bool: the stop exists (its node coverable, its hover point covers it)."""
    why_invalid: tuple[str, ...]
    covered: tuple[np.ndarray, ...]
    """Per candidate, the nodes its hover point covers."""
    pair_cand: np.ndarray
    pair_node: np.ndarray
    pair_bits: np.ndarray
    pair_joules: np.ndarray
    route_steps: np.ndarray
    """(C + 1, C) int64: kernel steps of the leg from site s (0: the start, c + 1: candidate c)
    to candidate c; -1 where there is no usable leg."""
    routes: dict[tuple[int, int], np.ndarray]
    """(site, candidate) -> (k, 3) waypoints, m."""
    sources: dict[tuple[int, int], str]
    """(site, candidate) -> how the leg was made (:class:`planners.continuous.Leg` ``source``)."""
    data_weight: float
    energy_weight: float
    worth: float
    capacity: np.ndarray
    params: np.ndarray
    nodes_norm: np.ndarray
    max_step_m: float

    start_site = 0

    @staticmethod
    def hover() -> np.ndarray:
        return np.zeros(3, dtype=np.float32)

    @property
    def n_candidates(self) -> int:
        return len(self.points_m)

    def reach_steps(self, env: Any, site: int | None) -> np.ndarray:
        """(C,) steps of the way from where the AUV is to each candidate (-1: none): the
        planned leg from a site, the straight segment from elsewhere."""
        if site is not None:
            return self.route_steps[site]
        travel = np.linalg.norm(self.points_m - env.position, axis=1) / self.max_step_m
        return np.where(self.valid, np.ceil(travel - 1e-9), -1).astype(np.int64)

    def move(self, env: Any, site: int | None, candidate: int, dwell: Dwell) -> ContinuousMove:
        if site is not None:
            waypoints = self.routes[site, candidate]
        else:
            waypoints = np.stack([env.position, self.points_m[candidate]])
        return ContinuousMove(waypoints, candidate + 1, self.covered[candidate], dwell, self.max_step_m)

    def base_observation(self, env: Any) -> np.ndarray:
        """The continuous env's vector observation of its state."""
        from swiptopt import continuous as C

        w, s = env.world, env.state
        n = w.n_nodes
        out = np.empty(4 + K.VECTOR_NODE_FEATURES * n, dtype=np.float32)
        C.observe(w.world, w.nodes_m, env.position, s.where, np.empty(n, dtype=np.int64), np.empty(n), np.empty(n),
                  s.data_left, s.energy, w.data0, w.capacity, w.params, self.nodes_norm, out)
        return out


def _ompl_legs(scenario: Scenario, sites: np.ndarray, pairs: list[tuple[int, int]], clearance_m: float,
               iterations: int, planner_name: str, seed: int) -> list[LegPath]:
    """The OMPL tour's legs between the given pairs of sites, in order; OMPL's seed is
    ``seed + 1`` (as :class:`planners.continuous.OmplTourPlanner` seeds it), which makes the
    legs reproducible only in a process that has planned nothing before
    (:func:`_plan_in_fresh_process`)."""
    planner = OmplTourPlanner(seed, clearance_m=clearance_m, ompl_iterations=iterations, ompl_planner=planner_name)
    return [planner.leg_between(scenario, sites[i], sites[j]) for i, j in pairs]


def _plan_in_fresh_process(scenario: Scenario, sites: np.ndarray, pairs: list[tuple[int, int]], clearance_m: float,
                           iterations: int, planner_name: str, seed: int) -> list[LegPath]:
    """:func:`_ompl_legs` in a fresh Python process (OMPL's first plan there), talking JSON over
    its standard input and output (floats round-trip exactly through JSON's shortest repr)."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    import planners

    root = str(Path(planners.__file__).resolve().parent.parent)
    request = json.dumps({
        "scenario": scenario.to_dict(), "sites": np.asarray(sites, dtype=float).tolist(),
        "pairs": [list(map(int, p)) for p in pairs], "clearance_m": clearance_m, "iterations": iterations,
        "planner": planner_name, "seed": seed,
    })
    code = f"import sys; sys.path.insert(0, {root!r}); from planners.stops.continuous import _serve_legs; _serve_legs()"
    run = subprocess.run([sys.executable, "-c", code], input=request, capture_output=True, text=True)
    if run.returncode != 0:
        raise RuntimeError(
            f"planning the legs in a fresh process failed (exit {run.returncode}):\n{run.stderr[-2000:]}"
        )
    legs = json.loads(run.stdout)
    return [LegPath(np.array(w, dtype=float).reshape(-1, 3), str(source), bool(blocked)) for w, source, blocked in legs]


def _serve_legs() -> None:
    """The child's side of :func:`_plan_in_fresh_process`: a request on stdin, the legs on stdout."""
    import json
    import sys

    request = json.loads(sys.stdin.read())
    legs = _ompl_legs(Scenario.from_dict(request["scenario"]), np.array(request["sites"], dtype=float),
                      [tuple(p) for p in request["pairs"]], request["clearance_m"], request["iterations"],
                      request["planner"], request["seed"])
    json.dump(
        [[np.asarray(leg.waypoints_m, dtype=float).tolist(), leg.source, leg.blocked] for leg in legs], sys.stdout
    )


def build_continuous_stops(world: Any, scenario: Scenario, settings: ContinuousStopSettings) -> ContinuousStops:
    """The candidate hover points of ``scenario``'s layout (``world`` its
    :func:`swiptopt.continuous.build_world`) and the legs between them (module docstring)."""
    start = np.asarray(world.start_m, dtype=float)
    points, valid, why, covered = _hover_points(world, scenario, settings)
    sites = np.concatenate([start[None, :], points])
    legs = _legs(scenario, sites, valid, settings)
    max_step = float(world.max_step_m)
    route_steps, routes, sources = _routes(legs, sites, valid, max_step)

    model = point_model(world, points)
    keep = valid[model.cell_of_pair()]
    p = world.params
    return ContinuousStops(
        points_m=points,
        valid=valid,
        why_invalid=tuple(why),
        covered=tuple(covered),
        pair_cand=model.cell_of_pair()[keep],
        pair_node=model.cov_node[keep],
        pair_bits=model.bits[keep],
        pair_joules=model.joules[keep],
        route_steps=route_steps,
        routes=routes,
        sources=sources,
        data_weight=model.data_weight,
        energy_weight=model.energy_weight,
        worth=node_worth(K.named(p), scenario.data_bits, scenario.storage_capacity_j),
        capacity=np.asarray(world.capacity, dtype=float),
        params=p,
        nodes_norm=np.ascontiguousarray(scenario.layout.positions_m / scenario.extent_m),
        max_step_m=max_step,
    )


def _hover_points(
    world: Any, scenario: Scenario, settings: ContinuousStopSettings
) -> tuple[np.ndarray, np.ndarray, list[str], list[np.ndarray]]:
    """Each node's hover point (the start where there is none), whether the stop exists, why
    not, and the nodes each hover point covers (none for a stop that does not exist)."""
    from planners.continuous import StraightLinePlanner
    from swiptopt.continuous import coverable_nodes, coverage_at

    n = int(world.n_nodes)
    start = np.asarray(world.start_m, dtype=float)
    searcher = StraightLinePlanner(settings.planner_seed, clearance_m=settings.clearance_m,
                                   search_evaluations=settings.search_evaluations)
    coverable = coverable_nodes(scenario)
    points = np.repeat(start[None, :], n, axis=0)
    valid = np.zeros(n, dtype=bool)
    why = [""] * n
    covered: list[np.ndarray] = []
    for i in range(n):
        if not coverable[i]:
            why[i] = f"no free position covers node {i}"
        else:
            point = searcher.search_hover_point(world, scenario, np.array([i]))
            nodes = coverage_at(world, point)[0]
            if i in nodes:
                points[i], valid[i] = point, True
            else:
                why[i] = f"the hover point search found no point that covers node {i}"
        covered.append(coverage_at(world, points[i])[0] if valid[i] else np.zeros(0, dtype=np.int64))
    for i in range(n):  # no two actions alike: a hover point equal to an earlier one is a copy
        for j in range(i):
            if valid[i] and valid[j] and np.array_equal(points[i], points[j]):
                valid[i], why[i] = False, f"its hover point is stop {j}'s"
                break
    return points, valid, why, covered


def _legs(
    scenario: Scenario, sites: np.ndarray, valid: np.ndarray, settings: ContinuousStopSettings
) -> dict[tuple[int, int], LegPath]:
    """The leg of every unordered pair of sites (i < j) the AUV may sit at both ends of:
    straight, or (``legs="ompl"``) straight where that keeps the clearance and planned by
    OMPL in a fresh process where it does not."""
    from planners.paths3d import segments_free

    n = len(valid)
    wanted: list[tuple[int, int]] = []  # unordered pairs of sites (i < j), both of which the AUV may sit at
    for i in range(n + 1):
        for j in range(i + 1, n + 1):
            if (i == 0 or valid[i - 1]) and valid[j - 1]:
                wanted.append((i, j))
    legs: dict[tuple[int, int], LegPath] = {}
    if settings.legs == "straight":
        for i, j in wanted:
            legs[i, j] = LegPath(np.stack([sites[i], sites[j]]), "straight (obstacles ignored)")
        return legs
    a = np.array([sites[i] for i, _ in wanted]).reshape(-1, 3)
    b = np.array([sites[j] for _, j in wanted]).reshape(-1, 3)
    free = segments_free(a, b, scenario, clearance_m=settings.clearance_m)
    blocked = [pair for pair, ok in zip(wanted, free) if not ok]
    for pair, ok in zip(wanted, free):
        if ok:
            legs[pair] = LegPath(np.stack([sites[pair[0]], sites[pair[1]]]), "straight")
    if blocked:
        planned = _plan_in_fresh_process(scenario, sites, blocked, settings.clearance_m, settings.ompl_iterations,
                                         settings.ompl_planner, settings.planner_seed)
        legs.update(zip(blocked, planned))
    return legs


def _routes(
    legs: dict[tuple[int, int], LegPath], sites: np.ndarray, valid: np.ndarray, max_step: float
) -> tuple[np.ndarray, dict[tuple[int, int], np.ndarray], dict[tuple[int, int], str]]:
    """Each leg both ways, by (site, candidate): its kernel steps (-1: not usable), its
    waypoints and how it was made; a candidate's own site reaches it in no steps."""
    n = len(valid)
    route_steps = np.full((n + 1, n), -1, dtype=np.int64)
    routes: dict[tuple[int, int], np.ndarray] = {}
    sources: dict[tuple[int, int], str] = {}
    for c in np.flatnonzero(valid):
        routes[c + 1, c] = sites[c + 1 : c + 2].copy()
        sources[c + 1, c] = "here"
        route_steps[c + 1, c] = 0
    for (i, j), leg in legs.items():
        for site, cand, path in ((i, j - 1, leg.waypoints_m), (j, i - 1, leg.waypoints_m[::-1].copy())):
            if cand < 0:
                continue  # no leg leads to the start
            routes[site, cand] = path
            sources[site, cand] = leg.source
            route_steps[site, cand] = -1 if leg.blocked else leg_steps(path, max_step)
    return route_steps, routes, sources


#: Stops layouts built in this process, shared by every env and adapter (the last
#: :data:`~swiptopt.env.LAYOUT_CACHE_SIZE`): each layout's hover points and legs are made once.
_BUILT: OrderedDict[tuple, ContinuousStops] = OrderedDict()


def continuous_stops(world: Any, scenario: Scenario, settings: ContinuousStopSettings) -> ContinuousStops:
    """:func:`build_continuous_stops`, cached per scenario and layout settings in this process."""
    key = (layout_key(scenario), settings.layout_settings())
    built = _BUILT.pop(key, None)
    if built is None:
        built = build_continuous_stops(world, scenario, settings)
    _BUILT[key] = built
    if len(_BUILT) > LAYOUT_CACHE_SIZE:
        _BUILT.popitem(last=False)
    return built


class ContinuousMove:
    """Carries out one decision in the continuous world, one action per call: along the
    leg's waypoints as the continuous executor does, then hovers for the dwell. A move that
    made no progress towards its waypoint (stopped at contact) ends the decision there."""

    def __init__(self, waypoints: np.ndarray, site: int, covered: np.ndarray, dwell: Dwell, max_step_m: float):
        self.waypoints = waypoints
        self.waypoint = 1
        self.target_site = site
        self.site_after: int | None = site
        self.covered = covered
        self.dwell = dwell
        self.max_step_m = max_step_m
        self.moved = False
        self.service = 0
        self.last: tuple[np.ndarray, int] | None = None
        self.given_up = False

    def _dwell_over(self, env: Any) -> bool:
        s, w = env.state, env.world
        if self.dwell.until == "data":
            return not bool(np.any(s.data_left[self.covered] > 0.0))
        unserved = ~K.served_mask(s.data_left[self.covered], s.energy[self.covered], w.capacity[self.covered],
                                  w.named.reward_weight)
        return not bool(unserved.any())

    def next_action(self, env: Any) -> np.ndarray | None:
        from swiptopt.continuous import action_towards

        position = env.position
        while self.waypoint < len(self.waypoints):
            target = self.waypoints[self.waypoint]
            if math.dist(target, position) <= ARRIVAL_TOLERANCE_M:
                self.waypoint += 1
                continue
            stuck = self.last is not None and math.dist(position, self.last[0]) < NO_PROGRESS_M
            if stuck and self.last[1] == self.waypoint:
                self.given_up = True  # stopped at contact: the decision ends where the AUV is
                self.site_after = None
                return None
            self.last = (position, self.waypoint)
            self.moved = True
            return np.asarray(action_towards(position, target, self.max_step_m), dtype=np.float32)
        if self.moved and self.service == 0:
            self.service = 1  # the arrival step served
        if self.service >= self.dwell.steps:
            return None
        if self.service >= 1 and self.dwell.until is not None and self._dwell_over(env):
            return None
        self.service += 1
        return np.zeros(3, dtype=np.float32)


class ContinuousStopChoiceEnv(StopEnvBase):
    """
    ## Description

    The continuous world of ``swiptopt/AuvSwiptContinuous-v0`` decided one hover point at a
    time: each action picks the next candidate hover point and the dwell there; the AUV then
    follows the leg to it and hovers, each command a step of the wrapped
    :class:`swiptopt.env_continuous.AuvSwiptContinuousEnv`. Candidate c is node c's hover point
    (the tour planners' search for a group of one node), the legs those of the OMPL tour
    (default) or straight (module docstring).

    ## Action Space, Masks, Observation Space

    As :class:`planners.stops.StopChoiceEnv`'s with n_nodes candidates: ``Discrete(n_nodes D
    + 1)``; (c, d) allowed when hover point c exists, a usable leg leads there from where the
    AUV is, a node it covers still needs something and the leg's steps plus the dwell's fewest
    fit the steps left; the observation is the continuous env's vector observation and, per
    candidate, the leg's steps over ``episode_steps``, what one step and the longest fixed
    dwell there earn now (squashed) and whether it is allowed.

    ## Starting State, Rewards, Episode End, Layouts

    As :class:`planners.stops.StopChoiceEnv`'s: rewards are sums of kernel rewards, the
    episode is the kernel's, the layouts are the wrapped env's. A layout's hover points and
    legs are built once per process (the last 64 kept) and shared by every env and adapter in
    it; with OMPL legs the blocked ones are planned in a fresh process, so they are the same
    in any process. ``info`` also says ``given_up`` when a move was stopped at contact.

    ## Arguments

    ``ContinuousStopChoiceEnv(scenario=None, *, preset="harbour", layout_seeds=None,
    backend="auto", render_mode=None, dwells=DWELLS, legs="ompl", clearance_m=1.0,
    ompl_iterations=150, ompl_planner="InformedRRTstar", search_evaluations=120,
    planner_seed=0, masked_action="raise", **overrides)``: the wrapped env's arguments and
    :class:`ContinuousStopSettings`.

    ## Version History

    - v0: initial version.
    """

    def __init__(
        self,
        scenario: Scenario | None = None,
        *,
        preset: str = "harbour",
        layout_seeds: Sequence[int] | None = None,
        backend: str = "auto",
        render_mode: str | None = None,
        dwells: Sequence[Dwell | int] = DWELLS,
        legs: str = "ompl",
        clearance_m: float = 1.0,
        ompl_iterations: int = 150,
        ompl_planner: str = "InformedRRTstar",
        search_evaluations: int = 120,
        planner_seed: int = 0,
        masked_action: str = "raise",
        **overrides: Any,
    ):
        from swiptopt.env_continuous import AuvSwiptContinuousEnv

        self.settings = ContinuousStopSettings(tuple(dwells), legs, clearance_m, ompl_iterations, ompl_planner,
                                               search_evaluations, planner_seed, masked_action)
        self.env = AuvSwiptContinuousEnv(scenario, preset=preset, render_mode=render_mode, backend=backend,
                                         layout_seeds=layout_seeds, **overrides)
        self._init_spaces()

    @property
    def n_candidates(self) -> int:
        return self.env.scenario.n_nodes

    @classmethod
    def build_layout(cls, env: Any, settings: ContinuousStopSettings) -> ContinuousStops:
        return continuous_stops(env.world, env.scenario, settings)
