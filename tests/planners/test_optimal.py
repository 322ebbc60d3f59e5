import gymnasium as gym
import numpy as np
import pytest

import swiptopt
from planners.bounds import exact_optimum, upper_bound
from planners.optimal import MilpBudget, MilpPlanner, resolve_budget, solve_optimum
from planners.policies import GreedyPlanner, KMeansTspPlanner, LawnmowerPlanner
from planners.rate_greedy import RateGreedyPlanner
from planners.service import step_model
from swiptopt import Scenario, evaluate
from swiptopt import kernel as K
from swiptopt.env import AuvSwiptEnv
from swiptopt.errors import ConfigError

DETERMINISTIC = {"channel": "none", "failure_prob_min": 0.0, "failure_prob_max": 0.0}
QUICK = resolve_budget("quick")


def replay(scenario, actions):
    """The return of an action sequence in the registered environment."""
    env = gym.make(swiptopt.ENV_ID, scenario=scenario)
    env.reset(seed=0)
    total = 0.0
    for a in actions:
        _, r, terminated, truncated, _ = env.step(a)
        total += r
        if terminated or truncated:
            break
    env.close()
    return total


@pytest.mark.parametrize("layout", [1, 4, 5])
def test_tiny_milp_equals_the_exact_optimum(layout):
    scenario = Scenario.preset("tiny", layout_seed=layout)
    result = solve_optimum(scenario, budget=MilpBudget(max_nodes=10_000, rel_gap=0.0))
    best = exact_optimum(scenario)
    assert result.status == "optimal" and result.exact
    assert result.objective == pytest.approx(best.return_, abs=1e-9)
    assert result.bound >= best.return_ - 1e-9
    assert replay(scenario, result.actions) == pytest.approx(best.return_, abs=1e-9)


@pytest.fixture(scope="module")
def paper10():
    scenario = Scenario.preset("paper", n_nodes=10, layout_seed=1, **DETERMINISTIC)
    return scenario, solve_optimum(scenario, budget=QUICK)


def test_paper_plan_replays_to_its_objective(paper10):
    scenario, result = paper10
    assert result.status in ("optimal", "feasible") and result.exact
    assert len(result.actions) == scenario.episode_steps
    # the MILP's own value of its incumbent is the simulator's return of the plan
    assert result.details["highs_objective"] == pytest.approx(result.objective, abs=1e-5)
    assert replay(scenario, result.actions) == pytest.approx(result.objective, abs=1e-9)
    # the policy object solves again, finds the same plan (same numbers on every run) and
    # plays it through evaluate
    env = AuvSwiptEnv(scenario)
    planner = MilpPlanner(budget=QUICK)
    record = evaluate(planner, env, episodes=1).records[0]
    assert planner.result_.actions == result.actions
    assert (planner.result_.bound, planner.result_.lp_bound, planner.result_.nodes) == (
        result.bound, result.lp_bound, result.nodes
    )
    assert record["return"] == pytest.approx(result.objective, abs=1e-9)


def test_paper_bound_dominates_every_algorithm_and_tightens_the_upper_bound(paper10):
    scenario, result = paper10
    simple = upper_bound(scenario).return_
    assert result.objective <= result.bound + 1e-9
    assert result.lp_bound >= result.bound - 1e-9  # branching only tightens
    assert result.bound < simple - 0.05 * abs(simple)  # strictly, and by a margin
    env = AuvSwiptEnv(scenario)
    returns = {}
    for policy in (KMeansTspPlanner(tsp_time_limit_s=0.5), GreedyPlanner(), LawnmowerPlanner(), RateGreedyPlanner()):
        returns[type(policy).__name__] = evaluate(policy, env, episodes=1).records[0]["return"]
    assert max(returns.values()) <= result.bound + 1e-9
    # warm-started from the rate-greedy walk: never worse than it
    assert result.objective >= returns["RateGreedyPlanner"] - 1e-9


def test_bound_is_below_the_old_bound_on_tiny_too():
    for layout in range(4):
        scenario = Scenario.preset("tiny", layout_seed=layout)
        result = solve_optimum(scenario, budget=QUICK)
        assert result.bound <= upper_bound(scenario).return_ + 1e-9


def test_step_model_is_the_simulator_on_random_walks_with_obstacles_and_a_current():
    # harbour: obstacles (blocked moves), a current (direction-dependent move costs)
    scenario = Scenario.preset("harbour", n_nodes=12, episode_steps=60, **DETERMINISTIC)
    tables = K.build_tables(scenario)
    model = step_model(tables)
    rng = np.random.default_rng(3)
    for _ in range(3):
        actions = rng.integers(0, K.N_ACTIONS, size=scenario.episode_steps).tolist()
        value, steps = model.walk_return(actions)
        assert value == pytest.approx(replay(scenario, actions), abs=1e-9)
        assert steps == scenario.episode_steps


def test_current_gives_a_valid_bound_and_an_honest_status():
    scenario = Scenario.preset("harbour", n_nodes=6, episode_steps=40, **DETERMINISTIC)
    result = solve_optimum(scenario, budget=QUICK)
    assert result.status == "feasible" and not result.exact
    assert "current" in result.message
    assert result.objective == pytest.approx(replay(scenario, result.actions), abs=1e-9)
    env = AuvSwiptEnv(scenario)
    for policy in (RateGreedyPlanner(), GreedyPlanner()):
        assert evaluate(policy, env, episodes=1).records[0]["return"] <= result.bound + 1e-9


