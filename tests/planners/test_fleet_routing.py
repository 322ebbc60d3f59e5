"""k-means + vehicle routing for a fleet (planners/fleet.py)."""


import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from planners.fleet import FleetRoutingPlanner, route_fleet
from planners.grid import bfs_distances
from planners.policies import KMeansTspPlanner, reachable, route_plan
from swiptopt import Box, ConfigError, Scenario
from swiptopt.env import AuvSwiptEnv
from swiptopt.env_fleet import AuvFleetEnv
from swiptopt.evaluation import evaluate_fleet

# across the whole volume at x = 60..70 m: the default starts of two AUVs, cells x = 2 and
# x = 7, lie on either side of it
WALL = Box((60.0, 0.0, 0.0), (70.0, 100.0, 50.0))


def planned(env, **settings):
    """A planner that has planned for ``env``'s first episode (seed 0)."""
    observations, infos = env.reset(seed=0)
    planner = FleetRoutingPlanner(**settings)
    planner.begin_episode(env, observations, infos)
    return planner


def reach_of(fleet, k):
    """(n_cells,) bool: cells AUV k can reach from its start."""
    dist, _ = bfs_distances(fleet.tables.next_cell, int(fleet.start_cells[k]))
    return dist >= 0


def coverable_nodes(fleet):
    """Nodes some cell covers that some AUV can reach."""
    reach = np.any([reach_of(fleet, k) for k in range(fleet.n_auvs)], axis=0)
    return {int(i) for c in np.flatnonzero(reach) for i in fleet.tables.covered(int(c))}


@pytest.fixture(scope="module")
def long_env():
    """Two AUVs on the paper preset (25 nodes), long enough to visit every hover point."""
    return AuvFleetEnv(n_auvs=2, episode_steps=200)


@pytest.mark.parametrize("obstacles", [(), (WALL,)], ids=["open", "wall"])
def test_routes_cover_every_coverable_node_and_share_no_stop(obstacles):
    env = AuvFleetEnv(n_auvs=2, episode_steps=200, obstacles=obstacles)
    plan = planned(env).plan_
    details, fleet = plan.details, env.fleet
    routes = details["routes"]
    assert len(plan.plans) == len(routes) == 2
    assert details["dropped_stops"] == [] and "dropped" not in plan.status
    stops = [c for route in routes for c in route]
    assert len(stops) == len(set(stops))  # no stop in two routes
    assert sorted(stops) == sorted(details["hover_cells"])
    covered = {int(i) for c in stops for i in fleet.tables.covered(c)}
    wanted = coverable_nodes(fleet)
    assert wanted and wanted <= covered
    for k, route in enumerate(routes):
        assert route and reach_of(fleet, k)[route].all()  # each AUV only gets stops it can reach
        assert [s.cell for s in plan.plans[k].stops] == route  # the dwells keep the route's order
    if obstacles:  # the wall splits the work: no AUV could take the other's share
        assert not reach_of(fleet, 0)[routes[1]].any() and not reach_of(fleet, 1)[routes[0]].any()


def test_makespan_balances_the_routes(long_env):
    by = {balance: planned(long_env, balance=balance).plan_.details for balance in ("makespan", "distance")}
    for details in by.values():
        assert details["dropped_stops"] == [] and details["routing_status"] == "feasible"
        service = dict(zip(details["hover_cells"], details["service_steps"]))
        for route, moves, steps in zip(details["routes"], details["route_moves"], details["route_times"]):
            # a route's time: its moves, then each stop's service steps after its arrival step
            assert steps == moves + sum(service[c] - 1 for c in route) <= long_env.scenario.episode_steps
    makespan, distance = by["makespan"], by["distance"]
    assert all(makespan["routes"])
    # the makespan search starts from the distance routes and keeps its best, which weighs a
    # step of the longest route above all moves: with the same stops served it is never longer
    assert max(makespan["route_times"]) <= max(distance["route_times"])


def test_the_same_seed_gives_the_same_routes_and_records():
    env = AuvFleetEnv(n_auvs=2, episode_steps=40)
    runs = []
    for _ in range(2):
        planner = FleetRoutingPlanner(seed=3)
        result = evaluate_fleet(planner, env, episodes=2, seed=5)
        runs.append((planner.plan_.details["routes"], [p.stops for p in planner.plan_.plans], result.records))
    assert runs[0] == runs[1]


def test_two_routing_auvs_collect_more_than_one():
    data = {}
    for n in (1, 2):
        env = AuvFleetEnv(n_auvs=n, episode_steps=40)
        result = evaluate_fleet(FleetRoutingPlanner(), env, episodes=2, seed=0)
        data[n] = [r["data_bits"] for r in result.records]
    # one AUV has to drop stops to fit 40 steps; two split the hover points and serve them all
    assert min(data[2]) > max(data[1])


def test_the_episode_follows_the_routes_and_serves_every_coverable_node(long_env):
    planner = FleetRoutingPlanner()
    record = evaluate_fleet(planner, long_env, episodes=1, seed=0).records[0]
    state, scenario = long_env.fleet_state, long_env.scenario
    assert record["nodes_served"] == scenario.n_nodes or state.t == scenario.episode_steps
    assert record["nodes_served"] == len(coverable_nodes(long_env.fleet))  # every reachable node served
    for k, route in enumerate(planner.plan_.details["routes"]):
        path = iter(long_env.paths[k])
        assert all(cell in path for cell in route)  # its stops were visited, in the route's order
        assert record["data_bits_each"][k] > 0


