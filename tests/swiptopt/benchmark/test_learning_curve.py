"""The learning curves: budgets in experiments, one training run serving every budget of a
lineage, the curves' table and figure, and the built-in group in --quick."""

from __future__ import annotations

import json
import re

import pytest

from swiptopt.benchmark import plots, tables
from swiptopt.benchmark.experiment import GROUPS, Experiment, builtin_experiments, learning_curves, load_experiments
from swiptopt.benchmark.runner import _batches, execute
from swiptopt.benchmark.store import ResultStore
from swiptopt.cli import main
from swiptopt.errors import ConfigError

pytest.importorskip("stable_baselines3")

TINY_PPO = {"n_steps": 32, "batch_size": 32, "net_arch": [16], "n_envs": 2, "n_epochs": 1, "training_seeds": 2}


def curve(**fields):
    fields.setdefault("name", "curve")
    fields.setdefault("scenario", {"preset": "tiny", "failure_prob_min": 0.05, "failure_prob_max": 0.1})
    fields.setdefault("episodes", 2)
    fields.setdefault("layouts", 2)
    fields.setdefault("algorithms", {"ppo": TINY_PPO, "greedy": {}})
    fields.setdefault("budgets", {"ppo": [64, 128, 256]})
    return Experiment(**fields)


def test_budgets_expand_into_a_row_per_budget_and_one_lineage_per_model():
    e = curve()
    tasks = e.tasks()
    ppo = [t for t in tasks if t.algorithm == "ppo"]
    assert len(ppo) == 2 * 2 * 3 and {t.settings["timesteps"] for t in ppo} == {64, 128, 256}
    assert {t.row for t in ppo} == {"ppo@64", "ppo@128", "ppo@256"}
    assert [r for r, _, _ in e.rows()] == ["ppo@64", "ppo@128", "ppo@256", "greedy"]
    stages = _batches(tasks, workers=2, models_dir="/tmp/models")
    trainers = [b[0] for b in stages[0] if "checkpoints" in b[0]]
    # one training per (layout, seed), at the longest budget, told to save the shorter ones
    assert len(trainers) == 4 and all(t["settings"]["timesteps"] == 256 for t in trainers)
    assert all(t["checkpoints"] == [64, 128] for t in trainers)
    assert sum(len(b) for b in stages[1]) == 8  # the shorter budgets wait for them


@pytest.mark.parametrize("budgets, words", [
    ({"ppo": [128, 64]}, "increasing order"),
    ({"ppo": [64, 64]}, "distinct"),
    ({"greedy": [64]}, "no 'timesteps' or 'train_episodes' setting"),
    ({"dqn": [64]}, "not one of the experiment's algorithms"),
    ({"ppo": []}, "1 to 32"),
    ({"ppo": [0]}, "budgets.ppo"),
])
def test_bad_budgets_are_one_line_errors(budgets, words):
    with pytest.raises(ConfigError, match=words) as info:
        curve(budgets=budgets)
    assert "\n" not in str(info.value)


def test_a_tabular_learners_budgets_set_its_training_episodes():
    """Budgets of an algorithm without ``timesteps`` (tabular RL) set its ``train_episodes``:
    each budget's tasks are, key for key, those of the experiment that trains that many
    episodes (so a suite's row is a point of the curve), --quick shrinks them to the
    setting's quick value and twice it, and the figure's axis counts episodes."""
    q = {"q_learning": {"learning_rate": 0.2}, "greedy": {}}
    e = curve(algorithms=q, budgets={"q_learning": [3000, 6000, 12000]})
    assert e.budget_setting("q_learning") == "train_episodes" and e.budget_setting("greedy") is None
    assert [r for r, _, _ in e.rows()] == ["q_learning@3000", "q_learning@6000", "q_learning@12000", "greedy"]
    for budget in (3000, 12000):
        alone = curve(algorithms={"q_learning": {"learning_rate": 0.2, "train_episodes": budget}, "greedy": {}},
                      budgets={})
        keys = {t.key for t in alone.tasks() if t.algorithm == "q_learning"}
        assert keys == {t.key for t in e.tasks() if t.budget == budget} and len(keys) == 2
    assert sorted({t.settings["train_episodes"] for t in e.quick().tasks() if t.budget}) == [2000, 4000]
    assert plots._budget_units(e) == "episodes"
    mixed = curve(algorithms={**q, "ppo": TINY_PPO, "stop_ppo": {}},
                  budgets={"q_learning": [64], "ppo": [64], "stop_ppo": [64]})
    assert plots._budget_units(mixed) == "steps; Q-learning: episodes; stop-choosing PPO: decisions"
    with pytest.raises(ConfigError, match="budgets.q_learning and train_episodes set elsewhere"):
        curve(algorithms={"q_learning": {"train_episodes": 10}}, budgets={"q_learning": [64]})


