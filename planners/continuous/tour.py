"""The continuous tour planners' shared pipeline (:class:`TourPlanner`): hover points, legs,
the tour, dwells, the choice of K, and the model's rollout of the executor. Subclasses
choose the legs (:mod:`planners.continuous.planners`).

1. **Hover points.** The nodes some position can cover
   (:func:`swiptopt.continuous.coverable_nodes`) are grouped by k-means (scikit-learn, seeded
   as :func:`planners.clustering.kmeans_hover_points` seeds it). Each group's hover point
   starts at the best of a few points above the group (its centroid and its members, at a
   few depths) and is then moved by a deterministic compass search (the six axis moves, the
   step halved when none improves, a fixed number of evaluations) to maximise what one step
   of hovering there earns from the group in the per-step model
   (:func:`planners.continuous.model.hover_values`), less the cost of holding station.
   Every hover point keeps ``clearance_m`` from the obstacles, the seabed and the faces.
2. **Legs** between every pair of sites (the start and the hover points), one plan per
   unordered pair serving both directions (each direction priced on its own: the current
   makes the energy asymmetric). A blocked leg (no free way found) costs
   :data:`BLOCKED_COST_FACTOR` times the dearest leg, so that the tour avoids it.
3. **Tour**: the open path from the start over the hover points minimising the legs' energy
   (or length, :attr:`TourPlanner.tour_cost`), by :func:`planners.tsp.solve_tsp`.
4. **Dwell**: the time left after travel goes to the stops by the convex program
   (:func:`planners.power_split.dwell_steps`) with the split fixed at the one the simulator
   applies (the env's actions cannot set it), rounded to whole steps; the step that arrives
   at a stop serves it too and counts as its first. The program models the power-split
   downlink with the linear harvester; with the logistic harvester or the uplink its dwells
   are a heuristic (the model return still prices them as the simulator does). Stops beyond
   the episode are dropped; then stops are dropped one at a time while the plan earns no
   less without them.
5. **K**: K groups for K from ``k_max`` down (or the given ``k``) are planned, and the plan
   whose whole trajectory earns most in the per-step model is kept; the search stops once
   ``k_patience`` K's in a row earn less than the best so far (``None``: every K from 1 to
   ``k_max``). A plan's model return runs the executor itself
   (:class:`planners.continuous.executor.Executor`, its reactions included) over model
   positions, with the env's own motion and propulsion functions and the model's expected
   service from where each step ends. With a deterministic channel and no link failures it
   is the env's return; with fading it is the expected-rate relaxation of
   :mod:`planners.service`.

Reproducibility: k-means and the compass search are seeded and counted, and the TSP stops on
a deterministic budget; each layout is planned once per planner (cached by its scenario).
"""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import numpy as np

from planners.continuous.executor import Executor
from planners.continuous.model import PointService, hover_values, point_model, step_functions
from planners.continuous.plan import ContinuousPlan, Leg, LegPath, OmplCall, leg_steps
from swiptopt.errors import ConfigError
from swiptopt.validation import Param, Parameterised

#: The largest planner seed (OMPL is seeded with seed + 1, which must be below 2**32).
MAX_SEED = 2**32 - 2

#: A leg that stays blocked costs this many times the dearest leg in the tour's matrix, so
#: that the tour uses it only when it must.
BLOCKED_COST_FACTOR = 100.0

#: When no start above a group keeps the clearance, its search starts from this many of the
#: free cell centres nearest the group's centroid.
FALLBACK_STARTS = 8

#: Depth levels tried above each starting (x, y) of a hover point's search.
START_DEPTH_LEVELS = 4

#: The compass search stops once its step is below this, m.
SEARCH_MIN_STEP_M = 0.25

#: The planner's seed: k-means' (and OMPL's, as seed + 1, which must be below 2**32).
SEED = Param(default=0, kind="int", lo=0, hi=MAX_SEED, strict=True, doc="k-means' seed; OMPL's is seed + 1")

