"""k-means + TSP with every choice scored by the simulator's own per-step reward.

:class:`~planners.policies.KMeansTspPlanner` picks the smallest number of k-means groups
whose nodes each fit one coverage footprint, hovers where a cell covers most of a group,
orders the stops by a TSP over straight-line distances and splits the time left by the
convex dwell/split program. On the paper preset that plan spends almost the whole episode
travelling between 14-17 hover points: the groups are chosen for coverage (collect every
node's data, worth a third of a fully served node) rather than for the energy that only
dwell delivers, and the convex program optimises a split ratio per node that the simulator
does not apply. :class:`RewardKMeansTspPlanner` keeps the pipeline and changes its choices:

- ``selection="reward"``: for every K up to ``k_max`` (k-means of the coverable nodes, the
  same seeded scikit-learn call), hover where a cell earns the most reward per step from its
  group (:func:`planners.service.step_model`), order the stops by an exact open TSP over
  grid moves (Held-Karp), allocate the dwell, drop stops that do not pay for their detour,
  and keep the K whose walk earns most in the simulator's own model;
- ``dwell="steps"``: whole service steps, each given to the stop where it adds the most
  reward, counted as the simulator counts it (per-step amounts capped by what each node
  still needs), instead of the convex program's continuous dwell.

``selection="coverage"`` with ``dwell="convex"`` and ``linger_steps=2`` plans exactly what
:class:`~planners.policies.KMeansTspPlanner` plans; mixing the settings measures what each
choice is worth.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from planners.policies import KMEANS_TSP_PARAMETERS, LINGER_STEPS, KMeansTspPlanner, Plan, Stop
from planners.service import StepModel, step_model
from planners.walk_search import Walks
from swiptopt import fpmath
from swiptopt.validation import Param

SELECTIONS = ("reward", "coverage")
DWELLS = ("steps", "convex")

#: Held-Karp orders at most this many stops (13 nodes with the start): exact and fast.
MAX_EXACT_STOPS = 12

#: The reward tour's settings: k-means + TSP's and its own (:class:`RewardKMeansTspPlanner`).
REWARD_TOUR_PARAMETERS = {
    "selection": Param(default="reward", kind="str", choices=SELECTIONS,
                       doc="hover points: 'reward' (every K up to k_max, each walk scored by the simulator's "
                           "reward) or 'coverage' (the fewest groups that fit the cone)"),
    "dwell": Param(default="steps", kind="str", choices=DWELLS,
                   doc="dwell: 'steps' (whole steps by marginal reward) or 'convex' (the convex dwell/split program)"),
    **KMEANS_TSP_PARAMETERS,
    "k": Param(default=None, kind="int", lo=1, optional=True, strict=True,
               doc="hover groups (default: chosen by the selection rule)"),
    "k_max": Param(default=MAX_EXACT_STOPS, kind="int", lo=1, hi=100, strict=True,
                   doc="largest K the reward selection tries"),
    "linger_steps": Param(**{**dataclasses.asdict(LINGER_STEPS), "default": 0}),
}


class RewardKMeansTspPlanner(KMeansTspPlanner):
    """k-means hover points, TSP order and dwell chosen for the simulator's reward (module doc).

    ``k``: a fixed number of groups (else every K from 1 to ``k_max`` is tried with
    ``selection="reward"``, or the footprint rule with ``"coverage"``). The other arguments
    are :class:`KMeansTspPlanner`'s; the TSP settings apply to the coverage selection and
    to tours longer than :data:`MAX_EXACT_STOPS` stops.
    """

    parameters = REWARD_TOUR_PARAMETERS

    def make_plan(self, env: Any) -> Plan:
        if self.selection == "coverage" and self.dwell == "convex":
            return super().make_plan(env)
        scenario = env.scenario
        model = step_model(env.tables)
        walks = Walks(model)
        best: tuple[float, list[int], list[int], int] | None = None
        for k, cells in self._hover_sets(scenario, env, model):
            order = self._order(scenario, env, walks, cells)
            if self.selection == "reward":
                order = self._prune(scenario, walks, order)
            dwell, value = self._allocate(scenario, walks, order)
            if best is None or value > best[0] + 1e-12:
                best = (value, order, dwell, k)
        if best is None or not best[1]:
            return Plan([], status="no coverable nodes")
        value, order, dwell, k = best
        return Plan(
            [Stop(c, int(d)) for c, d in zip(order, dwell)],
            status=f"{self.selection} selection, {self.dwell} dwell",
            details={"hover_k": k, "stops": len(order), "model_return": value},
        )

    # ---------------------------------------------------------------- the choices

    def _hover_sets(self, scenario: Any, env: Any, model: StepModel):  # type: ignore[no-untyped-def]
        """(K, hover cells) candidates: k-means groups, a hover cell per group."""
        from planners.clustering import kmeans_hover_points

        if self.selection == "coverage":
            hover = kmeans_hover_points(scenario, self.k, rng=self.seed, tables=env.tables)
            yield hover.k, list(dict.fromkeys(int(c) for c in hover.cells))
            return
        from sklearn.cluster import KMeans

        coverable = np.flatnonzero(model.coverable())
        if coverable.size == 0:
            return
        positions = scenario.layout.positions_m[coverable]
        seed = int(np.random.default_rng(self.seed).integers(2**31 - 1))  # as kmeans_hover_points
        pair_cell = model.cell_of_pair()
        per_pair = model.data_weight * model.bits + model.energy_weight * model.joules
        ks = [self.k] if self.k is not None else range(1, min(self.k_max, coverable.size) + 1)
        for k in ks:
            labels = KMeans(n_clusters=k, n_init=4, random_state=seed).fit(positions).labels_
            cells = []
            for g in range(k):
                members = np.isin(model.cov_node, coverable[labels == g])
                reward = np.bincount(pair_cell, weights=np.where(members, per_pair, 0.0), minlength=model.n_cells)
                cells.append(int(np.argmax(reward)))  # the most reward per step from the group
            yield k, list(dict.fromkeys(cells))

    def _order(self, scenario: Any, env: Any, walks: Walks, cells: list[int]) -> list[int]:
        """The stops in tour order from the start (exact over grid moves when small)."""
        from planners.grid import distance_matrix
        from planners.tsp import held_karp, solve_tsp

        tables = env.tables
        nodes = [tables.start_cell] + cells
        if self.selection == "reward" and len(cells) <= MAX_EXACT_STOPS:
            moves = distance_matrix(tables.next_cell, nodes)
            order, _ = held_karp(np.where(np.isfinite(moves), moves, 1e9), start=0, closed=False)
        else:
            kind = self.tour_costs
            if kind == "auto":
                kind = "grid" if (scenario.obstacles or scenario.seabed_height_m) else "euclidean"
            if kind == "grid":
                costs = distance_matrix(tables.next_cell, nodes) * scenario.cell_size_m
            else:
                centres = scenario.cell_centers_m[nodes]
                costs = np.linalg.norm(centres[:, None, :] - centres[None, :, :], axis=-1)
            tour = solve_tsp(costs, start=0, closed=False, time_limit_s=self.tsp_time_limit_s, method=self.tsp_method)
            order = tour.order
        return [nodes[i] for i in order[1:] if walks.distances(nodes[i])[tables.start_cell] >= 0]

    def _prune(self, scenario: Any, walks: Walks, order: list[int]) -> list[int]:
        """Drop stops, one at a time, while the walk earns no less without them."""
        _, value = self._allocate(scenario, walks, order)
        dropped = True
        while dropped and len(order) > 1:
            dropped = False
            for j in range(len(order)):
                fewer = order[:j] + order[j + 1 :]
                _, v = self._allocate(scenario, walks, fewer)
                if v >= value - 1e-12:
                    order, value, dropped = fewer, v, True
                    break
        return order

    def _allocate(self, scenario: Any, walks: Walks, order: list[int]) -> tuple[list[int], float]:
        """Dwell steps per stop (the executor's count: arrival included) and the walk's
        return in the model; stops beyond the episode are dropped from ``order`` in place."""
        m = walks.model
        # the path: moves to each stop; a stop where the AUV already is has no arrival step
        cells: list[int] = []
        arrived: list[bool] = []
        cost = 0.0
        here = m.start_cell
        kept = 0
        for target in order:
            path = []
            while here != target:
                a = walks.step_toward(here, target)
                cost += m.step_cost[here, a]
                here = int(m.next_cell[here, a])
                path.append(here)
            if len(cells) + len(path) > m.steps:
                break
            cells.extend(path)
            arrived.append(bool(path))
            kept += 1
        del order[kept:]
        if not order:
            return [], -m.steps * float(m.stay_cost[m.start_cell])
        extra_steps = m.steps - len(cells)
        if self.dwell == "convex":
            extra = self._convex_extra(scenario, order, arrived, extra_steps)
        else:
            extra = _greedy_extra(m, cells, order, extra_steps)
        counts = np.bincount(np.asarray(cells + [c for c, e in zip(order, extra) for _ in range(e)], dtype=np.int64),
                             minlength=m.n_cells)
        cost += float(fpmath.dot(np.asarray(extra, dtype=float), m.stay_cost[order]))
        dwell = [e + 1 for e in extra]  # the executor counts the arrival (or the first stay)
        return dwell, m.service_value(counts) - cost

    def _convex_extra(self, scenario: Any, order: list[int], arrived: list[bool], extra_steps: int) -> list[int]:
        """KMeansTspPlanner's dwell: the convex program's split of the service time, in whole steps."""
        from planners.clustering import hover_link
        from planners.power_split import dwell_steps, stop_inputs

        service_steps = extra_steps + sum(arrived)
        snr, p_av = hover_link(scenario, np.asarray(order), None)
        inputs = stop_inputs(scenario, snr, p_av, mission_time_s=max(service_steps, 1) * scenario.step_duration_s)
        steps, _ = dwell_steps(inputs, scenario.step_duration_s, service_steps, max(service_steps, len(order)),
                               split_ratio=None)
        extra = [int(s) - int(a) for s, a in zip(steps, arrived)]
        # keep the total: the program's steps count arrivals, which are already in the path
        surplus = sum(extra) - extra_steps
        for k in np.argsort(-np.asarray(extra), kind="stable"):
            take = min(surplus, extra[k])
            extra[k] -= take
            surplus -= take
        return extra


def _greedy_extra(model: StepModel, path: list[int], order: list[int], extra_steps: int) -> list[int]:
    """Stays per stop: each of ``extra_steps`` goes where it adds the most reward."""
    bits, joules = model.delivered(np.bincount(np.asarray(path, dtype=np.int64), minlength=model.n_cells))
    spans = [(model.cov_ptr[c], model.cov_ptr[c + 1]) for c in order]
    extra = [0] * len(order)
    for _ in range(extra_steps):
        gains = []
        for k, (lo, hi) in enumerate(spans):
            nodes = model.cov_node[lo:hi]
            data_cap, room = model.data_bits[nodes], model.room_j[nodes]
            more_bits = np.minimum(data_cap, bits[nodes] + model.bits[lo:hi]) - np.minimum(data_cap, bits[nodes])
            more_joules = np.minimum(room, joules[nodes] + model.joules[lo:hi]) - np.minimum(room, joules[nodes])
            gain = model.data_weight * float(more_bits.sum()) + model.energy_weight * float(more_joules.sum())
            gains.append(gain - model.stay_cost[order[k]])
        k = int(np.argmax(gains))
        lo, hi = spans[k]
        np.add.at(bits, model.cov_node[lo:hi], model.bits[lo:hi])
        np.add.at(joules, model.cov_node[lo:hi], model.joules[lo:hi])
        extra[k] += 1
    return extra