@pytest.mark.parametrize(("name", "head"), [
    ("learning-curve-grid-tabular", "episodes: mean ± 95 % CI"),
    ("learning-curve-grid-stop-ppo", "decisions: mean ± 95 % CI"),
    ("learning-curve-grid-ppo-dqn", "steps: mean ± 95 % CI"),
    ("learning-curve-fleet-optimum-one",
     "mean ± 95 % CI; budgets in decisions for stop-choosing PPO (fleet), in steps for parameter-shared PPO"),
])
def test_a_curve_tables_header_names_what_its_budgets_count(tmp_path, name, head):
    """The curve table's budget column says what the budgets count: training episodes for
    tabular RL, decisions for a stop-choosing agent, steps for the others, and each
    algorithm's where an experiment mixes them."""
    from pathlib import Path

    out = tmp_path / "curve.md"
    store = Path(__file__).parents[3] / "benchmarks" / "stores" / f"{name}.sqlite"
    assert main(["table", str(store), "--experiment", name, "--format", "markdown", "--output", str(out)]) == 0
    (header,) = [line for line in out.read_text().splitlines() if line.startswith("| experiment | algorithm |")]
    assert header.split(" | ")[2] == f"return at each budget ({head})"


def test_a_curve_runs_at_one_sweep_point():
    """A curve's table and figure have one line per algorithm, so budgets with a sweep of
    several points (whose lines would hide one another) are refused; one point is a curve."""
    assert curve(sweep={"n_nodes": [4]}).budgets == {"ppo": [64, 128, 256]}
    with pytest.raises(ConfigError, match="sweep of 2 points.*one experiment file per point") as info:
        curve(sweep={"n_nodes": [4, 5]})
    assert "\n" not in str(info.value) and info.value.field == "budgets"


def test_a_curve_trains_once_per_lineage_and_reports_its_plateau(tmp_path):
    e = curve()
    with ResultStore(tmp_path / "s.sqlite") as store:
        report = execute(e, store, workers=2)
        assert report.failed == 0, report.failures
        results = store.get({t.key for t in e.tasks()})
        extras = [r["extra"] for r in results.values() if r["task"]["algorithm"] == "ppo"]
        trained = [x for x in extras if not x["model_loaded"]]
        # the four lineages trained once each, at 256 steps; the 64- and 128-step models are
        # their checkpoints, loaded by the other tasks
        assert len(trained) == 4 and len(extras) == 12
        rows, missing = tables.aggregate(e, store)
        assert missing == 0 and [r.label for r in rows][:3] == ["PPO @ 64", "PPO @ 128", "PPO @ 256"]
        (row,) = tables.curve_rows(e, store)
        assert row.budgets == (64, 128, 256) and len(row.returns) == 3 and row.reference == "greedy"
        assert row.ratio is not None and row.ratio.n == 2
        last, before = row.returns[-1], row.returns[-2]
        assert row.flat == (abs(last.mean - before.mean) <= min(last.ci95, before.ci95))
        assert row.near_plateau in row.budgets
        text = tables.curves_to_markdown([row])
        assert "PPO" in text and "64:" in text and "(greedy)" in text
        figure = plots.learning_curve_figure([e], store, tmp_path / "fig")
    assert figure.skipped == "" and {p.suffix for p in figure.paths} == {".png", ".pdf", ".csv"}
    lines = (tmp_path / "fig" / "fig-learning-curve.csv").read_text().splitlines()
    assert len(lines) == 1 + 3 + 1  # header, three budgets, the planner's band
    # `swiptopt plot` draws the same curves from the store alone
    from swiptopt.cli import main

    assert main(["plot", str(tmp_path / "s.sqlite"), "--outdir", str(tmp_path / "plotted")]) == 0
    assert (tmp_path / "plotted" / "fig-learning-curve.csv").read_text().splitlines() == lines
    # one experiment of a store, drawn apart under its own name; a name the store lacks is refused
    assert main(["plot", str(tmp_path / "s.sqlite"), "--outdir", str(tmp_path / "one"), "--experiment", "curve"]) == 0
    assert (tmp_path / "one" / "fig-curve.csv").read_text().splitlines() == lines
    assert not (tmp_path / "one" / "fig-learning-curve.csv").exists()
    assert main(["plot", str(tmp_path / "s.sqlite"), "--outdir", str(tmp_path / "none"), "--experiment", "nope"]) == 2
    assert not (tmp_path / "none").exists()

    # a run stopped part-way: one task of the last budget has no result. Its mean is shown
    # with its task count, no verdict is drawn from it, and the figure leaves it out.
    import sqlite3

    last_key = next(t.key for t in e.tasks() if t.budget == 256)
    with sqlite3.connect(tmp_path / "s.sqlite") as db:
        db.execute("DELETE FROM results WHERE key = ?", (last_key,))
    db.close()
    with ResultStore(tmp_path / "s.sqlite", readonly=True) as store:
        (partial,) = tables.curve_rows(e, store)
        figure = plots.learning_curve_figure([e], store, tmp_path / "partial")
    assert partial.tasks == ((4, 4), (4, 4), (3, 4)) and partial.complete == (True, True, False)
    assert partial.flat is None and partial.near_plateau is None and partial.ratio is None
    assert partial.returns[-1].n == 3 and partial.returns[0] == row.returns[0]
    text = tables.curves_to_markdown([partial])
    assert "256: " in text and "(3 of 4 tasks)" in text and text.count("incomplete") == 3
    kept = (tmp_path / "partial" / "fig-learning-curve.csv").read_text().splitlines()
    assert kept == [line for line in lines if not line.startswith("curve,ppo,256,")]
    assert len(kept) == len(lines) - 1


