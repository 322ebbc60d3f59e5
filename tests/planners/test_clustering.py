"""planners.clustering: hover points from k-means on the kernel's own (sparse) coverage."""

from __future__ import annotations

import numpy as np
import pytest

from planners.clustering import (
    best_hover_cell,
    coverage_matrices,
    coverage_tables,
    hover_link,
    kmeans_hover_points,
)
from swiptopt import kernel as K
from swiptopt.errors import ConfigError
from swiptopt.link import link_budget
from swiptopt.scenario import Scenario


def test_sparse_coverage_is_the_kernel_tables_and_the_dense_one():
    scenario = Scenario.preset("harbour", n_nodes=40)
    t = K.build_tables(scenario)
    covered, power = coverage_matrices(t)
    dense_covered, dense_power = coverage_tables(scenario, t)
    assert covered.shape == power.shape == dense_covered.shape == (t.n_cells, t.n_nodes)
    assert covered.nnz == t.cov_node.size
    np.testing.assert_array_equal(covered.toarray(), dense_covered)
    np.testing.assert_array_equal(power.toarray(), dense_power)
    for cell in (0, t.start_cell, int(np.argmax(np.diff(t.cov_ptr)))):
        assert set(np.flatnonzero(dense_covered[cell])) == set(t.covered(cell).tolist())
    assert np.shares_memory(power.data, t.cov_pav)  # the tables' arrays, not a copy


def test_best_hover_cell_is_the_same_on_sparse_and_dense_coverage():
    scenario = Scenario.preset("paper", n_nodes=60, layout_seed=3)
    t = K.build_tables(scenario)
    sparse_pair, dense_pair = coverage_matrices(t), coverage_tables(scenario, t)
    rng = np.random.default_rng(0)
    coverable = np.unique(t.cov_node)
    for _ in range(20):
        group = rng.choice(coverable, size=int(rng.integers(1, 6)), replace=False)
        cell = best_hover_cell(*sparse_pair, group)
        assert cell == best_hover_cell(*dense_pair, group)
        count = np.isin(group, t.covered(cell)).sum()
        assert count == max(np.isin(group, t.covered(c)).sum() for c in range(t.n_cells))


def test_kmeans_hover_points_cover_their_groups_and_repeat():
    scenario = Scenario.preset("paper", n_nodes=40, layout_seed=1)
    t = K.build_tables(scenario)
    first = kmeans_hover_points(scenario, rng=5, tables=t)
    again = kmeans_hover_points(scenario, rng=5)
    np.testing.assert_array_equal(first.cells, again.cells)
    np.testing.assert_array_equal(first.labels, again.labels)
    for g, cell in enumerate(first.cells):
        members = np.flatnonzero(first.labels == g)
        assert np.isin(members, t.covered(cell)).all()  # every group fits its footprint
        np.testing.assert_array_equal(first.covered[g], np.isin(np.arange(t.n_nodes), t.covered(cell)))
    assert set(np.flatnonzero(first.labels >= 0)) == set(np.unique(t.cov_node).tolist())


def test_hover_link_is_the_link_budget_where_covered():
    scenario = Scenario.preset("paper", n_nodes=30)
    t = K.build_tables(scenario)
    cells = kmeans_hover_points(scenario, tables=t).cells
    snr, power = hover_link(scenario, cells, t)
    for row, cell in enumerate(cells):
        nodes = t.covered(cell)
        d = np.linalg.norm(scenario.layout.positions_m[nodes] - scenario.cell_centers_m[cell], axis=1)
        budget = link_budget(scenario, d)
        np.testing.assert_allclose(power[row, nodes], budget.available_power_w, rtol=1e-12)
        np.testing.assert_allclose(snr[row, nodes], 10 ** (budget.snr_db / 10), rtol=1e-12)
        assert np.count_nonzero(power[row]) == nodes.size


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"max_k": 0}, "max_k"), ({"max_k": -3}, "max_k"), ({"max_k": 2.5}, "max_k"), ({"max_k": True}, "max_k"),
     ({"k": 0}, "k"), ({"k": True}, "k"), ({"k": "3"}, "k"), ({"k": 10_000}, "k")],
)
def test_bad_k_or_max_k_is_a_config_error_not_a_library_exception(kwargs, field):
    scenario = Scenario.preset("paper", n_nodes=20)
    with pytest.raises(ConfigError) as err:
        kmeans_hover_points(scenario, **kwargs)
    assert err.value.field == field and field in str(err.value)


def test_no_coverage_gives_no_hover_points():
    scenario = Scenario.preset("paper", n_nodes=10, snr_threshold_db=200.0)  # no link is good enough
    assert K.build_tables(scenario).cov_node.size == 0
    points = kmeans_hover_points(scenario, max_k=3)
    assert points.k == 0 and points.cells.size == 0 and np.all(points.labels == -1)
