"""The optimum as the benchmark's reference: the MILP and rate-greedy in the registry, what a
MILP task records, and the gap column measured against the tightest bound it has."""

import dataclasses
import math

import pytest

from planners.optimal import BUDGETS
from planners.policies import KMeansTspPlanner
from planners.reward_tour import DWELLS, MAX_EXACT_STOPS, SELECTIONS, RewardKMeansTspPlanner
from swiptopt import Scenario, evaluate
from swiptopt.benchmark import tables
from swiptopt.benchmark.algorithms import ALGORITHMS, build_policy, quick_settings
from swiptopt.benchmark.experiment import SEEDS_PER_LAYOUT, Experiment, builtin_experiments
from swiptopt.benchmark.runner import run_task
from swiptopt.benchmark.store import ResultStore
from swiptopt.cli import main
from swiptopt.env import AuvSwiptEnv
from swiptopt.metrics import EPISODE_METRICS

DETERMINISTIC = {"channel": "none", "failure_prob_min": 0.0, "failure_prob_max": 0.0}


# ------------------------------------------------------------------ the registry


def test_milp_settings_are_the_budgets_and_reach_the_solver():
    assert ALGORITHMS["milp"].settings["budget"].choices == tuple(BUDGETS)
    env = AuvSwiptEnv(Scenario.preset("tiny"))
    policy = build_policy("milp", env, {"budget": "compare", "max_nodes": 3, "time_limit_s": 50}, seed=0)
    assert policy.budget == dataclasses.replace(BUDGETS["compare"], max_nodes=3, time_limit_s=50.0)
    assert build_policy("milp", env, {}, seed=7).budget == BUDGETS["default"]  # no override: the budget itself
    # --quick: the quick budget, and an explicit node limit capped at the quick budget's
    assert quick_settings("milp", {"budget": "default", "max_nodes": 500}) == {"budget": "quick", "max_nodes": 1}
    assert quick_settings("milp", {"time_limit_s": 60}) == {"time_limit_s": 60, "budget": "quick"}


def test_registry_kmeans_tsp_is_the_improved_planner_and_keeps_the_old_one_under_settings():
    env = AuvSwiptEnv(Scenario.preset("paper", n_nodes=12, layout_seed=1, **DETERMINISTIC))
    new = build_policy("kmeans_tsp", env, {}, seed=3)
    # the planner whose 85 % of the MILP's best tests/planners/test_reward_tour.py checks,
    # with its own defaults and the task's seed
    assert type(new) is RewardKMeansTspPlanner and vars(new) == vars(RewardKMeansTspPlanner(seed=3))
    schema = ALGORITHMS["kmeans_tsp"].settings
    assert (schema["selection"].choices, schema["dwell"].choices) == (SELECTIONS, DWELLS)
    assert schema["k_max"].default == MAX_EXACT_STOPS
    assert (new.selection, new.dwell, new.linger_steps) == ("reward", "steps", 0)
    old = build_policy("kmeans_tsp", env, {"selection": "coverage", "dwell": "convex", "linger_steps": 2}, seed=0)
    before = KMeansTspPlanner(seed=0)
    assert evaluate(old, env, 1).records[0]["return"] == evaluate(before, env, 1).records[0]["return"]
    assert old.plan_.stops == before.plan_.stops


# ------------------------------------------------------------------ the gap column by hand


def _record(value):
    record = {m: 0.0 for m in EPISODE_METRICS}
    record["return"] = value
    return record


def _put(store, task, returns, extra):
    store.put({"key": task.key, "task": task.to_dict(), "records": [_record(v) for v in returns], "extra": extra,
               "duration_s": 0.0})