#: The settings every continuous tour planner takes (:class:`TourPlanner`), declared once:
#: the planners' constructors, the benchmark's registry and its listing read them.
TOUR_PARAMETERS: dict[str, Param] = {
    "k": Param(default=None, kind="int", lo=1, optional=True,
               doc="a fixed number of k-means groups (default: every K from k_max down, the best tour kept)"),
    "k_max": Param(default=20, kind="int", lo=1, hi=100, doc="the most groups tried (at most the coverable nodes)"),
    "k_patience": Param(default=2, kind="int", lo=1, hi=100, optional=True,
                        doc="K is searched from k_max down and stops after this many K's worse than the best "
                            "(none: every K from 1 to k_max)"),
    "clearance_m": Param(default=1.0, lo=0, lo_open=True, hi=100, unit="m",
                         doc="distance legs and hover points keep from obstacles and the seabed"),
    "search_evaluations": Param(default=120, kind="int", lo=0, hi=10**6,
                                doc="the hover-point search's budget per point, evaluations"),
    "prune": Param(default=True, kind="bool", doc="drop stops that do not pay for their detour"),
    "tsp_time_limit_s": Param(default=60.0, lo=0, lo_open=True, hi=3600, unit="s",
                              doc="TSP wall-clock safety net (the search stops on a deterministic budget)"),
    "adaptive": Param(default=True, kind="bool",
                      doc="the executor skips stops already served, cuts dwells when its nodes are served, "
                          "lingers while they hold data and spends the steps left where they earn most"),
    "linger_steps": Param(default=2, kind="int", lo=0, hi=1_000_000,
                          doc="extra hover steps while covered nodes hold data (adaptive executor)"),
}


