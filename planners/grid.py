"""Shortest 6-connected paths on a scenario's free cells, as env actions.

The executed motion of every planner goes through here: a breadth-first search over the
kernel's own transition table (``next_cell``), so a path never enters a blocked cell and
its actions are exactly the moves the simulator will make.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from swiptopt import kernel as K


def bfs_distances(next_cell: np.ndarray, source: int) -> tuple[np.ndarray, np.ndarray]:
    """Moves from ``source`` to every cell (-1 where unreachable) and each cell's parent action.

    ``next_cell``: the kernel table (n_cells, 7). Returns (distance, action) where
    ``action[c]`` is the move taken into c on a shortest path (-1 for the source).
    """
    n = next_cell.shape[0]
    dist = np.full(n, -1, dtype=np.int64)
    via = np.full(n, -1, dtype=np.int64)
    parent = np.full(n, -1, dtype=np.int64)
    dist[source] = 0
    queue = deque([source])
    while queue:
        c = queue.popleft()
        for a in range(K.HOVER):
            d = next_cell[c, a]
            if dist[d] < 0:
                dist[d] = dist[c] + 1
                via[d] = a
                parent[d] = c
                queue.append(d)
    return dist, np.stack([via, parent])


def path_actions(next_cell: np.ndarray, source: int, target: int) -> list[int]:
    """The moves of one shortest path from ``source`` to ``target`` (empty if equal).

    Raises ``ValueError`` if the target cannot be reached.
    """
    if source == target:
        return []
    dist, tree = bfs_distances(next_cell, source)
    if dist[target] < 0:
        raise ValueError(f"cell {target} cannot be reached from cell {source}")
    actions = []
    c = target
    while c != source:
        actions.append(int(tree[0, c]))
        c = int(tree[1, c])
    return actions[::-1]


def distance_matrix(next_cell: np.ndarray, cells: list[int]) -> np.ndarray:
    """Moves between every pair of ``cells`` (inf where unreachable), (len, len)."""
    out = np.zeros((len(cells), len(cells)))
    for i, c in enumerate(cells):
        dist, _ = bfs_distances(next_cell, c)
        row = dist[np.asarray(cells)].astype(float)
        row[row < 0] = np.inf
        out[i] = row
    return out
