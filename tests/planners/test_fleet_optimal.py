import numpy as np
import pytest

from planners.bounds import ADAPTIVE, LP_EXPECTED_NAME, MILP_EXPECTED_NAME, MILP_NAME, OPEN_LOOP, PolicyBound
from planners.fleet import BALANCES, FleetRoutingPlanner
from planners.fleet_optimal import (
    FleetMilpPlanner,
    auv_models,
    fleet_policy_bounds,
    fleet_walk_return,
    solve_fleet_optimum,
)
from planners.optimal import MilpBudget, resolve_budget, solve_optimum
from planners.service import step_model
from swiptopt import Scenario
from swiptopt import kernel as K
from swiptopt.env_fleet import AuvFleetEnv
from swiptopt.evaluation import evaluate_fleet

DETERMINISTIC = {"channel": "none", "failure_prob_min": 0.0, "failure_prob_max": 0.0}
QUICK = resolve_budget("quick")
#: enough branching to prove the tiny instances optimal
FULL = MilpBudget(max_nodes=10_000, rel_gap=0.0, polish_evaluations=2000, cut_rounds=2, time_limit_s=300.0)
#: the default start cells of two AUVs on the tiny preset's 3 x 3 grid
TWO_STARTS = ((0, 1, 0), (2, 1, 0))


def tiny(**overrides):
    return Scenario.preset("tiny", **{**DETERMINISTIC, **overrides})


def replay(planner, scenario):
    """The fleet's return when ``planner`` plays one episode of ``scenario``."""
    return evaluate_fleet(planner, AuvFleetEnv(scenario), episodes=1).records[0]["return"]


class RandomFleet:
    """Uniformly random actions from a seeded generator: a cheap fleet policy to bound."""

    def __init__(self, seed):
        self.rng = np.random.default_rng(seed)

    def begin_episode(self, env, observations=None, infos=None):
        self.env = env

    def act(self, observations=None):
        return {agent: int(self.rng.integers(K.N_ACTIONS)) for agent in self.env.agents}


@pytest.mark.parametrize("layout", [1, 4])
def test_one_auv_is_the_single_milp(layout):
    scenario = tiny(layout_seed=layout)
    fleet = solve_fleet_optimum(scenario, budget=QUICK)
    single = solve_optimum(scenario, budget=QUICK)
    assert fleet.status == single.status == "optimal"
    assert fleet.objective == pytest.approx(single.objective, rel=1e-12)
    assert (fleet.bound, fleet.lp_bound, fleet.nodes) == (single.bound, single.lp_bound, single.nodes)
    assert fleet.actions == [single.actions]
    for name in ("vertices", "arcs", "rows", "columns", "cuts", "highs_objective"):
        assert fleet.details[name] == single.details[name]


@pytest.mark.parametrize("layout", [1, 3])
def test_shared_cells_plan_replays_to_its_objective(layout):
    scenario = tiny(layout_seed=layout, n_auvs=2, share_cells=True, episode_steps=6)
    planner = FleetMilpPlanner(budget=QUICK)
    score = replay(planner, scenario)
    result = planner.result_
    assert result.status in ("optimal", "feasible") and result.exact
    assert result.details["blocked_moves"] == 0 and not result.details["relaxes_cell_sharing"]
    assert [len(a) for a in result.actions] == [scenario.episode_steps] * 2
    assert score == pytest.approx(result.objective, rel=1e-9, abs=1e-12)
    if result.details["plan"] == "milp":  # the program's value of its plan is what the plan earns
        assert result.details["milp_objective"] == pytest.approx(result.objective, abs=1e-5)
    assert result.objective <= result.bound + 1e-9 <= result.lp_bound + 2e-9


def test_a_blocked_plan_is_scored_as_played():
    # AUVs side by side without shared cells: the program's walks cross and get blocked
    scenario = tiny(layout_seed=0, n_auvs=2, auv_start_cells=((1, 1, 0), (2, 1, 0)), episode_steps=10)
    planner = FleetMilpPlanner(budget=QUICK)
    score = replay(planner, scenario)
    result = planner.result_
    assert result.details["relaxes_cell_sharing"]
    assert score == pytest.approx(result.objective, rel=1e-9)
    assert result.objective <= result.bound + 1e-9
    if result.details["blocked_moves"]:
        assert result.status == "feasible" and "blocked" in result.message


