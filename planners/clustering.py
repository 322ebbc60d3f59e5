"""Hover points by k-means of the node positions.

Coverage comes from the simulator kernel's own tables (:func:`swiptopt.kernel.build_tables`),
which already hold it as a compressed sparse row structure (``cov_ptr``, ``cov_node``,
``cov_pav``): :func:`coverage_matrices` wraps those arrays as scipy sparse matrices without
copying them, so a planner works in memory proportional to the covered pairs, not to cells
x nodes. scikit-learn and scipy are imported inside the functions.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from swiptopt import kernel as K
from swiptopt.acoustics import db_to_linear
from swiptopt.coverage import slant_distances_m
from swiptopt.link import link_budget
from swiptopt.scenario import Scenario
from swiptopt.validation import Spec, check_value


@dataclass(frozen=True, eq=False)
class HoverPoints:
    """Hover cells, one per node group, and which nodes each covers."""

    cells: np.ndarray
    """(K,) flat cell indices."""
    labels: np.ndarray
    """(n_nodes,) group of each node (-1 for nodes no cell can cover)."""
    covered: np.ndarray
    """(K, n_nodes) bool: the nodes each hover cell covers."""
    k: int


def coverage_matrices(tables: K.Tables) -> tuple[Any, Any]:
    """The kernel's coverage as two (n_cells, N) ``scipy.sparse.csr_array``: which pairs are
    covered (bool) and their mean available power (W), sharing the tables' arrays."""
    from scipy import sparse

    shape = (tables.n_cells, tables.n_nodes)
    structure = (tables.cov_node, tables.cov_ptr)
    covered = sparse.csr_array((np.ones(tables.cov_node.size, dtype=bool), *structure), shape=shape)
    power = sparse.csr_array((tables.cov_pav, *structure), shape=shape)
    return covered, power


def coverage_tables(scenario: Scenario, tables: K.Tables | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(n_cells, N) coverage from every free cell and the mean available power there, W,
    as dense arrays (cells x nodes in memory: :func:`coverage_matrices` is the sparse form).

    ``tables``: the scenario's kernel tables when the caller has them (else built here).
    """
    covered, power = coverage_matrices(K.build_tables(scenario) if tables is None else tables)
    return covered.toarray(), power.toarray()


def best_hover_cell(covered: Any, power: Any, group: np.ndarray) -> int:
    """The cell covering most nodes of ``group``, ties broken by their total received power.

    ``covered`` and ``power``: (n_cells, N), dense arrays or sparse matrices, power zero
    where not covered.
    """
    member = np.zeros(covered.shape[1])
    member[np.asarray(group, dtype=np.int64)] = 1.0
    count = np.asarray(covered @ member, dtype=float)
    total = np.asarray(power @ member, dtype=float)
    score = count * (1.0 + total.max() + 1.0) + total  # lexicographic: count first
    return int(np.argmax(score))


#: What ``k`` and ``max_k`` of :func:`kmeans_hover_points` may hold: a number of groups, or
#: ``None`` (``k``: choose it; ``max_k``: no limit).
GROUP_COUNT = Spec(kind="int", lo=1, strict=True, optional=True, doc="a number of k-means groups")


def kmeans_hover_points(
    scenario: Scenario,
    k: int | None = None,
    *,
    rng: np.random.Generator | int | None = 0,
    max_k: int | None = None,
    tables: K.Tables | None = None,
) -> HoverPoints:
    """Group the coverable nodes with k-means (scikit-learn, seeded) and pick a hover cell each.

    ``k`` given: that many groups. ``k=None``: the smallest K for which every group fits one
    coverage footprint (its hover cell covers all of its nodes), trying at most ``max_k``
    groups (default: one per coverable node). Nodes that no cell can cover are left out
    (label -1); with none coverable the result has K = 0. Bad ``k`` or ``max_k`` raise
    :class:`~swiptopt.errors.ConfigError` naming it.
    """
    max_k = check_value("max_k", max_k, GROUP_COUNT)
    k = check_value("k", k, GROUP_COUNT)
    tables = K.build_tables(scenario) if tables is None else tables
    coverable = np.unique(tables.cov_node)
    labels = np.full(scenario.n_nodes, -1, dtype=np.int64)
    if coverable.size == 0:
        return HoverPoints(np.zeros(0, dtype=np.int64), labels, np.zeros((0, scenario.n_nodes), bool), 0)
    if k is not None:
        k = check_value("k", k, GROUP_COUNT, hi=coverable.size)  # at most one group per coverable node

    from sklearn.cluster import KMeans

    covered, power = coverage_matrices(tables)
    positions = scenario.layout.positions_m[coverable]
    seed = int(np.random.default_rng(rng).integers(2**31 - 1))
    limit = coverable.size if max_k is None else min(int(max_k), coverable.size)
    # no K below this can fit: every group needs one footprint covering all of it
    widest = int(np.diff(tables.cov_ptr).max())
    lowest = min(limit, -(-coverable.size // widest))
    candidates = [int(k)] if k is not None else range(lowest, limit + 1)
    for kk in candidates:
        model = KMeans(n_clusters=kk, n_init=4, random_state=seed).fit(positions)
        cells = []
        fits = True
        for g in range(kk):
            group = coverable[model.labels_ == g]
            cell = best_hover_cell(covered, power, group)
            cells.append(cell)
            fits &= bool(np.isin(group, tables.covered(cell)).all())
        if fits or k is not None or kk == limit:
            labels[coverable] = model.labels_
            cells_arr = np.asarray(cells, dtype=np.int64)
            return HoverPoints(cells_arr, labels, covered[cells_arr].toarray(), kk)
    raise AssertionError("unreachable")  # the loop returns at kk == limit


def hover_link(
    scenario: Scenario, cells: np.ndarray, tables: K.Tables | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Mean link SNR (linear) and available power (W) from hover ``cells`` to every node.

    Zero where the node is not covered from that cell.
    """
    covered, _ = coverage_matrices(K.build_tables(scenario) if tables is None else tables)
    cells = np.asarray(cells, dtype=np.int64)
    d = slant_distances_m(scenario.cell_centers_m[cells], scenario.layout.positions_m)
    budget = link_budget(scenario, d)
    mask = covered[cells].toarray()
    return np.where(mask, db_to_linear(budget.snr_db), 0.0), np.where(mask, budget.available_power_w, 0.0)