def test_a_lineage_whose_last_model_is_kept_trains_once_to_the_budget_before(tmp_path):
    """A lineage whose longest budget's model is already kept (here trained by a run of that
    budget alone beside the store; in practice a shipped model) loads it and trains once, to
    its longest budget without a model, saving the shorter ones on its way, instead of
    training every shorter budget apart: the same results as a run that trains everything."""
    e = curve()
    alone = curve(name="alone", budgets={}, algorithms={"ppo": {**TINY_PPO, "timesteps": 256}, "greedy": {}})
    with ResultStore(tmp_path / "kept" / "first.sqlite") as first:
        assert execute(alone, first, workers=1).failed == 0
    stages = _batches(e.tasks(), workers=2, models_dir=str(tmp_path / "kept" / "models"))
    trainers = [b[0] for b in stages[0] if "checkpoints" in b[0]]
    assert len(trainers) == 4 and all(t["settings"]["timesteps"] == 128 and t["checkpoints"] == [64] for t in trainers)
    # the kept 256-step models' tasks run beside the trainers, the 64-step ones after them
    loading = [[d["settings"]["timesteps"] for b in stage for d in b
                if d["algorithm"] == "ppo" and "checkpoints" not in d] for stage in stages]
    assert loading == [[256] * 4, [64] * 4]
    results = {}
    for name in ("kept", "fresh"):
        with ResultStore(tmp_path / name / "s.sqlite") as store:
            assert execute(e, store, workers=2).failed == 0
            results[name] = store.get({t.key for t in e.tasks()})
    assert results["kept"].keys() == results["fresh"].keys() and len(results["kept"]) == 14
    for key, result in results["kept"].items():
        assert result["records"] == results["fresh"][key]["records"]
    trained = [r["task"]["settings"]["timesteps"] for r in results["kept"].values()
               if r["task"]["algorithm"] == "ppo" and not r["extra"]["model_loaded"]]
    assert trained == [128] * 4


def test_a_checkpoint_evaluates_like_the_run_of_its_length(tmp_path):
    """A budget's row is the same whether its model came from a longer run's checkpoint or
    from a run of that length alone."""
    both = curve(budgets={"ppo": [64, 128]}, layouts=1, algorithms={"ppo": {**TINY_PPO, "training_seeds": 1}})
    alone = curve(budgets={"ppo": [64]}, layouts=1, algorithms={"ppo": {**TINY_PPO, "training_seeds": 1}})
    reports = []
    with ResultStore(tmp_path / "a" / "s.sqlite") as store:
        execute(both, store, workers=1, on_training=lambda task, *report: reports.append((task.key, *report)))
        a = store.get({t.key for t in both.tasks() if t.budget == 64})
    # the one training (the lineage's, at 128 steps) told the parent how far it had got
    (trainer,) = [t.key for t in both.tasks() if t.budget == 128]
    assert {r[0] for r in reports} == {trainer} and reports[0][1:] == (0, 128, False)
    assert reports[-1][1:] == (128, 128, True) and [r[1] for r in reports] == sorted(r[1] for r in reports)
    with ResultStore(tmp_path / "b" / "s.sqlite") as store:
        execute(alone, store, workers=1)
        b = store.get({t.key for t in alone.tasks()})
    assert set(a) == set(b)
    assert [a[k]["records"] for k in sorted(a)] == [b[k]["records"] for k in sorted(b)]
    assert all(r["extra"]["model_loaded"] for r in a.values())  # the checkpoint
    assert not any(r["extra"]["model_loaded"] for r in b.values())  # trained alone


def test_the_built_in_curves_cover_both_worlds_and_both_trainings():
    (group,) = GROUPS.values()
    experiments = load_experiments("learning-curve")
    assert [e.name for e in experiments] == list(group) == [e.name for e in learning_curves()]
    assert {e.world for e in experiments} == {"grid", "continuous"}
    for e in experiments:
        trainings = {e.algorithms[name]["training"] for name in e.budgets}
        assert len(trainings) == 1
        assert len(e.layout_seeds()) >= 6 and e.baseline in e.algorithms and e.baseline not in e.budgets
        for budgets in e.budgets.values():
            assert len(budgets) >= 4 and all(b2 == 2 * b1 for b1, b2 in zip(budgets, budgets[1:]))
        tasks = e.tasks()
        seeds = {t.seed % 1000 for t in tasks if t.algorithm in e.budgets}
        assert seeds == {0, 1, 2}  # three training seeds
    assert {("grid", "across_layouts"), ("grid", "per_layout"), ("continuous", "across_layouts"),
            ("continuous", "per_layout")} == {(e.world, next(iter(e.algorithms[n]["training"] for n in e.budgets)))
                                              for e in experiments}


