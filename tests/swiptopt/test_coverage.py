import math

import numpy as np
import pytest

from swiptopt import coverage as cov
from swiptopt.scenario import Scenario


def test_cone_mask_geometry():
    auv = np.array([[50.0, 50.0, 0.0]])
    t30 = math.tan(math.radians(30))
    nodes = np.array([
        [50.0, 50.0, 20.0],  # straight below: covered
        [50.0 + 20 * t30 * 0.99, 50.0, 20.0],  # just inside the cone
        [50.0 + 20 * t30 * 1.01, 50.0, 20.0],  # just outside
        [50.0, 50.0, 0.0],  # level with the AUV: not below
        [50.0, 50.0, 120.0],  # below but beyond the 100 m range
    ])
    np.testing.assert_array_equal(cov.cone_mask(auv, nodes, 30.0, 100.0)[0], [1, 1, 0, 0, 0])


def test_cone_volume_closed_form_and_monte_carlo():
    # depth-limited: a plain cone pi tan^2(theta) h^3 / 3
    assert cov.cone_volume_m3(50.0, 30.0, 100.0) == pytest.approx(math.pi * 50.0**3 / 9.0)
    # range-limited: cone up to R cos(theta) plus a spherical cap, against Monte Carlo
    rng = np.random.default_rng(5)
    pts = rng.uniform([-60, -60, 0], [60, 60, 80], (400_000, 3))
    inside = cov.cone_mask([0.0, 0.0, 0.0], pts, 40.0, 70.0)[0]
    mc = inside.mean() * 120 * 120 * 80
    se = math.sqrt(inside.mean() * (1 - inside.mean()) / len(pts)) * 120 * 120 * 80
    assert cov.cone_volume_m3(80.0, 40.0, 70.0) == pytest.approx(mc, abs=4 * se)


def test_paper_coverage_number():
    s = Scenario.preset("paper")
    frac = cov.coverage_fraction(s, (50.0, 50.0, 0.0))
    assert frac.method == "analytic"
    assert frac.p == pytest.approx(math.pi * 50.0**3 / 9.0 / 500_000.0)
    # from the surface centre, P(cover >= 1 of 10) is about 0.6
    assert cov.analytic_coverage_probability(s, (50.0, 50.0, 0.0), 10, 1) == pytest.approx(0.5987, abs=1e-4)


def test_binomial_tail():
    assert cov.binomial_at_least(3, 2, 0.5) == pytest.approx(0.5)
    assert cov.binomial_at_least(4, 0, 0.3) == 1.0
    assert cov.binomial_at_least(4, 5, 0.3) == 0.0
    assert cov.binomial_at_least(10, 1, 0.1) == pytest.approx(1 - 0.9**10)


@pytest.mark.parametrize(
    "position, n, k",
    [
        ((50.0, 50.0, 0.0), 10, 1),
        ((50.0, 50.0, 0.0), 25, 3),
        ((50.0, 50.0, 10.0), 50, 4),
        ((10.0, 15.0, 0.0), 20, 1),  # clipped by the side walls: Monte Carlo integration
        ((5.0, 95.0, 5.0), 40, 2),
    ],
)
def test_analytic_and_simulated_coverage_agree(position, n, k):
    s = Scenario.preset("paper")
    trials = 4000
    analytic = cov.analytic_coverage_probability(s, position, n, k, rng=1)
    simulated = cov.simulated_coverage_probability(s, position, n, k, trials=trials, rng=2)
    se = math.sqrt(max(analytic * (1 - analytic), 1e-4) / trials)
    assert simulated == pytest.approx(analytic, abs=4.5 * se + 0.005)


def test_coverage_with_obstacles_uses_free_water():
    s = Scenario.preset("harbour")
    frac = cov.coverage_fraction(s, (100.0, 100.0, 0.0), rng=0, n_samples=50_000)
    assert frac.method == "monte-carlo" and 0 < frac.p < 1
    sim = cov.simulated_coverage_probability(s, (100.0, 100.0, 0.0), 20, 1, trials=3000, rng=3)
    ana = cov.binomial_at_least(20, 1, frac.p)
    assert sim == pytest.approx(ana, abs=4.5 * math.sqrt(ana * (1 - ana) / 3000) + 0.01)


def test_snr_threshold_shrinks_coverage():
    s = Scenario.preset("paper", n_nodes=200, layout_seed=1)
    positions = s.cell_centers_m[s.cell_of_index(np.arange(s.n_cells))[:, 2] == 0]
    base = cov.covered_nodes(s, positions)
    strict = cov.covered_nodes(s.replace(snr_threshold_db=96.0), positions)
    assert strict.sum() < base.sum()
    assert not np.any(strict & ~base)  # a stricter threshold never adds a node