class TourPlanner(Parameterised):
    """The shared pipeline (module docstring); subclasses choose the legs
    (:meth:`leg_between`) and declare their settings in :attr:`parameters`.

    Constructed as ``Planner(seed=0, **settings)``: every setting is a keyword of
    :attr:`parameters`, checked against its declaration and stored as an attribute of the
    same name; ``seed`` seeds k-means (and OMPL, as ``seed + 1``).
    """

    #: The settings, name -> declaration (:class:`swiptopt.validation.Param`).
    parameters = {"seed": SEED, **TOUR_PARAMETERS}
    positional = ("seed",)
    #: What the tour minimises over the legs: ``"energy_j"`` or ``"length"``.
    tour_cost = "energy_j"

    def __init__(self, *args: Any, **settings: Any):
        super().__init__(*args, **settings)
        self._plans: dict[str, ContinuousPlan] = {}
        self._env: Any = None
        self._executor: Executor | None = None
        self.ompl_calls_: list[OmplCall] = []  # the OMPL plans of the layout being planned

    # ------------------------------------------------------------- policy interface

    def begin_episode(self, env: Any, obs: Any = None, info: Any = None) -> None:
        """Plan for ``env``'s layout (once per layout: cached), then start following the plan."""
        key = json.dumps(env.scenario.to_dict(), sort_keys=True, default=str)
        if key not in self._plans:
            self._plans[key] = self.make_plan(env.world, env.scenario)
        self.plan_ = self._plans[key]
        self._env = env
        self._executor = self.executor(self.plan_, env.world)
        self.given_up_ = self._executor.given_up
        self.skipped_ = self._executor.skipped
        self.cut_ = self._executor.cut

    def predict(self, obs: Any, deterministic: bool = True) -> np.ndarray:
        """The next velocity action (3,) float32 (see the module docstring)."""
        if self._executor is None:
            raise RuntimeError("call begin_episode(env, obs, info) after each reset (swiptopt.evaluate does)")
        state = self._env.state
        room_left = np.asarray(self._env.world.capacity) - state.energy
        return self._executor.action(self._env.position, state.data_left, room_left, int(state.t))

    def executor(self, plan: ContinuousPlan, world: Any) -> Executor:
        """A fresh executor of ``plan`` with this planner's reactions."""
        return Executor(plan, world, adaptive=self.adaptive, linger_steps=self.linger_steps)

    # ------------------------------------------------------------- planning

    def make_plan(self, world: Any, scenario: Any) -> ContinuousPlan:
        """Plan the tour for ``world`` (:func:`swiptopt.continuous.build_world` of ``scenario``)."""
        self._scenario = scenario
        self._pair_cache: dict[tuple[bytes, bytes], LegPath] = {}
        self.ompl_calls_: list[OmplCall] = []
        self._service = PointService(world)
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
        return dataclasses.replace(best, candidates=candidates, ompl_plans=tuple(self.ompl_calls_))

    def _empty_plan(self, world: Any, status: str) -> ContinuousPlan:
        sites = np.asarray(world.start_m, dtype=float)[None, :].copy()
        plan = ContinuousPlan(
            0, np.zeros((0, 3)), (), (), np.zeros(0, dtype=np.int64), None, "no_coverage", 0.0, sites,
            np.zeros((0, 3), dtype=np.float32), status, sites_m=sites, site_model=point_model(world, sites),
        )
        return self._scored(world, plan)

    def _scored(self, world: Any, plan: ContinuousPlan) -> ContinuousPlan:
        """``plan`` with the executor's trajectory in the model and its return."""
        positions, actions, model_return = self.rollout(world, plan)
        return dataclasses.replace(plan, positions_m=positions, actions=actions, model_return=model_return)

    def _hover_point(self, world: Any, scenario: Any, group: np.ndarray) -> np.ndarray:
        """The group's hover point: the best start above it, then the compass search. Kept
        per group: neighbouring K share most groups, hence their hover points and the legs
        between them (planned once, :meth:`_pair`)."""
        key = tuple(int(i) for i in group)
        if key not in self._hover_cache:
            self._hover_cache[key] = self.search_hover_point(world, scenario, group)
        return self._hover_cache[key]

    def search_hover_point(self, world: Any, scenario: Any, group: np.ndarray) -> np.ndarray:
        """The hover point of the nodes ``group``: the best start above them, then the
        compass search (module docstring, step 1)."""
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

    def leg_between(self, scenario: Any, a: np.ndarray, b: np.ndarray) -> LegPath:
        """The way from point ``a`` to point ``b`` (3,) m: the subclass's choice."""
        raise NotImplementedError  # pragma: no cover

    def _pair(self, scenario: Any, a: np.ndarray, b: np.ndarray) -> LegPath:
        """The leg a -> b, planned once per unordered pair (the reverse reuses it reversed)."""
        key = (a.tobytes(), b.tobytes())
        if key in self._pair_cache:
            return self._pair_cache[key]
        back = self._pair_cache.get((b.tobytes(), a.tobytes()))
        if back is not None:
            return back.reversed()
        leg = self.leg_between(scenario, a, b)
        self._pair_cache[key] = leg
        return leg

    def _plan_for(
        self, world: Any, scenario: Any, k: int, points: np.ndarray, groups: list[np.ndarray]
    ) -> ContinuousPlan:
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
                path = self._pair(scenario, sites[i], sites[j])
                waypoints = path.waypoints_m
                leg = Leg(waypoints, path_energy_j(waypoints, scenario), leg_steps(waypoints, max_step), path.source,
                          path.blocked)
                routes[i, j] = leg
                if self.tour_cost == "length":
                    cost[i, j] = float(np.linalg.norm(np.diff(waypoints, axis=0), axis=1).sum())
                else:
                    cost[i, j] = leg.energy_j
                blocked[i, j] = path.blocked
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
        steps_total = int(world.named.steps)
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
        """Hover steps after each arrival, from the convex program with the simulator's split
        (:func:`planners.power_split.dwell_steps`)."""
        from planners.power_split import dwell_steps, stop_inputs
        from swiptopt.continuous import coverage_at

        p = world.named
        n = int(world.n_nodes)
        snr = np.zeros((len(points), n))
        pav = np.zeros((len(points), n))
        for s, point in enumerate(points):
            nodes, snr_s, pav_s = coverage_at(world, point)
            nodes = np.asarray(nodes, dtype=np.int64)
            snr[s, nodes] = snr_s
            pav[s, nodes] = pav_s
        step_s = float(p.dt_s)
        inputs = stop_inputs(self._scenario, snr, pav, mission_time_s=service_steps * step_s)
        steps, result = dwell_steps(inputs, step_s, service_steps, max(service_steps, len(points)),
                                    split_ratio=float(p.split_ratio))
        return steps - 1, result.objective, result.status

    def rollout(self, world: Any, plan: ContinuousPlan) -> tuple[np.ndarray, np.ndarray, float]:
        """The executor run in the per-step model: (T + 1, 3) positions, (T, 3) actions and the
        return, moving as the env moves an unobstructed AUV and serving with the model's
        expected amounts (:func:`trajectory_return`'s rules; T < the episode when every node
        is served).

        The executor reacts to the nodes' state, so the positions are not known before the
        run: a run looks up what each position serves among those already computed and
        collects the others, which are computed at once (:class:`PointService`) for the next
        run; the run that finds every position known is the answer. Each run is exact up to
        the first position the one before it lacked, so the runs end.
        """
        _, command, propulsion_j = step_functions()
        p, named = world.params, world.named
        steps = int(named.steps)
        move_weight = named.movement_weight / named.move_ref_j
        hotel_j = named.hotel_j
        capacity = np.asarray(world.capacity, dtype=float)
        data0 = np.asarray(world.data0, dtype=float)
        room0 = np.maximum(capacity - np.asarray(world.energy0, dtype=float), 0.0)
        needs_energy = named.reward_weight < 1.0
        data_weight, energy_weight = plan.site_model.data_weight, plan.site_model.energy_weight
        for _ in range(steps + 1):
            executor = self.executor(plan, world)
            data_left, room_left = data0.copy(), room0.copy()
            positions = np.empty((steps + 1, 3))
            actions = np.empty((steps, 3), dtype=np.float32)
            positions[0] = world.start_m
            total, ran, missing = 0.0, steps, []
            action, unit = np.empty(3), np.empty(3)
            for t in range(steps):
                actions[t] = executor.action(positions[t], data_left, room_left, t)
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