def test_the_grid_curves_run_in_quick(tmp_path, monkeypatch, capsys):
    import swiptopt.cli
    from swiptopt.cli import main

    monkeypatch.setattr(swiptopt.cli, "STATUS_INTERVAL_S", 0.0)  # every report is a line (stderr is no terminal)
    out = tmp_path / "curves.md"
    code = main(["run", "learning-curve", "--quick", "--store", str(tmp_path / "s.sqlite"), "--format", "markdown",
                 "--output", str(out), "--workers", "2", "--keep-state"])
    assert code == 0
    # --keep-state: each lineage's longest training keeps its state at its end, for a longer budget to go on from
    from rl.resume import read_state

    states = {p.name.split("-")[0]: read_state(p, header_only=True)[0]
              for p in (tmp_path / "models").glob("*.state.npz")}
    longest = {b[-1] for e in learning_curves() for b in e.quick().budgets.values()}
    assert {"sac", "ppo", "dqn", "maskable_ppo"} <= set(states)
    assert all(header["steps"] in longest for header in states.values())
    status = capsys.readouterr().err.splitlines()
    # plain status lines: the tasks done, and each training under way with its steps
    assert status[0].startswith("learning-curve: 0/") and " tasks, 0:00:0" in status[0]
    assert any(re.search(r"training dqn \(seed \d, layout \d+\): [\d,]+/[\d,]+ steps", line) for line in status)
    assert any(re.search(r"training sac \(seed \d, across layouts\): [\d,]+/[\d,]+ steps", line) for line in status)
    assert any(re.search(r"training stop_ppo \(seed \d, layout \d+\): [\d,]+/[\d,]+ decisions", line)
               for line in status)
    text = out.read_text()
    assert "learning curves" in text and "stop-choosing PPO @" in text and "SAC @" in text
    with ResultStore(tmp_path / "s.sqlite", readonly=True) as store:
        recorded = {json.loads(json.dumps(r["config"]))["name"] for r in store.runs()}
    assert recorded == set(GROUPS["learning-curve"])


@pytest.mark.parametrize(("file", "built_in_name", "left_out"), [
    ("learning-curve-grid-ppo-dqn.toml", "learning-curve", {"stop_ppo"}),
    ("learning-curve-grid-stop-ppo.toml", "learning-curve", {"ppo", "dqn"}),
    ("learning-curve-harbour-stop-ppo.toml", "learning-curve-harbour", {"ppo", "sac"}),
    ("learning-curve-harbour-ppo.toml", "learning-curve-harbour", {"stop_ppo", "sac"}),
    ("learning-curve-harbour-sac.toml", "learning-curve-harbour", {"stop_ppo", "ppo"}),
    ("learning-curve-harbour-across-ppo.toml", "learning-curve-harbour-across", {"stop_ppo", "sac"}),
    ("learning-curve-harbour-across-sac.toml", "learning-curve-harbour-across", {"stop_ppo", "ppo"}),
])
def test_a_curve_file_is_the_built_in_curve_without_the_other_agents(file, built_in_name, left_out):
    """The curve files under benchmarks/ (the runs docs/results.md quotes) run their built-in
    curve's tasks of their agents and the planners, no other: the same keys, so a store of
    either serves the built-in."""
    from pathlib import Path

    path = Path(__file__).parents[3] / "benchmarks" / file
    subset = Experiment.from_toml(path)
    (built_in,) = [e for e in learning_curves() if e.name == built_in_name]
    ours = {t.key for t in subset.tasks()}
    theirs = {t.key: t.algorithm for t in built_in.tasks()}
    assert ours <= set(theirs)
    assert {a for k, a in theirs.items() if k not in ours} == left_out
    assert subset.budgets == {k: v for k, v in built_in.budgets.items() if k not in left_out}


def test_the_grid_tabular_curve_file_holds_the_standard_suites_tabular_and_planner_tasks():
    """benchmarks/learning-curve-grid-tabular.toml (the curve docs/results.md quotes for
    Q-learning and SARSA) runs, for its first training seed at the standard suite's 20,000
    episodes, the suite's very tasks of both learners and of its planners (so its row is a
    point of the curve), and otherwise only other seeds and other budgets of the same."""
    from pathlib import Path

    curve = Experiment.from_toml(Path(__file__).parents[3] / "benchmarks" / "learning-curve-grid-tabular.toml")
    tasks = {t.key: t for t in curve.tasks()}
    suite = {t.key: t for t in builtin_experiments()["compare"].tasks()}
    shared = tasks.keys() & suite.keys()
    names = ("q_learning", "sarsa", "kmeans_tsp", "rate_greedy", "milp")
    assert sorted(suite[k].algorithm for k in shared) == sorted(n for n in names for _ in range(6))
    assert {tasks[k].settings["train_episodes"] for k in shared if tasks[k].budget} == {20_000}
    assert {t.algorithm for t in tasks.values()} == set(names)
    for name in ("q_learning", "sarsa"):
        runs = [t for t in tasks.values() if t.algorithm == name]
        assert len(runs) == 6 * 3 * len(curve.budgets[name])  # 6 layouts, 3 seeds, every budget
        assert sorted({t.settings["train_episodes"] for t in runs}) == curve.budgets[name]
        assert 20_000 in curve.budgets[name]


