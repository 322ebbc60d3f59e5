"""Hover points by k-means of the node positions (SPEC 6, ``clustering``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swiptopt import kernel as K
from swiptopt.coverage import slant_distances_m
from swiptopt.errors import ConfigError
from swiptopt.link import link_budget
from swiptopt.scenario import Scenario


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


def coverage_tables(scenario: Scenario, tables: K.Tables | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(n_cells, N) coverage from every free cell and the mean available power there, W.

    ``tables``: the scenario's kernel tables when the caller has them (else built here).
    """
    tables = K.build_tables(scenario) if tables is None else tables
    covered = np.zeros((scenario.n_cells, scenario.n_nodes), dtype=bool)
    power = np.zeros((scenario.n_cells, scenario.n_nodes))
    for c in range(scenario.n_cells):
        nodes = tables.covered(c)
        covered[c, nodes] = True
        power[c, nodes] = tables.cov_pav[tables.cov_ptr[c] : tables.cov_ptr[c + 1]]
    return covered, power


def best_hover_cell(covered: np.ndarray, power: np.ndarray, group: np.ndarray) -> int:
    """The cell covering most nodes of ``group``, ties broken by their total received power."""
    count = covered[:, group].sum(axis=1)
    total = (power[:, group] * covered[:, group]).sum(axis=1)
    score = count * (1.0 + total.max() + 1.0) + total  # lexicographic: count first
    return int(np.argmax(score))


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
    coverage footprint (its hover cell covers all of its nodes). Nodes that no cell can
    cover are left out (label -1).
    """
    from sklearn.cluster import KMeans

    covered, power = coverage_tables(scenario, tables)
    coverable = np.flatnonzero(covered.any(axis=0))
    labels = np.full(scenario.n_nodes, -1, dtype=np.int64)
    if coverable.size == 0:
        return HoverPoints(np.zeros(0, dtype=np.int64), labels, np.zeros((0, scenario.n_nodes), bool), 0)
    positions = scenario.layout.positions_m[coverable]
    seed = int(np.random.default_rng(rng).integers(2**31 - 1))
    limit = coverable.size if max_k is None else min(max_k, coverable.size)
    if k is not None and (isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= coverable.size):
        raise ConfigError(f"k = {k!r} must be an integer in [1, {coverable.size}] (the coverable nodes)", "k")
    # no K below this can fit: every group needs one footprint covering all of it
    widest = int(covered[:, coverable].sum(axis=1).max())
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
            fits &= bool(covered[cell, group].all())
        if fits or k is not None or kk == limit:
            labels[coverable] = model.labels_
            cells_arr = np.asarray(cells, dtype=np.int64)
            return HoverPoints(cells_arr, labels, covered[cells_arr], kk)
    raise AssertionError("unreachable")  # the loop returns at kk == limit


def hover_link(
    scenario: Scenario, cells: np.ndarray, tables: K.Tables | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Mean link SNR (linear) and available power (W) from hover ``cells`` to every node.

    Zero where the node is not covered from that cell.
    """
    covered, _ = coverage_tables(scenario, tables)
    d = slant_distances_m(scenario.cell_centers_m[cells], scenario.layout.positions_m)
    budget = link_budget(scenario, d)
    mask = covered[cells]
    return np.where(mask, 10.0 ** (budget.snr_db / 10.0), 0.0), np.where(mask, budget.available_power_w, 0.0)