def dense_coverage(scenario):
    """Every cell against every node at once, as the tables were first built: the cone
    mask and the link budget on the full (cells, nodes) matrices, blocked cells removed."""
    from swiptopt.link import link_budget

    centres, nodes = scenario.cell_centers_m, scenario.layout.positions_m
    distance = cov.slant_distances_m(centres, nodes)
    covered = cov.cone_mask(centres, nodes, scenario.cone_half_angle_deg, scenario.cone_range_m)
    covered &= link_budget(scenario, distance).in_service & ~scenario.blocked_cells[:, None]
    rows, cols = np.nonzero(covered)
    return rows, cols, distance[rows, cols]


COVERAGE_CASES = [
    ("paper", {"n_nodes": 40}),
    ("paper", {"cell_size_m": 5.0, "n_nodes": 120}),
    ("harbour", {"n_nodes": 60}),  # obstacles and a seabed: blocked cells
    ("tiny", {}),
    ("paper", {"cone_half_angle_deg": 75.0, "n_nodes": 50}),  # wide cone, clipped by the walls
    ("paper", {"cone_range_m": 22.0, "n_nodes": 50}),  # range-limited
    ("paper", {"electrical_power_w": 0.5, "n_nodes": 50}),  # SNR-limited inside the cone
]


@pytest.mark.parametrize("preset, overrides", COVERAGE_CASES)
@pytest.mark.parametrize("pairs_per_block", [1, 997, cov.PAIRS_PER_BLOCK])
def test_cell_coverage_and_covered_pairs_are_the_dense_test_pair_for_pair(preset, overrides, pairs_per_block):
    scenario = Scenario.preset(preset, **overrides)
    rows, cols, distance = dense_coverage(scenario)
    assert rows.size > 0
    fast = cov.cell_coverage(scenario, pairs_per_block=pairs_per_block)
    np.testing.assert_array_equal(fast.rows, rows)
    np.testing.assert_array_equal(fast.nodes, cols)
    np.testing.assert_array_equal(fast.distance_m, distance)  # bit for bit
    blocks = cov.covered_pairs(scenario, scenario.cell_centers_m, pairs_per_block=pairs_per_block)
    free = ~scenario.blocked_cells[blocks.rows]
    np.testing.assert_array_equal(blocks.rows[free], rows)
    np.testing.assert_array_equal(blocks.nodes[free], cols)
    np.testing.assert_array_equal(blocks.distance_m[free], distance)
    dense = cov.covered_nodes(scenario, scenario.cell_centers_m)
    assert dense.sum() == blocks.rows.size and dense[blocks.rows, blocks.nodes].all()


def test_kernel_tables_hold_the_covered_pairs_and_their_link():
    from swiptopt import kernel as K
    from swiptopt.acoustics import db_to_linear
    from swiptopt.link import link_budget

    scenario = Scenario.preset("harbour", n_nodes=60)
    t = K.build_tables(scenario)
    rows, cols, distance = dense_coverage(scenario)
    np.testing.assert_array_equal(np.repeat(np.arange(t.n_cells), np.diff(t.cov_ptr)), rows)
    np.testing.assert_array_equal(t.cov_node, cols)
    budget = link_budget(scenario, distance)
    np.testing.assert_array_equal(t.cov_pav, budget.available_power_w)
    np.testing.assert_array_equal(t.cov_snr, db_to_linear(budget.snr_db))


def test_the_papers_coverage_statements_from_the_surface_centre_and_the_start_cell():
    """The statements of Section III-B (on Fig. 5) against the paper preset. The surface centre (50, 50, 0) is where the
    paper's figure puts the AUV; it never stands there: the start cell's centre is
    (55, 55, 5). The cone stays inside the volume from both, so the binomial is exact
    (closed-form volume); direct simulation of 4000 layouts agrees within 4 standard
    errors (at most 0.032)."""
    from swiptopt.coverage import paper_coverage_statements, simulated_coverage_probability

    scenario = Scenario.preset("paper")
    expected = {
        (50.0, 50.0, 0.0): {(10, 1): 0.5987, (31, 4): 0.2839, (51, 5): 0.4624, (11, 1): 0.6337},
        (55.0, 55.0, 5.0): {(10, 1): 0.4818, (31, 4): 0.1317, (51, 5): 0.2227, (11, 1): 0.5148},
    }
    assert tuple(scenario.cell_centers_m[scenario.start_cell_index]) == (55.0, 55.0, 5.0)
    for position, values in expected.items():
        statements = paper_coverage_statements(scenario, position)
        for s in statements:
            assert s.analytic == pytest.approx(values[(s.n_nodes, s.at_least)], abs=1e-4)
            simulated = simulated_coverage_probability(scenario, position, s.n_nodes, s.at_least, trials=4000, rng=1)
            assert simulated == pytest.approx(s.analytic, abs=4 * math.sqrt(0.25 / 4000))
        holds = {(s.n_nodes, s.at_least): s.holds for s in statements}
        # "more than 10 nodes: at least one covered with > 50 %" holds from both positions;
        # "more than 4 of > 50 nodes with > 50 %" holds from neither
        assert holds[(11, 1)] and not holds[(51, 5)] and not holds[(31, 4)]
