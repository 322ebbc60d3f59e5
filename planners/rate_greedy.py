"""The rate-greedy walk: always head for the cell that earns the most reward per step.

At every step the AUV weighs each cell c and each number k of service steps there: going
to c takes d(c) moves (the last of which already serves), then k - 1 hovers; the reward is
what k steps at c would deliver to its covered nodes given what they still need (data
left, storage free), minus the movement penalty of the moves and hovers. It heads for the
(c, k) with the best reward per step, d(c) + k - 1, and decides again at the next step.
The per-step amounts come from :func:`planners.service.step_model` (the kernel's own
numbers; expectations under a stochastic channel), so the walk reacts to what the
simulator actually delivered. Fast: one vectorised evaluation of every cell per step.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from planners.policies import Plan, PlanExecutor
from planners.service import StepModel, step_model
from planners.walk_search import Walks


class _RateChooser:
    """The rate-greedy decision rule over one :class:`StepModel`."""

    def __init__(self, model: StepModel):
        self.model = model
        self.walks = Walks(model)
        moves = model.step_cost[model.next_cell != np.arange(model.n_cells)[:, None]]
        # the penalty of one move; with a current the moves differ and this is their mean
        self._move_cost = float(moves.mean()) if moves.size else 0.0
        self._covering = np.flatnonzero(np.diff(model.cov_ptr) > 0)

    def action(self, cell: int, target: int) -> int:
        """The move from ``cell`` along a shortest path to ``target`` (the cheapest stay
        when they are the same cell)."""
        if target == cell:
            return int(self.model.stay_action[cell])
        return self.walks.step_toward(cell, target)

    def target(self, cell: int, steps_left: int, data_left: np.ndarray, room_left: np.ndarray) -> int:
        """The cell to head for (``cell`` itself: stay), given what the nodes still need."""
        m = self.model
        if steps_left <= 0 or self._covering.size == 0:
            return cell
        dist = self.walks.distances(cell)[self._covering]
        reachable = (dist >= 0) & (dist <= steps_left)
        if not reachable.any():
            return cell
        ks = np.arange(1, steps_left + 1, dtype=float)  # service steps there, arrival included
        # service of k steps at each covering cell: (k, pairs) capped by what is left
        nodes = m.cov_node
        service = (
            m.data_weight * np.minimum(data_left[nodes][None, :], ks[:, None] * m.bits[None, :])
            + m.energy_weight * np.minimum(room_left[nodes][None, :], ks[:, None] * m.joules[None, :])
        )
        value = np.add.reduceat(service, m.cov_ptr[self._covering], axis=1)[:, reachable]  # (k, candidates)
        cells, dist = self._covering[reachable], dist[reachable]
        here = dist == 0
        steps = np.where(here[None, :], ks[:, None], dist[None, :] + ks[:, None] - 1.0)
        cost = np.where(here[None, :], ks[:, None], ks[:, None] - 1.0) * m.stay_cost[cells][None, :]
        cost = cost + dist[None, :] * self._move_cost
        rate = np.where(steps <= steps_left, (value - cost) / steps, -np.inf)
        k, j = np.unravel_index(int(np.argmax(rate)), rate.shape)
        # staying put earns at least minus the cheapest stay: go only for something better
        if rate[k, j] <= -m.stay_cost[cell] and not here[j]:
            return cell
        return int(cells[j])


class RateGreedyPlanner(PlanExecutor):
    """Head for the cell earning the most reward per step of travel and hover (module doc).

    A closed-loop policy: each ``predict`` reads what the nodes still need from the
    environment's state and decides again.
    """

    parameters: dict = {}  # nothing to set: the rate decides
    linger_steps = 0

    def make_plan(self, env: Any) -> Plan:
        self._chooser = _RateChooser(step_model(env.tables))
        return Plan([], status="online")

    def predict(self, obs: Any, deterministic: bool = True) -> int:
        if self._env is None or self._env.state is None:
            raise RuntimeError("call begin_episode(env, obs, info) after each reset (swiptopt.evaluate does)")
        t, s = self._env.tables, self._env.state
        m = self._chooser.model
        cell = s.cell
        target = self._chooser.target(cell, m.steps - s.t, s.data_left, np.maximum(t.capacity - s.energy, 0.0))
        return self._chooser.action(cell, target)


def rate_greedy_actions(model: StepModel) -> list[int]:
    """The rate-greedy walk in the model itself (open loop): its actions, one per step.

    With a deterministic channel this is exactly the walk :class:`RateGreedyPlanner` takes
    in the simulator; with a stochastic one, the walk it would take if every step delivered
    its expected amounts.
    """
    chooser = _RateChooser(model)
    data_left = model.data_bits.astype(float).copy()
    room_left = model.room_j.astype(float).copy()
    cell = model.start_cell
    actions: list[int] = []
    for t in range(model.steps):
        a = chooser.action(cell, chooser.target(cell, model.steps - t, data_left, room_left))
        actions.append(a)
        cell = int(model.next_cell[cell, a])
        gained = model.serve(cell, data_left, room_left)
        if gained > 0.0 and model.all_served(data_left, room_left):
            break
    return actions

