"""The fleet in the benchmark: fleet algorithms run in the fleet env, a fleet of one
reproduces the single AUV's rows, single-AUV algorithms refuse a fleet before any task runs,
and the fleet suite runs in --quick with the same table twice."""

from __future__ import annotations

import pytest

pytest.importorskip("pettingzoo")

from swiptopt import ConfigError  # noqa: E402
from swiptopt.benchmark import tables  # noqa: E402
from swiptopt.benchmark.experiment import Experiment, builtin_experiments  # noqa: E402
from swiptopt.benchmark.runner import execute, run_task  # noqa: E402
from swiptopt.benchmark.store import ResultStore  # noqa: E402

SMALL = {"preset": "paper", "n_nodes": 8, "episode_steps": 30}


def _task(algorithm: str, scenario: dict, settings: dict | None = None) -> dict:
    exp = Experiment(name="t", scenario=scenario, algorithms={algorithm: settings or {}}, layouts=1, episodes=3)
    (task,) = exp.tasks()
    return run_task(task.to_dict())


def _metrics(records: list[dict]) -> list[dict]:
    single = ("return", "data_bits", "energy_delivered_j", "auv_energy_j", "nodes_served", "length")
    return [{k: r[k] for k in single} for r in records]


@pytest.mark.parametrize(("single", "fleet", "settings"), [
    ("random", "fleet_random", {}),
    ("q_learning", "fleet_q_learning", {"train_episodes": 200}),
])
def test_a_fleet_of_one_reproduces_the_single_auvs_rows(single, fleet, settings):
    # the same agent, seeded alike, in the fleet env of one AUV and in the single AUV's env:
    # the same episodes (the compiled trainer and the fleet's Python loop draw alike)
    one = _task(single, SMALL, settings)
    many = _task(fleet, {**SMALL, "n_auvs": 1}, settings)
    assert _metrics(one["records"]) == _metrics(many["records"])
    assert [r["return_each"] for r in many["records"]] == [[r["return"]] for r in one["records"]]


def test_n_auvs_one_keeps_every_single_auv_task_as_it_was():
    compare = builtin_experiments()["compare"]
    explicit = Experiment(**{**compare.to_dict(), "scenario": {**compare.scenario, "n_auvs": 1}})
    assert [t.key for t in explicit.tasks()] == [t.key for t in compare.tasks()]


def test_a_single_auv_algorithm_refuses_a_fleet_before_any_task_runs():
    with pytest.raises(ConfigError, match="runs one AUV, and the scenario has n_auvs = 2") as err:
        Experiment(name="t", scenario={**SMALL, "n_auvs": 2}, algorithms={"kmeans_tsp": {}})
    assert err.value.field == "n_auvs"
    with pytest.raises(ConfigError, match="at sweep point"):
        Experiment(name="t", scenario=SMALL, sweep={"n_auvs": [1, 2]}, algorithms={"q_learning": {}})


def test_the_fleet_suite_runs_quick_and_gives_the_same_table_twice(tmp_path):
    suite = builtin_experiments()["fleet"].quick()
    small = {**suite.to_dict(), "scenario": {**suite.scenario, "n_nodes": 12, "episode_steps": 40}, "layouts": 1}
    small["algorithms"] = {**small["algorithms"], "fleet_q_learning": {"train_episodes": 200}}
    suite = Experiment(**small)
    texts = []
    for name in ("a", "b"):
        with ResultStore(tmp_path / f"{name}.sqlite") as store:
            report = execute(suite, store, workers=1)
            assert report.failures == ()
            rows, _ = tables.aggregate(suite, store)
            texts.append(tables.to_markdown(rows))
            results = store.get(t.key for t in suite.tasks())
    assert texts[0] == texts[1]
    lines = texts[0].splitlines()
    assert "| makespan (s) | Jain AUV energy |" in lines[0]
    labels = ("k-means + vehicle routing", "stop-choosing PPO (fleet)", "parameter-shared PPO",
              "independent Q-learning", "random (each AUV)")
    for label in labels:
        assert sum(f"| {label} |" in line for line in lines) == 2  # at n_auvs = 1 and 2
    # every AUV of a fleet of two has its own numbers, and they add up to the fleet's
    twos = [r for r in results.values() if r["task"]["scenario"].get("n_auvs") == 2]
    assert twos and all(len(rec["return_each"]) == 2 for r in twos for rec in r["records"])
    assert all(abs(sum(rec["data_bits_each"]) - rec["data_bits"]) <= 1e-6 * max(1.0, rec["data_bits"])
               for r in twos for rec in r["records"])


