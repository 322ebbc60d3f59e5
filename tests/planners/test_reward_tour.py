import pytest

from planners.optimal import solve_optimum
from planners.policies import KMeansTspPlanner
from planners.reward_tour import RewardKMeansTspPlanner
from swiptopt import Scenario, evaluate
from swiptopt.env import AuvSwiptEnv
from swiptopt.errors import ConfigError

DETERMINISTIC = {"channel": "none", "failure_prob_min": 0.0, "failure_prob_max": 0.0}


def one_return(policy, env):
    return evaluate(policy, env, episodes=1).records[0]["return"]


@pytest.mark.parametrize("layout", [0, 2])
def test_reaches_85_percent_of_the_milp_best_on_the_paper_preset(layout):
    env = AuvSwiptEnv(Scenario.preset("paper", n_nodes=25, layout_seed=layout, **DETERMINISTIC))
    best = solve_optimum(env.scenario, budget="quick", tables=env.tables)
    planner = RewardKMeansTspPlanner()
    tuned = one_return(planner, env)
    assert tuned >= 0.85 * best.objective
    assert tuned <= best.bound + 1e-9
    # the plan is executed as it was scored: the model's return is the simulator's
    assert tuned == pytest.approx(planner.plan_.details["model_return"], abs=1e-9)
    # and it is a different league from KMeansTspPlanner's choices (hover points for coverage)
    assert tuned > 1.15 * one_return(KMeansTspPlanner(), env)


def test_coverage_settings_plan_what_kmeans_tsp_plans():
    env = AuvSwiptEnv(Scenario.preset("paper", n_nodes=25, layout_seed=1, **DETERMINISTIC))
    kmeans_tsp = KMeansTspPlanner()
    coverage = RewardKMeansTspPlanner(selection="coverage", dwell="convex", linger_steps=2)
    assert one_return(coverage, env) == one_return(kmeans_tsp, env)
    assert coverage.plan_.stops == kmeans_tsp.plan_.stops


def test_each_choice_is_scored_in_the_simulator_model():
    # with a fixed K and the convex dwell, the walk still replays to its model return
    env = AuvSwiptEnv(Scenario.preset("paper", n_nodes=15, layout_seed=3, **DETERMINISTIC))
    for planner in (RewardKMeansTspPlanner(k=4, dwell="convex"), RewardKMeansTspPlanner(k=4)):
        value = one_return(planner, env)
        assert value == pytest.approx(planner.plan_.details["model_return"], abs=1e-9)
        assert planner.plan_.details["hover_k"] == 4
        assert len(planner.plan_.stops) <= 4
    # whole steps by marginal reward never lose to the convex program's dwell on the same K
    steps, convex = RewardKMeansTspPlanner(k=4), RewardKMeansTspPlanner(k=4, dwell="convex")
    assert one_return(steps, env) >= one_return(convex, env) - 1e-9


@pytest.mark.parametrize(("kwargs", "field"), [({"selection": "cover"}, "selection"), ({"dwell": "exact"}, "dwell"),
                                               ({"k_max": 0}, "k_max")])
def test_bad_settings_name_the_field(kwargs, field):
    with pytest.raises(ConfigError) as info:
        RewardKMeansTspPlanner(**kwargs)
    assert info.value.field == field