def test_stochastic_channel_solves_the_expected_rate_relaxation():
    scenario = Scenario.preset("paper", n_nodes=8, layout_seed=2)  # shadowing and link failures
    env = AuvSwiptEnv(scenario)
    planner = MilpPlanner(budget=QUICK)
    mean = evaluate(planner, env, episodes=20, seed=5).summary["return"].mean
    result = planner.result_
    assert result.status == "feasible" and not result.exact
    assert "expected-rate relaxation" in result.message
    assert result.objective <= result.bound + 1e-9
    # Jensen: the open-loop plan's mean return stays below its relaxed value (8 nodes and
    # 50 steps cannot serve everyone, so no episode ends early)
    assert mean <= result.objective + 1e-9


def test_expected_amounts_match_monte_carlo():
    # the quadrature against direct draws of the kernel's fading, for both fading laws
    for channel in ("shadowing", "rician"):
        scenario = Scenario.preset("paper", n_nodes=6, layout_seed=3, channel=channel, shadowing_sigma_db=6.0,
                                   rician_k=2.0, failure_prob_min=0.1, failure_prob_max=0.1, data_bits=2e5)
        tables = K.build_tables(scenario)
        model = step_model(tables)
        rng = np.random.default_rng(0)
        draws = 400_000
        p = tables.params
        if channel == "shadowing":
            gain = np.exp(p[K.P_SIGMA_DB] * K.LN10_OVER_10 * rng.standard_normal(draws))
        else:
            k = p[K.P_RICIAN_K]
            re = np.sqrt(k / (k + 1)) + np.sqrt(0.5 / (k + 1)) * rng.standard_normal(draws)
            im = np.sqrt(0.5 / (k + 1)) * rng.standard_normal(draws)
            gain = re**2 + im**2
        for pair in (0, len(tables.cov_node) // 2, len(tables.cov_node) - 1):
            node = tables.cov_node[pair]
            snr = gain * tables.cov_snr[pair]
            bits = np.where(snr >= p[K.P_SNR_TH], p[K.P_DT] * p[K.P_BW] * np.log2(1 + p[K.P_ALPHA] * snr), 0.0)
            expected_bits = (1 - tables.fail_prob[node]) * np.minimum(bits, tables.data0[node]).mean()
            joules = np.minimum(
                p[K.P_DT] * p[K.P_ETA] * (1 - p[K.P_ALPHA]) * gain * tables.cov_pav[pair],
                tables.capacity[node] - tables.energy0[node],
            ).mean()
            assert model.bits[pair] == pytest.approx(expected_bits, rel=1e-2)
            assert model.joules[pair] == pytest.approx(joules, rel=1e-2)


@pytest.mark.parametrize(
    ("override", "field"),
    [
        ({"idle_drain_w": 1e-3}, "idle_drain_w"),
        ({"energy_gate_j": 0.5}, "energy_gate_j"),
        ({"battery_j": 1e4}, "battery_j"),
        ({"link": "uplink"}, "uplink"),
    ],
)
def test_unsupported_scenarios_return_a_status_naming_the_reason(override, field):
    scenario = Scenario.preset("paper", n_nodes=5, **DETERMINISTIC, **override)
    result = solve_optimum(scenario, budget=QUICK)
    assert result.status == "unsupported"
    assert field in result.message
    assert result.objective is None and result.actions == []


def test_a_graph_too_large_for_the_budget_is_unsupported():
    scenario = Scenario.preset("paper", n_nodes=10, **DETERMINISTIC)
    result = solve_optimum(scenario, budget=MilpBudget(max_arcs=10))
    assert result.status == "unsupported" and "max_arcs" in result.message


def test_no_coverable_node_gives_the_cheapest_stay():
    # nodes outside every cone: the best walk stays put, paying only the hover penalty
    scenario = Scenario.preset("tiny", cone_half_angle_deg=1.0, node_positions_m=((1.0, 1.0, 19.0),) * 3)
    result = solve_optimum(scenario, budget=QUICK)
    model = step_model(K.build_tables(scenario))
    assert result.status == "optimal"
    assert result.objective == pytest.approx(-scenario.episode_steps * model.stay_cost[model.start_cell], abs=1e-12)
    assert replay(scenario, result.actions) == pytest.approx(result.objective, abs=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"max_nodes": -1}, "max_nodes"), ({"rel_gap": float("nan")}, "rel_gap"), ({"time_limit_s": 0}, "time_limit_s"),
     ({"cut_rounds": 1.5}, "cut_rounds")],
)
def test_bad_budgets_name_the_field(kwargs, field):
    with pytest.raises(ConfigError) as info:
        MilpBudget(**kwargs)
    assert info.value.field == field


def test_budget_names():
    assert resolve_budget("quick").max_nodes < resolve_budget("default").max_nodes
    with pytest.raises(ConfigError, match="budget"):
        resolve_budget("fast")