_FLEET_LEARNERS = ("fleet_stop_ppo", "shared_ppo")


@pytest.mark.parametrize(("file", "built_in", "learners", "n_auvs"), [
    ("learning-curve-fleet-stop-ppo.toml", "fleet", ["fleet_stop_ppo"], 4),
    ("learning-curve-fleet-stop-ppo-two.toml", "fleet", ["fleet_stop_ppo"], 2),
    ("learning-curve-fleet-stop-ppo-one.toml", "fleet", ["fleet_stop_ppo"], 1),
    ("learning-curve-fleet-shared-ppo.toml", "fleet", ["shared_ppo"], 4),
    ("learning-curve-fleet-shared-ppo-two.toml", "fleet", ["shared_ppo"], 2),
    ("learning-curve-fleet-shared-ppo-one.toml", "fleet", ["shared_ppo"], 1),
    ("learning-curve-fleet-optimum-one.toml", "fleet-optimum", _FLEET_LEARNERS, 1),
    ("learning-curve-fleet-optimum-two.toml", "fleet-optimum", _FLEET_LEARNERS, 2),
    ("learning-curve-fleet-q-learning-one.toml", "fleet", ["fleet_q_learning"], 1),
    ("learning-curve-fleet-q-learning-two.toml", "fleet", ["fleet_q_learning"], 2),
    ("learning-curve-fleet-q-learning-four.toml", "fleet", ["fleet_q_learning"], 4),
    ("learning-curve-fleet-optimum-q-learning-one.toml", "fleet-optimum", ["fleet_q_learning"], 1),
    ("learning-curve-fleet-optimum-q-learning-two.toml", "fleet-optimum", ["fleet_q_learning"], 2),
])
def test_a_fleet_curve_file_holds_its_experiments_tasks(file, built_in, learners, n_auvs):
    """The fleet curve files under benchmarks/ (the curves docs/fleet.md quotes) run, at the
    budget of the fleet experiment they serve (the suite, or fleet-optimum beside the fleet
    MILP), that experiment's very tasks of their learners and planners with their number of
    AUVs (so one store serves both, and the experiment's row is a point of the curve), and at
    their other budgets only other trainings of the same learners."""
    from pathlib import Path

    curve = Experiment.from_toml(Path(__file__).parents[3] / "benchmarks" / file)
    tasks = {t.key: t for t in curve.tasks()}
    theirs = {t.key: t for t in builtin_experiments()[built_in].tasks()}
    shared = {k for k in tasks if k in theirs}
    planners = [name for name in curve.algorithms if name not in curve.budgets]
    assert sorted(curve.budgets) == sorted(learners)
    assert {(theirs[k].algorithm, theirs[k].point["n_auvs"]) for k in shared} == {
        (name, n_auvs) for name in (*planners, *learners)}
    assert len(shared) == 4 * (len(planners) + len(learners))  # 4 layouts, each algorithm once
    for name in learners:
        setting = curve.budget_setting(name)  # timesteps, or a tabular learner's train_episodes
        (budget,) = {theirs[k].settings[setting] for k in shared if theirs[k].algorithm == name}
        others = [t for k, t in tasks.items() if k not in shared and t.algorithm == name]
        assert sorted({t.settings[setting] for t in others}) == sorted(set(curve.budgets[name]) - {budget})
        assert len(others) == 4 * (len(curve.budgets[name]) - 1)
    assert {t.algorithm for k, t in tasks.items() if k not in shared} == set(learners)


_PPO_DQN_ROWS = {
    "PPO": "1,048,576: 16.04 ± 1.73 | yes | 131,072 | 0.75× [0.68–0.81] 0/6 (MILP)",
    "DQN": "1,048,576: 19.39 ± 1.17; 2,097,152: 18.80 ± 1.93 | yes | 524,288 | 0.88× [0.79–0.95] 0/6 (MILP)",
}
_STOP_ROWS = {"stop-choosing PPO": "262,144: 19.82 ± 0.98 | yes | 32,768 | 0.93× [0.92–0.95] 0/6 (MILP)"}
_HARBOUR_PPO_ROWS = {
    "PPO": "1,048,576: 9.21 ± 1.10; 2,097,152: 9.82 ± 1.15 | yes | 1,048,576 | 0.26× [0.21–0.32] 0/6 (OMPL tour)"}
_HARBOUR_SAC_ROWS = {
    "SAC": "1,048,576: 12.17 ± 1.50; 2,097,152: 15.57 ± 1.36 | no | 2,097,152 | 0.42× [0.39–0.46] 0/6 (OMPL tour)"}
_HARBOUR_ACROSS_PPO_ROWS = {
    "PPO": "4,194,304: 8.29 ± 0.87; 8,388,608: 8.78 ± 1.02 | yes | 4,194,304 | 0.24× [0.21–0.26] 0/8 (OMPL tour)"}
