"""Local search over walks: the MILP's primal heuristic (and a polish for any plan).

A walk is written as stops, each a cell and a number of service steps there (the arrival
step counts as the first); between stops the AUV takes a shortest grid path, and after the
last stop it stays where it is. :func:`polish_walk` climbs from a walk through a fixed,
ordered neighbourhood (a dwell one step longer or shorter, a stop dropped, a stop moved to
a neighbouring cell, two consecutive stops swapped, a stop inserted where it costs the
shortest detour at the cell that serves some node fastest), taking the first improving
move, then kicks the best walk found (two stops dropped or moved, from a seeded generator)
and climbs again: an iterated local search. It is limited by a number of walk evaluations,
so its result does not depend on the machine. A walk's value is
:class:`planners.service.StepModel`'s, the simulator's return for a deterministic channel.
"""

from __future__ import annotations

import numpy as np

from planners.grid import bfs_distances
from planners.policies import _REVERSE
from planners.service import StepModel


class Walks:
    """Builds walks from stops and values them with one :class:`StepModel`."""

    def __init__(self, model: StepModel):
        self.model = model
        self._trees: dict[int, np.ndarray] = {}
        self._dist: dict[int, np.ndarray] = {}
        self.evaluations = 0

    def distances(self, cell: int) -> np.ndarray:
        """(n_cells,) moves between ``cell`` and every cell (-1: unreachable), cached."""
        dist = self._dist.get(cell)
        if dist is None:
            dist, tree = bfs_distances(self.model.next_cell, cell)
            self._dist[cell], self._trees[cell] = dist, tree
        return dist

    def step_toward(self, cell: int, target: int) -> int:
        """The move from ``cell`` along a shortest path to ``target`` (they differ)."""
        self.distances(target)
        return int(_REVERSE[self._trees[target][0, cell]])

    def actions(self, stops: list[tuple[int, int]]) -> list[int]:
        """One action per step: shortest paths between stops, stays at them, then stays."""
        m = self.model
        out: list[int] = []
        cell = m.start_cell
        for target, dwell in stops:
            if self.distances(target)[cell] < 0:
                continue  # unreachable: skip the stop
            moved = False
            while cell != target and len(out) < m.steps:
                a = self.step_toward(cell, target)
                out.append(a)
                cell = int(m.next_cell[cell, a])
                moved = True
            # arriving serves once; a stop where the AUV already is serves only by staying
            stays = dwell - 1 if moved else dwell
            out.extend([int(m.stay_action[cell])] * max(0, min(stays, m.steps - len(out))))
            if len(out) >= m.steps:
                break
        out.extend([int(m.stay_action[cell])] * (m.steps - len(out)))
        return out[: m.steps]

    def value(self, actions: list[int]) -> float:
        """The walk's return in the model, ignoring the end when every node is served
        (a lower bound on :meth:`StepModel.walk_return`, equal unless that happens)."""
        m = self.model
        self.evaluations += 1
        a = np.asarray(actions, dtype=np.int64)
        cells = np.empty(len(a) + 1, dtype=np.int64)
        cells[0] = m.start_cell
        for t in range(len(a)):
            cells[t + 1] = m.next_cell[cells[t], a[t]]
        cost = float(m.step_cost[cells[:-1], a].sum())
        return m.service_value(np.bincount(cells[1:], minlength=m.n_cells)) - cost


def stops_of(model: StepModel, actions: list[int]) -> list[tuple[int, int]]:
    """The stops of a walk: every covering cell (or the start) where a step ends, with the
    consecutive steps ending there."""
    covering = np.diff(model.cov_ptr) > 0
    stops: list[tuple[int, int]] = []
    cell = model.start_cell
    for a in actions[: model.steps]:
        cell = int(model.next_cell[cell, a])
        if not covering[cell] and cell != model.start_cell:
            continue
        if stops and stops[-1][0] == cell and (model.next_cell[cell, a] == cell):
            stops[-1] = (cell, stops[-1][1] + 1)
        else:
            stops.append((cell, 1))
    return stops