def test_gap_column_against_hand_computed_numbers(tmp_path):
    exp = Experiment(name="hand", scenario={"preset": "tiny", "name": "small"}, layouts=2, episodes=2,
                     algorithms={"greedy": {}, "milp": {}})
    tasks = {(t.algorithm, t.seed // SEEDS_PER_LAYOUT): t for t in exp.tasks()}
    with ResultStore(tmp_path / "hand.sqlite") as store:
        # layout 0: the MILP proved 10 (deterministic channel), the closed-form bound is 20
        _put(store, tasks["milp", 0], [9.5, 9.5], {"upper_bound_return": 20.0, "solver_status": "feasible",
                                                   "best_return": 9.5, "bound_return": 10.0, "bound_label": "milp"})
        _put(store, tasks["greedy", 0], [7.0, 9.0], {"upper_bound_return": 20.0})
        # layout 1: the model could not express the scenario: no bound, the plan hovers
        _put(store, tasks["milp", 1], [-1.0, -1.0], {"upper_bound_return": 16.0, "solver_status": "unsupported",
                                                     "best_return": None, "bound_return": None})
        _put(store, tasks["greedy", 1], [12.0, 12.0], {"upper_bound_return": 16.0})
        rows, missing = tables.aggregate(exp, store)
    assert missing == 0
    greedy, milp = (next(r for r in rows if r.algorithm == name) for name in ("greedy", "milp"))
    # greedy: (10 - 8) / 10 against the MILP's bound, (16 - 12) / 16 against the upper bound
    assert greedy.summaries[tables.GAP_BOUND].mean == pytest.approx((0.2 + 0.25) / 2, abs=1e-12)
    assert greedy.summaries[tables.GAP_BOUND].min == pytest.approx(0.2, abs=1e-12)
    assert greedy.bound == "milp 1/2, upper 1/2" and greedy.notes == ""
    # the MILP: (10 - 9.5) / 10 and (16 + 1) / 16; its [best, bound] over the layouts it solved
    assert milp.summaries[tables.GAP_BOUND].mean == pytest.approx((0.05 + 17 / 16) / 2, abs=1e-12)
    assert milp.summaries[tables.SOLVER_BEST].mean == 9.5 and milp.summaries[tables.SOLVER_BOUND].mean == 10.0
    assert milp.notes == "unsupported 1/2"
    markdown = tables.to_markdown(rows)
    assert "| MILP | 2 |" in markdown and "% [9.50, 10.00] | milp 1/2, upper 1/2 (unsupported 1/2) |" in markdown
    assert "| greedy | 1 |" in markdown and "| 22 ± 32 % | milp 1/2, upper 1/2 |" in markdown
    csv_lines = tables.to_csv(rows).splitlines()
    assert csv_lines[0].endswith(",bound,notes")
    assert any(line.startswith("greedy,1,gap_to_bound,0.225") and line.endswith(",\"milp 1/2, upper 1/2\",")
               for line in csv_lines)


def test_the_tightest_bound_wins_and_says_what_it_bounds(tmp_path):
    """Each row's gap is to the tightest bound that holds for its class (docs/optimum.md):
    the MILP's plan is open loop, greedy adaptive, and a ``milp (expected)`` bound holds for
    open-loop plans only; a record from before ``policy_bounds`` is read conservatively."""
    exp = Experiment(name="labels", scenario={"preset": "tiny", "name": "small"}, layouts=3, episodes=1,
                     algorithms={"greedy": {}, "milp": {}})
    tasks = {(t.algorithm, t.seed // SEEDS_PER_LAYOUT): t for t in exp.tasks()}
    with ResultStore(tmp_path / "labels.sqlite") as store:
        # layouts 0 and 1: the LP holds for every policy, the MILP's bound for open-loop plans;
        # above the closed-form bound (layout 0) neither is the tightest: upper wins
        for layout, lp, relaxed in ((0, 35.0, 30.0), (1, 14.0, 12.0)):
            bounds = [{"value": lp, "name": "lp (expected)", "holds_for": "adaptive"},
                      {"value": relaxed, "name": "milp (expected)", "holds_for": "open-loop"}]
            extra = {"upper_bound_return": 20.0, "solver_status": "feasible", "best_return": 10.0,
                     "bound_return": relaxed, "bound_label": "milp (expected)", "lp_bound_return": lp,
                     "policy_bounds": bounds, "policy_class": "open-loop"}
            _put(store, tasks["milp", layout], [10.0], extra)
            _put(store, tasks["greedy", layout], [15.0], {"upper_bound_return": 20.0})
        # layout 2, stored before policy_bounds: its milp (expected) bound holds for no one
        _put(store, tasks["milp", 2], [10.0], {"upper_bound_return": 20.0, "solver_status": "feasible",
                                                "best_return": 10.0, "bound_return": 11.0,
                                                "bound_label": "milp (expected)", "lp_bound_return": 16.0})
        _put(store, tasks["greedy", 2], [15.0], {"upper_bound_return": 20.0})
        rows, _ = tables.aggregate(exp, store)
    greedy, milp = (next(r for r in rows if r.algorithm == name) for name in ("greedy", "milp"))
    assert greedy.bound == "lp (expected) 2/3, upper 1/3"
    assert sorted(greedy.summaries[tables.GAP_BOUND].__dict__[k] for k in ("min", "max")) == pytest.approx(
        [(14.0 - 15.0) / 14.0, (20.0 - 15.0) / 20.0])
    assert greedy.summaries[tables.GAP_BOUND].mean == pytest.approx(((14 - 15) / 14 + 5 / 20 + 1 / 16) / 3)
    # the open-loop plan: upper, then its own MILP bound, then the old record's LP
    assert milp.bound in ("upper 1/3, milp (expected) 1/3, lp (expected) 1/3",
                          "milp (expected) 1/3, upper 1/3, lp (expected) 1/3")
    assert milp.summaries[tables.GAP_BOUND].mean == pytest.approx((10 / 20 + 2 / 12 + 6 / 16) / 3)


@pytest.mark.parametrize(("channel", "label"), [({}, "milp"), ({"channel": "shadowing"}, "milp (expected)"),
                                                ({"failure_prob_max": 0.2}, "milp (expected)")])
def test_a_milp_task_records_its_outcome_and_the_label_follows_the_channel(channel, label):
    exp = Experiment(name="t", scenario={"preset": "tiny", "name": "small", **channel}, layouts=1, episodes=2,
                     algorithms={"milp": {"budget": "quick"}})
    (task,) = exp.tasks()
    extra = run_task(task.to_dict())["extra"]
    assert extra["bound_label"] == label
    assert extra["solver_status"] == ("optimal" if label == "milp" else "feasible")
    assert extra["best_return"] <= extra["bound_return"] + 1e-9 <= extra["lp_bound_return"] + 2e-9
    assert extra["bound_return"] <= extra["upper_bound_return"] + 1e-9
    assert extra["solver_gap"] == pytest.approx(
        (extra["bound_return"] - extra["best_return"]) / abs(extra["bound_return"]), abs=1e-12)
    assert extra["solver_time_limit_hit"] is False and extra["solver_nodes"] >= 0


def test_an_unsupported_scenario_is_a_recorded_status_and_the_plan_hovers(tmp_path):
    exp = Experiment(name="drain", scenario={"preset": "tiny", "name": "small", "idle_drain_w": 1e-3}, layouts=1,
                     episodes=1, algorithms={"milp": {"budget": "quick"}})
    (task,) = exp.tasks()
    result = run_task(task.to_dict())
    extra = result["extra"]
    assert extra["solver_status"] == "unsupported" and "idle_drain_w" in extra["solver_message"]
    assert extra["bound_return"] is None and extra["best_return"] is None and "bound_label" not in extra
    (record,) = result["records"]
    assert record["auv_propulsion_j"] == 0 and record["length"] == 8  # it stayed at the start
    with ResultStore(tmp_path / "s.sqlite") as store:
        store.put(result)
        (row,), _ = tables.aggregate(exp, store)
    assert row.bound == "upper" and row.notes == "unsupported 1/1"
    assert tables.SOLVER_BEST not in row.summaries or row.summaries[tables.SOLVER_BEST].n == 0


# ------------------------------------------------------------------ a small `optimum` run


@pytest.fixture(scope="module")
def small_optimum(tmp_path_factory):
    """`swiptopt run optimum --quick` on 10 nodes: 2 layouts, the MILP at its quick budget."""
    import tomli_w

    folder = tmp_path_factory.mktemp("optimum")
    optimum = builtin_experiments()["optimum"]
    config = {"name": "optimum-10", "layouts": optimum.layouts, "episodes": optimum.episodes,
              "scenario": {**optimum.scenario, "n_nodes": 10}, "algorithms": optimum.algorithms,
              "baseline": optimum.baseline}
    path = folder / "optimum.toml"
    path.write_bytes(tomli_w.dumps(config).encode())
    store = folder / "s.sqlite"
    code = main(["run", str(path), "--quick", "--workers", "1", "--store", str(store), "--format", "markdown",
                 "--output", str(folder / "table.md")])
    experiment = Experiment.from_toml(path).quick()
    with ResultStore(store, readonly=True) as s:
        results = s.get({t.key for t in experiment.tasks()})
        rows, missing = tables.aggregate(experiment, s)
    return code, experiment, results, rows, missing, (folder / "table.md").read_text()


def test_no_algorithm_beats_the_milp_bound_in_a_small_optimum_run(small_optimum):
    code, experiment, results, rows, missing, _ = small_optimum
    assert code == 0 and missing == 0 and len(results) == 2 * len(experiment.algorithms)
    milp = {r["task"]["seed"] // SEEDS_PER_LAYOUT: r for r in results.values() if r["task"]["algorithm"] == "milp"}
    assert set(milp) == {0, 1}
    for r in milp.values():
        assert r["task"]["settings"]["budget"] == "quick"
        assert r["extra"]["solver_status"] in ("optimal", "feasible") and r["extra"]["bound_label"] == "milp"
        # deterministic channel: the plan earns in the simulator exactly its value in the model
        for record in r["records"]:
            assert record["return"] == pytest.approx(r["extra"]["best_return"], abs=1e-9)
        assert r["extra"]["bound_return"] < r["extra"]["upper_bound_return"]
    for r in results.values():
        bound = milp[r["task"]["seed"] // SEEDS_PER_LAYOUT]["extra"]["bound_return"]
        for record in r["records"]:
            assert record["return"] <= bound + 1e-9, r["task"]["algorithm"]
    for row in rows:
        assert row.bound == "milp" and row.summaries[tables.GAP_BOUND].n == 2
        assert row.summaries[tables.GAP_BOUND].min >= -1e-12, row.algorithm
    gaps = {row.algorithm: row.summaries[tables.GAP_BOUND].mean for row in rows}
    best = {layout: r["extra"]["best_return"] for layout, r in milp.items()}
    bounds = {layout: r["extra"]["bound_return"] for layout, r in milp.items()}
    assert gaps["milp"] == pytest.approx(sum((bounds[k] - best[k]) / bounds[k] for k in (0, 1)) / 2, abs=1e-12)


def test_the_small_optimum_table_shows_the_bound_and_the_milp_row(small_optimum):
    *_, rows, _, text = small_optimum
    assert "| gap to bound | bound |" in text
    milp = next(r for r in rows if r.algorithm == "milp")
    line = next(line for line in text.splitlines() if line.startswith("| MILP |"))
    best, bound = milp.summaries[tables.SOLVER_BEST].mean, milp.summaries[tables.SOLVER_BOUND].mean
    assert f"[{best:.2f}, {bound:.2f}] | milp |" in line
    assert not math.isnan(best) and best <= bound
    # the paired table is against the MILP's best walk
    assert "| rate-greedy |" in text and "×" in text