_HARBOUR_ACROSS_SAC_ROWS = {
    "SAC": "4,194,304: 11.84 ± 1.47; 8,388,608: 12.80 ± 1.54 | yes | 4,194,304 | 0.35× [0.32–0.37] 0/8 (OMPL tour)"}
_FLEET_STOP_ROWS = {"stop-choosing PPO (fleet)": "262,144: 72.53 ± 6.56; 524,288: 71.38 ± 6.56 | yes | 131,072 | "
                                                 "0.86× [0.84–0.89] 0/4 (k-means + vehicle routing)"}
_FLEET_TWO_ROWS = {"stop-choosing PPO (fleet)": "131,072: 47.66 ± 1.72; 262,144: 48.06 ± 1.65 | yes | 131,072 | "
                                                "0.98× [0.90–1.05] 1/4 (k-means + vehicle routing)"}
_FLEET_ONE_ROWS = {"stop-choosing PPO (fleet)": "131,072: 30.79 ± 2.75; 262,144: 31.48 ± 3.88 | yes | 65,536 | "
                                                "1.20× [1.12–1.27] 4/4 (k-means + vehicle routing)"}
_FLEET_SHARED_ROWS = {"parameter-shared PPO": "2,097,152: 50.65 ± 11.05; 4,194,304: 55.70 ± 11.26 | yes | 2,097,152 | "
                                             "0.67× [0.61–0.72] 0/4 (k-means + vehicle routing)"}
_FLEET_SHARED_TWO_ROWS = {
    "parameter-shared PPO": "2,097,152: 38.85 ± 9.54; 4,194,304: 41.01 ± 7.16 | yes | 1,048,576 | "
                            "0.83× [0.75–0.92] 0/4 (k-means + vehicle routing)"}
_FLEET_SHARED_ONE_ROWS = {
    "parameter-shared PPO": "1,048,576: 23.60 ± 5.96; 2,097,152: 26.53 ± 7.29 | yes | 524,288 | "
                            "1.01× [0.88–1.13] 3/4 (k-means + vehicle routing)"}
_FLEET_OPTIMUM_ONE_ROWS = {
    "stop-choosing PPO (fleet)": "131,072: 9.85 ± 2.87; 262,144: 9.86 ± 2.76 | yes | 32,768 | "
                                 "0.89× [0.83–0.92] 0/4 (MILP (fleet))",
    "parameter-shared PPO": "524,288: 8.24 ± 2.58; 1,048,576: 8.15 ± 2.56 | yes | 262,144 | "
                            "0.74× [0.64–0.84] 0/4 (MILP (fleet))"}
_FLEET_OPTIMUM_TWO_ROWS = {
    "stop-choosing PPO (fleet)": "131,072: 14.92 ± 3.05; 262,144: 14.92 ± 3.05 | yes | 32,768 | "
                                 "0.95× [0.91–0.99] 1/4 (MILP (fleet))",
    "parameter-shared PPO": "524,288: 11.73 ± 3.11; 1,048,576: 11.68 ± 3.03 | yes | 262,144 | "
                            "0.75× [0.59–0.87] 0/4 (MILP (fleet))"}
_FLEET_Q_ONE_ROWS = {
    "independent Q-learning": "40,000: 14.76 ± 3.58 | yes | 20,000 | 0.56× [0.48–0.65] 0/4 (k-means + vehicle routing)"}
_FLEET_Q_TWO_ROWS = {
    "independent Q-learning": "40,000: 28.97 ± 9.65 | yes | 20,000 | 0.59× [0.50–0.70] 0/4 (k-means + vehicle routing)"}
_FLEET_Q_FOUR_ROWS = {
    "independent Q-learning": "40,000: 49.63 ± 9.34 | yes | 20,000 | 0.60× [0.56–0.62] 0/4 (k-means + vehicle routing)"}
_FLEET_OPTIMUM_Q_ONE_ROWS = {
    "independent Q-learning": "20,000: 6.19 ± 2.63; 40,000: 5.69 ± 4.07 | yes | 10,000 | 0.51× [0.31–0.61] 0/4 "
                              "(MILP (fleet))"}
_FLEET_OPTIMUM_Q_TWO_ROWS = {
    "independent Q-learning": "20,000: 7.78 ± 5.75; 40,000: 8.50 ± 7.92 | yes | 10,000 | 0.54× [0.31–0.73] 0/4 "
                              "(MILP (fleet))"}
_GRID_TABULAR_ROWS = {
    "Q-learning": "80,000: 12.79 ± 0.95; 160,000: 12.71 ± 1.64 | yes | 20,000 | 0.60× [0.55–0.65] 0/6 (MILP)",
    "SARSA": "80,000: 8.64 ± 1.21; 160,000: 9.03 ± 1.21 | yes | 5,000 | 0.42× [0.35–0.49] 0/6 (MILP)"}
