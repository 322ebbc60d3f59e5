"""The continuous planners' executor: a plan turned into velocity actions, one per step,
from the current position and the nodes' state (:class:`Executor`).

Along each route it steers straight at the next waypoint with
:func:`swiptopt.continuous.action_towards`, at most one step's length at a time and never
past the waypoint (a sub-segment of a valid segment is valid, so the AUV stays on the planned
path); at a stop it hovers its dwell (zero velocity). Routes join every pair of *sites* (the
start and the hover points of the plan's K, pruned ones included), so that, with
``adaptive``, the executor can react to the nodes' state:

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
  hovering, and goes there or stays.

Without ``adaptive`` it follows the plan as planned and hovers after the last stop. A
commanded move that makes no progress (the env stopped it at an obstacle) gives up that
stop: the executor goes on to the next one, straight from where it is.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from planners.continuous.plan import ARRIVAL_TOLERANCE_M, ContinuousPlan

#: A commanded move shorter than this, m, is no progress (the env stopped it at contact).
NO_PROGRESS_M = 1e-6


class Executor:
    """Turns a plan into actions, one per call, from the current position and the nodes' state.

    One piece of code serves the env (:meth:`TourPlanner.predict`, with the env's state) and
    the model (:meth:`TourPlanner.rollout`, with the model's state), so the model scores what
    the executor does. The rules (module docstring): follow
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
        self.steps = int(world.named.steps)
        self.full_j = np.asarray(world.capacity, dtype=float) * 1e-12  # the kernel's "full" margin
        self.needs_energy = bool(world.named.reward_weight < 1.0)
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
        move_per_j = float(world.named.movement_weight / world.named.move_ref_j)
        self.route_steps = np.zeros((n, n), dtype=np.int64)
        self.route_cost = np.zeros((n, n))
        self.route_ok = np.zeros((n, n), dtype=bool)
        for (i, j), route in self.routes.items():
            self.route_steps[i, j] = route.steps
            self.route_cost[i, j] = move_per_j * route.energy_j
            self.route_ok[i, j] = not route.blocked
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
        return not self.routes[self.site, self.order[i + 1]].blocked

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