def _candidate_cells(model: StepModel) -> list[int]:
    """Cells worth inserting: for every node the cell that charges it fastest and the one
    delivering its data fastest, and the cells with the most service per step."""
    pair_cell = model.cell_of_pair()
    cells: set[int] = set()
    for amount in (model.joules / np.maximum(model.room_j[model.cov_node], 1e-300), model.bits):
        best = np.full(model.n_nodes, -1.0)
        where = np.full(model.n_nodes, -1, dtype=np.int64)
        for p in range(len(pair_cell)):
            i = model.cov_node[p]
            if amount[p] > best[i]:
                best[i], where[i] = amount[p], pair_cell[p]
        cells.update(int(c) for c in where if c >= 0)
    per_step = np.bincount(
        pair_cell, weights=model.data_weight * model.bits + model.energy_weight * model.joules, minlength=model.n_cells
    )
    cells.update(int(c) for c in np.argsort(-per_step, kind="stable")[: max(5, model.n_nodes // 2)] if per_step[c] > 0)
    return sorted(cells)


def polish_walk(
    model: StepModel, actions: list[int], *, max_evaluations: int = 5000, seed: int = 0
) -> list[int]:
    """A walk at least as good as ``actions``, within ``max_evaluations`` walk evaluations.

    Hill climbing (module docstring) to a local optimum, then rounds of a random kick (two
    stops dropped or moved, from a generator seeded with ``seed``) followed by climbing
    again, keeping the best walk: an iterated local search.
    """
    walks = Walks(model)
    candidates = _candidate_cells(model)
    rng = np.random.default_rng(seed)
    best = _climb(walks, stops_of(model, actions), candidates, max_evaluations)
    best_value = walks.value(walks.actions(best))
    while walks.evaluations < max_evaluations and best and candidates:
        trial = list(best)
        for _ in range(2):
            if not trial:
                break
            k = int(rng.integers(len(trial)))
            if rng.random() < 0.5:
                del trial[k]
            else:
                cell, dwell = trial[k]
                trial[k] = (candidates[int(rng.integers(len(candidates)))], dwell)
        trial = _climb(walks, trial, candidates, max_evaluations)
        value = walks.value(walks.actions(trial))
        if value > best_value + 1e-12:
            best, best_value = trial, value
    polished = walks.actions(best)
    if model.walk_return(polished)[0] >= model.walk_return(actions)[0]:
        return polished
    return list(actions)


def _climb(
    walks: Walks, stops: list[tuple[int, int]], candidates: list[int], max_evaluations: int
) -> list[tuple[int, int]]:
    """First-improvement hill climbing from ``stops`` until no neighbour is better."""
    current = walks.value(walks.actions(stops))
    improved = True
    while improved and walks.evaluations < max_evaluations:
        improved = False
        for new in _neighbours(walks, stops, candidates):
            if walks.evaluations >= max_evaluations:
                break
            value = walks.value(walks.actions(new))
            if value > current + 1e-12:
                stops, current, improved = new, value, True
                break  # restart the neighbourhood from the improved walk
    return stops


def _neighbours(walks: Walks, stops: list[tuple[int, int]], candidates: list[int]):  # type: ignore[no-untyped-def]
    """Neighbouring stop lists, in a fixed order."""
    m = walks.model
    n = len(stops)
    for k in range(n):  # longer and shorter dwells
        cell, dwell = stops[k]
        yield stops[:k] + [(cell, dwell + 1)] + stops[k + 1 :]
        if dwell > 1:
            yield stops[:k] + [(cell, dwell - 1)] + stops[k + 1 :]
    for k in range(n):  # drop a stop
        yield stops[:k] + stops[k + 1 :]
    for k in range(n):  # move a stop to a neighbouring cell
        cell, dwell = stops[k]
        for nxt in dict.fromkeys(int(c) for c in m.next_cell[cell, :6]):
            if nxt != cell:
                yield stops[:k] + [(nxt, dwell)] + stops[k + 1 :]
    for k in range(n - 1):  # swap two consecutive stops
        yield stops[:k] + [stops[k + 1], stops[k]] + stops[k + 2 :]
    for cell in candidates:  # insert a stop where it costs the shortest detour
        dist = walks.distances(cell)
        previous = [m.start_cell] + [c for c, _ in stops]
        detour = []
        for k in range(n + 1):
            before = dist[previous[k]]
            after = dist[stops[k][0]] if k < n else 0
            base = walks.distances(previous[k])[stops[k][0]] if k < n else 0
            detour.append(np.inf if before < 0 or after < 0 else before + after - base)
        k = int(np.argmin(detour))
        for dwell in (1, 3):
            yield stops[:k] + [(cell, dwell)] + stops[k:]