_HARBOUR_STOP_ROWS = {
    "stop-choosing PPO": "262,144: 37.27 ± 1.58 | yes | 32,768 | 1.00× [1.00–1.00] 0/6 (OMPL tour)"}
#: The built-in curves across layouts (both in benchmarks/stores/learning-curve-across.sqlite):
#: the budgets ``compare`` trains at come from them.
_ACROSS_ROWS = {
    "PPO": "1,048,576: 15.32 ± 1.29; 2,097,152: 15.47 ± 1.29 | yes | 524,288 | 0.73× [0.69–0.77] 0/6 (MILP)",
    "DQN": "2,097,152: 18.70 ± 1.20; 4,194,304: 18.01 ± 1.72 | yes | 524,288 | 0.85× [0.79–0.91] 0/6 (MILP)",
    "stop-choosing PPO": "262,144: 19.11 ± 1.11; 524,288: 19.14 ± 1.35 | yes | 65,536 | 0.90× [0.86–0.93] 0/6 (MILP)"}
_HARBOUR_ACROSS_ROWS = {
    "PPO": _HARBOUR_ACROSS_PPO_ROWS["PPO"], "SAC": _HARBOUR_ACROSS_SAC_ROWS["SAC"],
    "stop-choosing PPO": "262,144: 35.70 ± 1.60; 524,288: 36.32 ± 1.73 | yes | 131,072 | "
                         "0.98× [0.97–0.99] 0/8 (OMPL tour)"}
#: The store of each experiment whose store is not named after it.
_STORE_OF = {"learning-curve-across": "learning-curve-across", "learning-curve-harbour-across": "learning-curve-across"}
#: Experiment files whose rows the docs quote as the built-in's (the same tasks, whose
#: results were copied into the built-in's store): their rows, renamed, are the built-in's.
_QUOTED_AS = {"learning-curve-harbour-across-ppo": "learning-curve-harbour-across",
              "learning-curve-harbour-across-sac": "learning-curve-harbour-across"}


@pytest.mark.parametrize(("name", "expected"), [("learning-curve-across", _ACROSS_ROWS),
                                                ("learning-curve-harbour-across", _HARBOUR_ACROSS_ROWS),
                                                ("learning-curve-grid-ppo-dqn", _PPO_DQN_ROWS),
                                                ("learning-curve-grid-stop-ppo", _STOP_ROWS),
                                                ("learning-curve-grid-tabular", _GRID_TABULAR_ROWS),
                                                ("learning-curve-harbour-stop-ppo", _HARBOUR_STOP_ROWS),
                                                ("learning-curve-harbour-ppo", _HARBOUR_PPO_ROWS),
                                                ("learning-curve-harbour-sac", _HARBOUR_SAC_ROWS),
                                                ("learning-curve-harbour-across-ppo", _HARBOUR_ACROSS_PPO_ROWS),
                                                ("learning-curve-harbour-across-sac", _HARBOUR_ACROSS_SAC_ROWS),
                                                ("learning-curve-fleet-stop-ppo", _FLEET_STOP_ROWS),
                                                ("learning-curve-fleet-stop-ppo-two", _FLEET_TWO_ROWS),
                                                ("learning-curve-fleet-stop-ppo-one", _FLEET_ONE_ROWS),
                                                ("learning-curve-fleet-shared-ppo", _FLEET_SHARED_ROWS),
                                                ("learning-curve-fleet-shared-ppo-two", _FLEET_SHARED_TWO_ROWS),
                                                ("learning-curve-fleet-shared-ppo-one", _FLEET_SHARED_ONE_ROWS),
                                                ("learning-curve-fleet-optimum-one", _FLEET_OPTIMUM_ONE_ROWS),
                                                ("learning-curve-fleet-optimum-two", _FLEET_OPTIMUM_TWO_ROWS),
                                                ("learning-curve-fleet-q-learning-one", _FLEET_Q_ONE_ROWS),
                                                ("learning-curve-fleet-q-learning-two", _FLEET_Q_TWO_ROWS),
                                                ("learning-curve-fleet-q-learning-four", _FLEET_Q_FOUR_ROWS),
                                                ("learning-curve-fleet-optimum-q-learning-one",
                                                 _FLEET_OPTIMUM_Q_ONE_ROWS),
                                                ("learning-curve-fleet-optimum-q-learning-two",
                                                 _FLEET_OPTIMUM_Q_TWO_ROWS)])
def test_a_stored_curve_run_prints_the_curve_docs_quote(tmp_path, name, expected):
    """benchmarks/stores/NAME.sqlite (or the store :data:`_STORE_OF` names) is the store of
    the run that docs/results.md (the fleet's: docs/fleet.md) and the README quote: its
    table, printed from the stored data alone, carries their numbers (a page that misquotes
    the run fails here; a run the docs quote under the built-in's name, :data:`_QUOTED_AS`,
    has the built-in's rows there)."""
    from pathlib import Path

    root = Path(__file__).parents[3]
    out = tmp_path / "curve.md"
    assert main(["table", str(root / "benchmarks" / "stores" / f"{_STORE_OF.get(name, name)}.sqlite"),
                 "--experiment", name, "--format", "markdown", "--output", str(out)]) == 0
    rows = {line.split(" | ")[1]: line for line in out.read_text().splitlines() if line.startswith(f"| {name} |")}
    docs = (root / "docs" / ("fleet.md" if "fleet" in name else "results.md")).read_text()
    assert set(rows) == set(expected)
    for algorithm, fragment in expected.items():
        assert rows[algorithm].replace(f"| {name} |", f"| {_QUOTED_AS.get(name, name)} |") in docs
        assert fragment in rows[algorithm]


