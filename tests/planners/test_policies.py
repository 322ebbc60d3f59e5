import numpy as np
import pytest

import swiptopt
from planners.bounds import exact_optimum, upper_bound
from planners.clustering import coverage_tables, kmeans_hover_points
from planners.grid import bfs_distances, path_actions
from planners.policies import GreedyPlanner, KMeansTspPlanner, LawnmowerPlanner
from planners.power_split import whole_steps
from rl import RandomAgent
from swiptopt import Box, Scenario, evaluate
from swiptopt import kernel as K
from swiptopt.env import AuvSwiptEnv


def policies():
    return [KMeansTspPlanner(tsp_time_limit_s=0.5), LawnmowerPlanner(), GreedyPlanner(), RandomAgent(seed=0)]


@pytest.mark.parametrize("layout", [1, 2])
def test_every_policy_stays_below_the_upper_bound(layout):
    scenario = Scenario.preset("paper", n_nodes=25, layout_seed=layout)
    env = AuvSwiptEnv(scenario)
    bound = upper_bound(scenario)
    returns = {}
    for policy in policies():
        result = evaluate(policy, env, episodes=3, seed=10)
        for r in result.records:
            assert r["return"] <= bound.return_ + 1e-9
            assert r["data_bits"] <= bound.data_bits + 1e-6
            assert r["energy_delivered_j"] <= bound.energy_delivered_j + 1e-12
        returns[type(policy).__name__] = result.summary["return"].mean
    # the planners are real baselines: each beats the random trajectory
    for name in ("KMeansTspPlanner", "LawnmowerPlanner", "GreedyPlanner"):
        assert returns[name] > returns["RandomAgent"]


@pytest.mark.parametrize("layout", [0, 1])
def test_tiny_exact_optimum_dominates_and_replays(layout):
    scenario = Scenario.preset("tiny", layout_seed=layout)
    best = exact_optimum(scenario)
    assert best.return_ <= upper_bound(scenario).return_ + 1e-9
    env = AuvSwiptEnv(scenario)
    env.reset(seed=0)
    total = 0.0
    for a in best.actions:
        _, r, term, trunc, _ = env.step(a)
        total += r
    assert term or trunc
    assert total == pytest.approx(best.return_, abs=1e-9)  # the DP's plan earns its value
    for policy in policies():
        result = evaluate(policy, env, episodes=2, seed=0)
        assert result.summary["return"].max <= best.return_ + 1e-9
    # k-means + TSP collects every coverable node's data on tiny
    covered, _ = coverage_tables(scenario)
    coverable_bits = scenario.layout.data_bits[covered.any(axis=0)].sum()
    kmeans = evaluate(KMeansTspPlanner(), env, episodes=1, seed=0)
    assert kmeans.records[0]["data_bits"] == pytest.approx(coverable_bits)


def test_exact_optimum_needs_a_deterministic_scenario():
    with pytest.raises(swiptopt.ConfigError, match="deterministic"):
        exact_optimum(Scenario.preset("paper"))


def test_kmeans_hover_points_fit_their_groups():
    scenario = Scenario.preset("paper", n_nodes=25, layout_seed=3)
    hover = kmeans_hover_points(scenario, rng=0)
    covered, _ = coverage_tables(scenario)
    for g, cell in enumerate(hover.cells):
        group = np.flatnonzero(hover.labels == g)
        assert covered[cell, group].all()
    assert np.array_equal(hover.labels < 0, ~covered.any(axis=0))
    again = kmeans_hover_points(scenario, rng=0)
    assert np.array_equal(again.cells, hover.cells)
    assert kmeans_hover_points(scenario, 3, rng=0).k == 3
    with pytest.raises(swiptopt.ConfigError, match="k = 0"):
        kmeans_hover_points(scenario, 0)


def test_grid_paths_follow_the_kernel_and_avoid_obstacles():
    scenario = Scenario.preset("harbour")
    t = K.build_tables(scenario)
    free = np.flatnonzero(~scenario.blocked_cells)
    rng = np.random.default_rng(0)
    for _ in range(5):
        a, b = rng.choice(free, 2, replace=False)
        actions = path_actions(t.next_cell, int(a), int(b))
        dist, _ = bfs_distances(t.next_cell, int(a))
        assert len(actions) == dist[b]
        c = int(a)
        for act in actions:
            c = int(t.next_cell[c, act])
            assert not scenario.blocked_cells[c]
        assert c == b


def test_planners_run_in_the_harbour_and_are_deterministic():
    env = AuvSwiptEnv(preset="harbour", n_nodes=8)
    for make in (lambda: KMeansTspPlanner(tsp_time_limit_s=0.3), LawnmowerPlanner, GreedyPlanner):
        a = evaluate(make(), env, episodes=2, seed=4)
        b = evaluate(make(), env, episodes=2, seed=4)
        assert a.records == b.records