@pytest.mark.parametrize("movement_weight", [0.0, None])
def test_two_auvs_earn_at_least_one_auvs_optimum(movement_weight):
    weight = {} if movement_weight is None else {"movement_weight": movement_weight}
    single = solve_optimum(tiny(layout_seed=1, start_cell=TWO_STARTS[0], **weight), budget=FULL)
    scenario = tiny(layout_seed=1, n_auvs=2, auv_start_cells=TWO_STARTS, share_cells=True, **weight)
    fleet = solve_fleet_optimum(scenario, budget=FULL)
    assert single.status == fleet.status == "optimal"
    # AUV 0 can walk the single AUV's best walk while AUV 1 hovers at its start: that costs
    # AUV 1's hover penalty for at most the whole episode (nothing without a movement penalty)
    model = step_model(K.build_tables(scenario))
    hover = scenario.episode_steps * model.stay_cost[scenario.cell_index(TWO_STARTS[1])]
    assert (hover == 0.0) == (movement_weight == 0.0)
    assert fleet.objective >= single.objective - hover - 1e-9
    if movement_weight == 0.0:
        assert fleet.objective >= single.objective - 1e-9


@pytest.mark.parametrize("share_cells", [True, False])
def test_bound_holds_for_every_fleet_algorithm(share_cells):
    scenario = tiny(layout_seed=1, n_auvs=2, share_cells=share_cells)
    result = solve_fleet_optimum(scenario, budget=QUICK)
    assert result.bound >= result.objective - 1e-9
    assert fleet_policy_bounds(result) == [PolicyBound(result.bound, MILP_NAME, ADAPTIVE)]
    routing = [FleetRoutingPlanner(balance=balance, solution_limit=10) for balance in BALANCES]
    returns = [replay(policy, scenario) for policy in routing + [RandomFleet(seed) for seed in range(3)]]
    assert max(returns) <= result.bound + 1e-9


def test_same_scenario_gives_the_same_plan_and_numbers():
    scenario = tiny(layout_seed=2, n_auvs=2, episode_steps=6)
    first, second = (solve_fleet_optimum(scenario, budget=QUICK) for _ in range(2))
    assert first.actions == second.actions
    assert (first.status, first.objective, first.bound, first.lp_bound, first.nodes) == (
        second.status, second.objective, second.bound, second.lp_bound, second.nodes
    )
    assert first.details == second.details


def test_auvs_sharing_a_start_get_symmetry_rows():
    scenario = tiny(layout_seed=3, n_auvs=3, share_cells=True, auv_start_cells=((1, 1, 0), (1, 1, 0), (2, 2, 0)),
                    episode_steps=6)
    result = solve_fleet_optimum(scenario, budget=FULL)
    assert result.details["symmetry_rows"] == 1
    assert result.status == "optimal"
    starts = [scenario.cell_index(c) for c in scenario.fleet_start_cells]
    models = auv_models(step_model(K.build_tables(scenario)), starts)
    # the earlier of the two AUVs that start together makes at least as many moves
    moves = []
    for model, actions in zip(models[:2], result.actions[:2]):
        cell, count = model.start_cell, 0
        for a in actions:
            count += int(model.next_cell[cell, a] != cell)
            cell = int(model.next_cell[cell, a])
        moves.append(count)
    assert moves[0] >= moves[1]
    value, _, blocked = fleet_walk_return(models, result.actions, share_cells=True)
    assert blocked == 0 and value == pytest.approx(result.objective, abs=1e-12)
    # swapping the two alike AUVs' walks changes nothing
    swapped = [result.actions[1], result.actions[0], result.actions[2]]
    assert fleet_walk_return(models, swapped, share_cells=True)[0] == pytest.approx(value, abs=1e-12)


def test_stochastic_channel_gives_the_relaxation_bounds():
    scenario = Scenario.preset("tiny", n_auvs=2, channel="shadowing", failure_prob_min=0.1, failure_prob_max=0.1)
    result = solve_fleet_optimum(scenario, budget=QUICK)
    assert result.status == "feasible" and not result.exact
    assert "expected-rate relaxation" in result.message
    assert result.objective <= result.bound + 1e-9 <= result.lp_bound + 2e-9
    # the LP bound for every fleet policy; the MILP's for open-loop plans only, and only when
    # no episode can end early (a node no cell covers, as on this layout)
    expected = [(LP_EXPECTED_NAME, ADAPTIVE)]
    if not result.details["can_end_early"] and result.bound < result.lp_bound:
        expected.append((MILP_EXPECTED_NAME, OPEN_LOOP))
    assert [(b.name, b.holds_for) for b in fleet_policy_bounds(result)] == expected


@pytest.mark.parametrize(
    ("overrides", "field"),
    [({"auv_batteries_j": (1e9, 1e3)}, "auv_batteries_j"), ({"link": "uplink"}, "uplink")],
)
def test_unsupported_fleets_return_a_status_naming_the_reason(overrides, field):
    result = solve_fleet_optimum(tiny(n_auvs=2, **overrides), budget=QUICK)
    assert result.status == "unsupported" and field in result.message
    assert result.objective is None and result.actions == [] and fleet_policy_bounds(result) == []


def test_too_many_arcs_for_the_budget_is_unsupported():
    result = solve_fleet_optimum(tiny(n_auvs=2), budget=MilpBudget(max_arcs=5))
    assert result.status == "unsupported" and "max_arcs" in result.message