@pytest.mark.parametrize(("suite", "name"), [("compare", "learning-curve-across"),
                                             ("harbour", "learning-curve-harbour-across")])
def test_the_suites_train_deep_rl_where_its_shipped_curve_is_flat(suite, name):
    """Each suite's deep-RL contenders are the tasks of the last budget of their curve across
    the suite's layouts (the same models), and the shipped store of that curve holds every
    budget of it, flat at its end: a budget moved in ``ACROSS_BUDGETS`` without running the
    curve to it, or a curve still rising where the suite trains, fails here."""
    from pathlib import Path

    experiments = builtin_experiments()
    curve, suite_tasks = experiments[name], experiments[suite].tasks()
    assert set(curve.budgets) == {t.algorithm for t in suite_tasks if "timesteps" in t.settings}
    learners = {t.key for t in suite_tasks if t.algorithm in curve.budgets}
    last = {t.key for t in curve.tasks() if t.algorithm in curve.budgets and t.budget == curve.budgets[t.algorithm][-1]}
    assert learners == last and len(learners) == 3 * len(curve.budgets) * curve.layouts
    store = Path(__file__).parents[3] / "benchmarks" / "stores" / f"{_STORE_OF[name]}.sqlite"
    with ResultStore(store, readonly=True) as s:
        rows = tables.curve_rows(curve, s)
    assert {r.algorithm for r in rows} == set(curve.budgets)
    for r in rows:
        assert all(r.complete) and r.flat, (r.algorithm, r.returns[-2:])


def test_the_per_layout_sac_curve_going_on_keeps_the_shipped_results():
    """benchmarks/stores/in-progress/ holds the per-layout SAC curve going on to 4,194,304
    steps on a copy of the shipped store, each lineage from the state its 2,097,152-step
    training kept (``--keep-state``). The longer file is the shipped one with one more budget
    (the same tasks and 18 more); its store holds only its tasks, no failure, and every
    result of the shipped store, unchanged episode for episode, and the shipped store is
    whole: a longer run on a store that lost or changed a shipped result, or on another
    experiment, fails here."""
    from pathlib import Path

    root = Path(__file__).parents[3] / "benchmarks"
    shipped = {t.key: t for t in Experiment.from_toml(root / "learning-curve-harbour-sac.toml").tasks()}
    longer = {t.key: t for t in Experiment.from_toml(root / "stores" / "in-progress" /
                                                      "learning-curve-harbour-sac.toml").tasks()}
    added = {k: t for k, t in longer.items() if k not in shipped}
    assert set(shipped) < set(longer) and len(added) == 18
    assert {t.budget for t in added.values()} == {4_194_304}
    with ResultStore(root / "stores" / "in-progress" / "learning-curve-harbour-sac.sqlite", readonly=True) as s:
        going_on = s.get(s.keys())
        assert not s.failures()
    with ResultStore(root / "stores" / "learning-curve-harbour-sac.sqlite", readonly=True) as s:
        before = s.get(s.keys())
    assert set(before) == set(shipped) and set(before) <= set(going_on) <= set(longer)
    for key, result in before.items():
        assert going_on[key]["records"] == result["records"], shipped[key].row


def test_each_algorithm_has_one_colour_in_every_learning_curve_panel():
    """PPO is drawn in one colour on the grid's panel, the harbour's and the fleet's (its
    fleet counterpart too), the planners beside the learners in others, and an algorithm
    whose colour is taken or missing gets one no other in its panel has."""
    from swiptopt.benchmark.plots import _curve_colours

    grid = _curve_colours(["ppo", "dqn", "stop_ppo", "kmeans_tsp", "rate_greedy", "milp"])
    harbour = _curve_colours(["ppo", "sac", "stop_ppo", "ompl_tour", "straight_line"])
    fleet = _curve_colours(["shared_ppo", "fleet_stop_ppo", "fleet_routing"])
    assert grid["ppo"] == harbour["ppo"] == fleet["shared_ppo"]
    assert grid["stop_ppo"] == harbour["stop_ppo"] == fleet["fleet_stop_ppo"]
    for panel in (grid, harbour, fleet):
        assert len(set(panel.values())) == len(panel)
    crowded = _curve_colours(["ppo", "rate_greedy", "straight_line", "greedy", "lawnmower"])
    assert len(set(crowded.values())) == 5 and crowded["straight_line"] not in (crowded["rate_greedy"], "C8")
    assert crowded["straight_line"] == "C1" and crowded["greedy"] == "C2"  # the first colours left, in order