@pytest.mark.parametrize(("algorithm", "budgets"), [
    ("fleet_stop_ppo", [64, 128]),  # a rollout: 32 decisions of 2 copies
    ("shared_ppo", [128, 256]),  # a rollout: 32 steps of 2 AUVs of 2 copies
])
def test_a_fleet_curve_trains_once_and_its_checkpoint_plays_like_the_run_of_its_length(tmp_path, algorithm,
                                                                                        budgets):
    """The fleet's stop-choosing PPO and parameter-shared PPO keep their models as the single
    agents do: a learning curve trains one run per lineage, and the shorter budget's row,
    from that run's checkpoint, is the row of a run of that length alone."""
    tiny = {"n_steps": 32, "batch_size": 32, "net_arch": [16], "n_envs": 2, "n_epochs": 1}

    def fleet_curve(budgets: list[int]) -> Experiment:
        return Experiment(name="c", scenario={**SMALL, "n_auvs": 2}, algorithms={algorithm: tiny},
                          budgets={algorithm: budgets}, layouts=1, episodes=2)

    both, alone = fleet_curve(budgets), fleet_curve(budgets[:1])
    trained = []
    with ResultStore(tmp_path / "a" / "s.sqlite") as store:
        assert execute(both, store, workers=1,
                       on_training=lambda task, steps, total, done: trained.append((task.budget, total))).failures == ()
        a = store.get(t.key for t in both.tasks())
    assert {total for _, total in trained} == {budgets[-1]}  # one training, the lineage's longest
    with ResultStore(tmp_path / "b" / "s.sqlite") as store:
        execute(alone, store, workers=1)
        b = store.get(t.key for t in alone.tasks())
    (short,) = b
    assert a[short]["records"] == b[short]["records"]
    assert a[short]["extra"]["model_loaded"] and not b[short]["extra"]["model_loaded"]
    longer = [r for k, r in a.items() if k != short]
    assert len(longer) == 1 and not longer[0]["extra"]["model_loaded"]
    assert longer[0]["records"] != a[short]["records"]  # the two budgets are two models


def _printed_rows(text: str) -> tuple[dict, dict]:
    """The rows of ``swiptopt table --format markdown``'s two tables (the metrics', and the
    ratios to the baseline), by (AUVs, algorithm) and column."""
    tables_, header = ({}, {}), None
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells[:2] == ["point", "algorithm"]:
            header, which = cells, 0 if "rank" in cells else 1
        elif header and cells[0].startswith("n_auvs="):
            tables_[which][(cells[0].removeprefix("n_auvs="), cells[1])] = dict(zip(header, cells))
    return tables_


def _to_routing(results: dict) -> dict:
    """Each learner's paired ratio of return to routing's on the same layouts, as the suite's
    table on the page gives it: the mean over layouts, then the lowest and highest layout's,
    by (AUVs, label)."""
    import numpy as np

    from swiptopt.benchmark.algorithms import labels

    means: dict = {}
    for r in results.values():
        task = r["task"]
        key = (str(task["point"]["n_auvs"]), task["algorithm"])
        means.setdefault(key, {})[task["scenario"]["layout_seed"]] = np.mean([x["return"] for x in r["records"]])
    out = {}
    for (auvs, algorithm), by_layout in means.items():
        routing = means[(auvs, "fleet_routing")]
        q = np.array([by_layout[layout] / routing[layout] for layout in sorted(routing)])
        out[(auvs, labels()[algorithm])] = f"{q.mean():.2f}× [{q.min():.2f}–{q.max():.2f}]"
    return out


def _suite_columns(cells, printed, ratios, to_routing):
    auvs, algorithm, ret, ratio, data, energy, makespan = cells
    row = printed[(auvs, algorithm)]
    # routing is the unit; random moves have no ratio on the page
    expected = {"k-means + vehicle routing": "1", "random (each AUV)": ""}.get(algorithm, to_routing[(auvs, algorithm)])
    return (ret, ratio, data, energy, makespan), (row["return"], expected, row["data (kbit)"], row["energy (mJ)"],
                                                  row["makespan (s)"])


def _yardstick_columns(cells, printed, ratios, to_routing):
    auvs, algorithm, ret, gap, ratio = cells
    row = printed[(auvs, algorithm)]
    to_milp = "1" if algorithm == "MILP (fleet)" else ratios[(auvs, algorithm)]["return"].rsplit(" ", 1)[0]
    return (ret, gap, ratio), (row["return"], row["gap to bound"].split(" [")[0], to_milp)


@pytest.mark.parametrize(("experiment", "store", "section", "rows", "columns"), [
    ("fleet", "fleet.sqlite", ("## The fleet suite", "### The stop-choosing PPO trained to its plateau"), 15,
     _suite_columns),
    ("fleet-optimum", "fleet-optimum.sqlite", ("`swiptopt run fleet-optimum` is the fleet's yardstick",
                                               "## The fleet suite"), 12, _yardstick_columns),
])
def test_a_stored_fleet_run_is_its_experiment_and_prints_the_rows_docs_quote(tmp_path, experiment, store, section,
                                                                              rows, columns):
    """benchmarks/stores/ holds the runs of ``swiptopt run fleet`` and ``swiptopt run
    fleet-optimum`` whose tables docs/fleet.md quotes: each store's tasks are its experiment's
    as built today, and every number of every row on the page is the one its table prints from
    the stored data alone (the suite's ratios to routing, which the table does not print, the
    ones its records give) (a page that misquotes the run, or an experiment changed without a
    new run, fails here)."""
    from pathlib import Path

    from swiptopt.cli import main

    root = Path(__file__).parents[3]
    path = root / "benchmarks" / "stores" / store
    with ResultStore(path, create=False, readonly=True) as stored:
        assert stored.keys() == {t.key for t in builtin_experiments()[experiment].tasks()}
        to_routing = _to_routing(stored.get(stored.keys()))
    out = tmp_path / "table.md"
    assert main(["table", str(path), "--experiment", experiment, "--format", "markdown", "--output", str(out)]) == 0
    printed, ratios = _printed_rows(out.read_text())
    page = (root / "docs" / "fleet.md").read_text()
    start = page.index(section[0])
    text = page[start:page.index(section[1], start)]
    quoted = [line for line in text.splitlines() if line.startswith(("| 1 |", "| 2 |", "| 4 |"))]
    assert len(quoted) == rows == len(printed)
    for line in quoted:
        on_page, from_store = columns([c.strip() for c in line.strip().strip("|").split("|")], printed, ratios,
                                      to_routing)
        assert on_page == from_store, line