def test_a_fleet_of_one_visits_the_single_planners_hover_cells():
    scenario = Scenario.preset("paper", episode_steps=200)
    fleet_planner = planned(AuvFleetEnv(scenario))
    env = AuvSwiptEnv(scenario)
    single = KMeansTspPlanner()
    single.begin_episode(env, *env.reset(seed=0))
    # the same k-means hover points (the same reachable tables and seed), every one visited
    # in a long episode; the orders may differ: the single planner's tour minimises
    # euclidean lengths, the routing grid moves plus the balance
    (route,) = fleet_planner.plan_.details["routes"]
    assert sorted(route) == sorted(s.cell for s in single.plan_.stops) == sorted(
        fleet_planner.plan_.details["hover_cells"])
    assert fleet_planner.plan_.details["hover_k"] == single.plan_.details["hover_k"]
    # the per-route part is one function: fed the single planner's order, it gives its stops
    order = [s.cell for s in single.plan_.stops]
    assert route_plan(scenario, reachable(env.tables).tables, env.tables.start_cell, order).stops == single.plan_.stops


def test_it_replans_only_for_a_new_layout():
    env = AuvFleetEnv(n_auvs=2, episode_steps=40)
    planner = planned(env)
    first = planner.plan_
    env.reset(seed=1)
    planner.begin_episode(env)
    assert planner.plan_ is first  # the same layout: the same plan
    env.reset(seed=1, options={"layout_seed": 7})
    planner.begin_episode(env)
    assert planner.plan_ is not first and planner.plan_.details["routes"] != first.details["routes"]
    actions = planner.act({})
    assert set(actions) == set(env.agents) and all(0 <= a <= 6 for a in actions.values())


def test_routing_stops_on_its_budgets_when_nothing_else_fits():
    # one vehicle, one stop: no other solution exists, and guided local search would wait for
    # the clock; the failure budget stops it and the result is reported as reproducible
    # (status "feasible", not "time_limit": the deterministic budget, not the clock, ended it)
    found = route_fleet(np.array([[0.0, 3.0], [3.0, 0.0]]), np.array([2]), 10, time_limit_s=60.0)
    assert (found.routes, found.times, found.moves, found.status) == ([[0]], [4], [3], "feasible")
    # a stop that fits in no route is dropped; one only vehicle 1 can reach goes to vehicle 1
    travel = np.array([[0, np.inf, 8, np.inf], [np.inf, 0, 9, 2], [8, 9, 0, np.inf], [np.inf, 2, np.inf, 0]])
    found = route_fleet(travel, np.array([4, 1]), 10)
    assert found.routes == [[], [1]] and found.dropped == [0]  # stop 0 needs 8 + 3 steps from vehicle 0
    assert found.times == [0, 2] and found.status == "feasible"


def test_the_return_balance_trades_a_stops_value_against_its_moves():
    # one vehicle, horizon 10: stop 0 is 2 moves away, stop 1 8 moves, 9 between them, so
    # only one fits; the makespan and distance objectives keep the near one
    travel = np.array([[0, 2, 8], [2, 0, 9], [8, 9, 0]], dtype=float)
    service = np.array([1, 1])
    for balance in ("makespan", "distance"):
        assert route_fleet(travel, service, 10, balance=balance).routes == [[0]]
    kept = {cost: route_fleet(travel, service, 10, balance="return", values=[3.0, 5.0], move_cost=cost)
            for cost in (0.0, 0.5, 2.0)}
    assert kept[0.0].routes == [[1]] and kept[0.0].dropped == [0]  # 5 beats 3 when moves are free
    assert kept[0.5].routes == [[0]]  # 3 - 2 x 0.5 = 2 beats 5 - 8 x 0.5 = 1
    assert kept[2.0].routes == [[]] and kept[2.0].dropped == [0, 1]  # neither is worth its moves
    with pytest.raises(ConfigError, match="values"):
        route_fleet(travel, service, 10, balance="return")
    with pytest.raises(ConfigError, match="values"):
        route_fleet(travel, service, 10, balance="return", values=[3.0, -1.0])
    with pytest.raises(ConfigError, match="move_cost"):
        route_fleet(travel, service, 10, balance="return", values=[3.0, 5.0], move_cost=-1.0)


def test_the_return_balance_estimates_no_less_than_the_distance_routes():
    # one AUV, 40 steps: it must leave stops out; the return search starts from the distance
    # routes and keeps its best, so by its own estimate it never does worse than they do
    env = AuvFleetEnv(episode_steps=40)
    by = {balance: planned(env, balance=balance).plan_.details for balance in ("distance", "return")}
    mine = by["return"]
    value = dict(zip(mine["hover_cells"], mine["stop_values"]))
    assert mine["move_cost"] > 0 and min(value.values()) > 0
    assert by["distance"]["dropped_stops"] and mine["routing_status"] == "feasible"

    def estimate(details):
        return sum(value[c] for route in details["routes"] for c in route) - mine["move_cost"] * sum(
            details["route_moves"])

    assert estimate(mine) >= estimate(by["distance"]) - 1e-3 * max(value.values())
    # the planner plays it: the episode's return is the simulator's, not the estimate
    record = evaluate_fleet(FleetRoutingPlanner(balance="return"), env, episodes=1, seed=0).records[0]
    assert record["return"] > 0


def test_settings_are_checked_and_act_needs_begin_episode():
    with pytest.raises(ConfigError, match="balance"):
        FleetRoutingPlanner(balance="fastest")
    with pytest.raises(ConfigError, match="solution_limit"):
        FleetRoutingPlanner(solution_limit=0)
    with pytest.raises(RuntimeError, match="begin_episode"):
        FleetRoutingPlanner().act({})