def test_kmeans_tsp_with_ompl_tour_costs():
    env = AuvSwiptEnv(preset="harbour", n_nodes=6)
    planner = KMeansTspPlanner(tour_costs="ompl", ompl_time_limit_s=0.05, tsp_time_limit_s=0.3)
    result = evaluate(planner, env, episodes=1, seed=0)
    assert planner.plan_.details["tour_costs"] == "ompl"
    assert result.records[0]["data_bits"] > 0
    with pytest.raises(swiptopt.ConfigError, match="tour_costs"):
        KMeansTspPlanner(tour_costs="manhattan")


def testwhole_steps():
    steps = whole_steps(np.array([0.2, 3.7, 1.1]), 9)
    assert steps.sum() == 9 and steps.min() >= 1
    assert list(whole_steps(np.array([1.0, 1.0]), 1)) == [1, 1]


def test_predict_without_begin_episode_is_a_clear_error():
    with pytest.raises(RuntimeError, match="begin_episode"):
        GreedyPlanner().predict(0)


# ------------------------------------------------------------------ cells the AUV cannot reach

PLANNERS = [lambda: KMeansTspPlanner(tsp_time_limit_s=0.3), LawnmowerPlanner, GreedyPlanner]
WALL = Box((60.0, 0.0, 0.0), (70.0, 100.0, 50.0))  # across the whole volume at x = 60..70 m
# the start cell (5, 5, 0) with its four horizontal neighbours and the one below blocked
BOXED_IN = tuple(
    Box(tuple(c - 4.0 for c in centre), tuple(c + 4.0 for c in centre))
    for centre in ((45.0, 55.0, 5.0), (65.0, 55.0, 5.0), (55.0, 45.0, 5.0), (55.0, 65.0, 5.0), (55.0, 55.0, 15.0))
)


def flood_fill(scenario):
    """(n_cells,) bool: free cells connected to the start cell by face neighbours (numpy
    dilation, independent of the planners' breadth-first search)."""
    free = ~scenario.blocked_cells.reshape(scenario.grid_shape)
    seen = np.zeros_like(free)
    seen[scenario.resolved_start_cell] = True
    while True:
        grown = seen.copy()
        for axis in range(3):
            ahead, behind = [slice(None)] * 3, [slice(None)] * 3
            ahead[axis], behind[axis] = slice(1, None), slice(None, -1)
            grown[tuple(ahead)] |= seen[tuple(behind)]
            grown[tuple(behind)] |= seen[tuple(ahead)]
        grown &= free
        if np.array_equal(grown, seen):
            return seen.ravel()
        seen = grown


def run_episode(policy, env):
    obs, info = env.reset(seed=0)
    policy.begin_episode(env, obs, info)
    cells = [env.state.cell]
    while True:
        obs, _, terminated, truncated, _ = env.step(policy.predict(obs, deterministic=True))
        cells.append(env.state.cell)
        if terminated or truncated:
            return env.state, cells


@pytest.mark.parametrize("make", PLANNERS, ids=["kmeans_tsp", "lawnmower", "greedy"])
@pytest.mark.parametrize("obstacles", [(WALL,), BOXED_IN], ids=["wall", "boxed_in"])
def test_planners_skip_what_they_cannot_reach_and_serve_the_rest(make, obstacles):
    scenario = Scenario.preset("paper", n_nodes=20, channel="none", obstacles=obstacles)
    env = AuvSwiptEnv(scenario)
    reach = flood_fill(scenario)
    covered, _ = coverage_tables(scenario)
    lost = np.flatnonzero(covered.any(axis=0) & ~covered[reach].any(axis=0))
    assert lost.size > 0  # the case is real: some coverable nodes are out of reach

    policy = make()
    state, cells = run_episode(policy, env)
    plan = policy.plan_
    assert plan.details["unreachable_nodes"] == list(lost)
    assert "unreachable from the start cell" in plan.status
    assert all(reach[c] for c in cells)
    np.testing.assert_array_equal(state.data_left[lost], env.tables.data0[lost])
    served = env.tables.data0 - state.data_left
    if obstacles == BOXED_IN:
        assert set(cells) == {scenario.start_cell_index}  # nowhere to go: it hovers
        assert np.all(served == 0)  # and the start cell covers nobody here
    else:
        assert served.sum() > 0  # it still serves what it can reach
    if isinstance(policy, LawnmowerPlanner):
        stops = plan.details["unreachable_stops"]
        assert stops and not reach[stops].any()
        assert all(reach[s.cell] for s in plan.stops)
    # the same through evaluate, twice: no exception, and the same numbers
    assert evaluate(make(), env, episodes=1, seed=3).records == evaluate(make(), env, episodes=1, seed=3).records
