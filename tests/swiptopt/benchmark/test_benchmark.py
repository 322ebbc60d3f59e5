import os
import signal
import sqlite3
import subprocess
import sys
import time

import numpy as np
import pytest

from swiptopt.benchmark import tables
from swiptopt.benchmark.experiment import Experiment, builtin_experiments, load_experiment
from swiptopt.benchmark.runner import execute
from swiptopt.benchmark.store import ResultStore
from swiptopt.cli import main
from swiptopt.errors import ConfigError

QUICK_TOML = """
name = "smoke"
layouts = 2
episodes = 2

[scenario]
preset = "paper"
n_nodes = 12

[sweep]
n_nodes = [8, 12]

[algorithms.q_learning]
train_episodes = 300
[algorithms.random]
[algorithms.greedy]

[figure]
metric = "data_bits"
"""


def write(tmp_path, text, name="exp.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def cli(*args, env_extra=None):
    env = dict(os.environ, **(env_extra or {}))
    return subprocess.run([sys.executable, "-m", "swiptopt.cli", *args], capture_output=True, text=True, env=env)


def test_experiment_expansion_and_keys(tmp_path):
    exp = Experiment.from_toml(write(tmp_path, QUICK_TOML))
    tasks = exp.tasks()
    assert len(tasks) == 2 * 2 * 3  # sweep points x layouts x algorithms
    assert len({t.key for t in tasks}) == len(tasks)
    again = Experiment.from_toml(write(tmp_path, QUICK_TOML.replace('"smoke"', '"renamed"'), "b.toml"))
    assert [t.key for t in again.tasks()] == [t.key for t in tasks]  # the name is not part of the key
    changed = Experiment.from_toml(write(tmp_path, QUICK_TOML.replace("train_episodes = 300", "train_episodes = 301"),
                                         "c.toml"))
    assert [t.key for t in changed.tasks()] != [t.key for t in tasks]
    # every figure experiment of the paper has at least 20 layouts per point
    for name, e in builtin_experiments().items():
        if e.figure:
            assert e.layouts >= 20, name


@pytest.mark.parametrize(
    "text, words",
    [
        ("name = 'x'\n[algorithms.q_learning\n", ["malformed TOML"]),
        ("name = 'x'\n[algorithms.dqm]\n", ["unknown algorithm 'dqm'", "did you mean 'dqn'"]),
        ("name = 'x'\nlayout = 3\n[algorithms.random]\n", ["unknown experiment key 'layout'"]),
        ("name = 'x'\n[scenario]\nn_node = 3\n[algorithms.random]\n", ["n_node"]),
        ("name = 'x'\n[scenario]\nsplit_ratio = 2.0\n[algorithms.random]\n", ["split_ratio", "2.0"]),
        ("name = 'x'\nepisodes = 0\n[algorithms.random]\n", ["episodes"]),
        ("name = 'x'\n[algorithms.q_learning]\nlearning_rate = 3\n", ["learning_rate"]),
        ("name = 'x'\n[algorithms.greedy]\nspeed = 3\n", ["unknown setting 'speed'"]),
        ("name = 'x'\n[sweep]\nn_nodes = [10, -1]\n[algorithms.random]\n", ["n_nodes", "-1"]),
        ("name = 'x'\nbaseline = 'greedy'\n[algorithms.random]\n", ["baseline = 'greedy'", "random"]),
    ],
)
def test_bad_experiments_exit_2_with_one_line(tmp_path, text, words):
    path = write(tmp_path, text)
    with pytest.raises(ConfigError):
        Experiment.from_toml(path)
    result = cli("run", str(path), "--store", str(tmp_path / "s.sqlite"))
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr
    for word in words:
        assert word in lines[0]


def test_unknown_experiment_name_and_missing_store(tmp_path):
    assert cli("run", "no-such-experiment").returncode == 2
    result = cli("table", str(tmp_path / "absent.sqlite"))
    assert result.returncode == 2 and "no results store" in result.stderr


def test_quick_sweep_end_to_end(tmp_path, capsys):
    exp_path = write(tmp_path, QUICK_TOML)
    store = tmp_path / "r.sqlite"
    assert main(["run", str(exp_path), "--store", str(store), "--workers", "2", "--format", "csv"]) == 0
    out = capsys.readouterr().out
    assert "q_learning" in out and "greedy" in out and "data_bits" in out
    with ResultStore(store) as s:
        assert s.count() == 12
        rows, missing = tables.aggregate(Experiment.from_toml(exp_path), s)
        assert missing == 0 and len(rows) == 2 * 3
        for r in rows:
            assert r.summaries["data_bits"].n == 2
            assert r.summaries["gap_to_bound"].max <= 1.0
            assert r.summaries["gap_to_bound"].min >= 0.0  # no task beat the upper bound
        assert s.runs()[0]["provenance"]["versions"]["numpy"]
    # a rerun finds everything stored and runs nothing
    assert main(["run", str(exp_path), "--store", str(store), "--format", "markdown"]) == 0
    assert "| algorithm |" in capsys.readouterr().out.replace("| point | algorithm |", "| algorithm |")
    with ResultStore(store) as s:
        assert s.count() == 12
    # table and plot read the store
    assert main(["table", str(store), "--format", "latex"]) == 0
    assert r"\begin{tabular}" in capsys.readouterr().out
    assert main(["plot", str(store), "--outdir", str(tmp_path / "fig")]) == 0
    assert (tmp_path / "fig" / "smoke.png").stat().st_size > 1000
    assert (tmp_path / "fig" / "smoke.pdf").exists() and (tmp_path / "fig" / "smoke.csv").exists()


def test_killed_run_resumes_without_duplicates(tmp_path):
    exp_path = write(tmp_path, QUICK_TOML.replace("train_episodes = 300", "train_episodes = 200")
                     .replace("layouts = 2", "layouts = 8"))
    store = tmp_path / "kill.sqlite"
    expected = {t.key for t in Experiment.from_toml(exp_path).tasks()}
    proc = subprocess.Popen([sys.executable, "-m", "swiptopt.cli", "run", str(exp_path), "--store", str(store),
                             "--workers", "1"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + 120  # a wait limit for the polling loop, not a speed check
    stored = 0
    while time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
        if store.exists():
            try:
                with sqlite3.connect(store, timeout=1) as db:
                    stored = db.execute("SELECT COUNT(*) FROM results").fetchone()[0]
            except sqlite3.OperationalError:
                continue
            if stored >= 3:
                break
    assert proc.poll() is None, "the run finished before it could be killed"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    with ResultStore(store) as s:
        partial = s.count()
    assert 3 <= partial < len(expected)
    assert main(["run", str(exp_path), "--store", str(store), "--format", "csv"]) == 0
    with sqlite3.connect(store) as db:
        keys = [k for (k,) in db.execute("SELECT key FROM results")]
    assert len(keys) == len(set(keys)) == len(expected)
    assert set(keys) == expected


def test_dask_local_cluster_gives_the_same_table(tmp_path):
    exp = Experiment.from_toml(write(tmp_path, QUICK_TOML)).quick()
    with ResultStore(tmp_path / "local.sqlite") as a, ResultStore(tmp_path / "dask.sqlite") as b:
        execute(exp, a, workers=1)
        execute(exp, b, scheduler="local:2")
        assert tables.to_csv(tables.aggregate(exp, a)[0]) == tables.to_csv(tables.aggregate(exp, b)[0])


def test_builtin_lookup():
    assert load_experiment("compare").name == "compare"
    builtins = builtin_experiments()
    planners_and_agents = {"q_learning", "sarsa", "random", "kmeans_tsp", "lawnmower", "greedy", "rate_greedy"}
    assert set(builtins["compare"].algorithms) == planners_and_agents | {"milp", "ppo", "dqn", "stop_ppo"}
    assert builtins["compare"].algorithms["milp"] == {"budget": "compare"}
    optimum = builtins["optimum"]
    assert set(optimum.algorithms) == planners_and_agents | {"milp"}
    assert optimum.algorithms["milp"] == {"budget": "default"} and optimum.layouts == 10
    scenario = optimum.scenario
    assert (scenario["n_nodes"], scenario["channel"], scenario["failure_prob_max"]) == (25, "none", 0)
    # the figures' sweeps run every algorithm but the MILP
    for e in builtins.values():
        if e.figure:
            assert set(e.algorithms) == planners_and_agents, e.name
    # --quick shrinks the MILP to its quick budget and the training and solver limits
    quick = optimum.quick()
    assert quick.algorithms["milp"] == {"budget": "quick"}
    assert quick.algorithms["q_learning"] == {"train_episodes": 2000}
    # the TSP's time limit is only a safety net: shortening it would make results machine-dependent
    assert quick.algorithms["kmeans_tsp"] == {"ompl_time_limit_s": 0.05}


def test_ratio_of_means_and_its_interval():
    rng = np.random.default_rng(0)
    exact = tables.Ratio.of(np.array([2.0, 4.0, 6.0]), np.array([1.0, 2.0, 3.0]), rng)
    assert (exact.ratio, exact.low, exact.high, exact.wins, exact.n) == (2.0, 2.0, 2.0, 3, 3)
    mixed = tables.Ratio.of(np.array([1.0, 3.0, 5.0, 1.0]), np.array([2.0, 2.0, 2.0, 2.0]), rng)
    assert mixed.ratio == 1.25 and mixed.wins == 2
    assert 0.5 <= mixed.low < 1.25 < mixed.high <= 2.0  # resampled sums stay within [1, 5] / 2
    assert np.isnan(tables.Ratio.of(np.array([1.0]), np.array([0.0]), rng).ratio)
    single = tables.Ratio.of(np.array([3.0]), np.array([2.0]), rng)
    assert single.ratio == 1.5 and np.isnan(single.low)


def test_paired_table_against_the_baseline(tmp_path, capsys):
    exp_path = write(tmp_path, 'baseline = "random"\n' + QUICK_TOML)
    exp = Experiment.from_toml(exp_path)
    store = tmp_path / "p.sqlite"
    assert main(["run", str(exp_path), "--store", str(store), "--format", "markdown"]) == 0
    out = capsys.readouterr().out
    assert "mean / mean of random" not in out  # titles go to the terminal table only
    assert "| point | algorithm | return | data |" in out and "×" in out
    with ResultStore(store) as s:
        rows, _ = tables.aggregate(exp, s)
        pairs = tables.paired(exp, s)
        assert tables.paired(exp, s) == pairs  # the bootstrap is seeded
    assert {(str(p.point), p.algorithm) for p in pairs} == {
        (str(r.point), r.algorithm) for r in rows if r.algorithm != "random"
    }
    means = {(str(r.point), r.algorithm): r.summaries for r in rows}
    for p in pairs:
        for metric in ("data_bits", "mobility_efficiency_bit_per_j"):
            q = p.ratios[metric]
            # every task has its baseline twin, so the ratio of means is the table's ratio
            expected = means[(str(p.point), p.algorithm)][metric].mean / means[(str(p.point), "random")][metric].mean
            assert q.ratio == pytest.approx(expected, rel=1e-12)
            assert q.n == 2 and 0 <= q.wins <= 2
            assert q.low <= q.ratio * (1 + 1e-12) and q.ratio <= q.high * (1 + 1e-12)
    assert main(["table", str(store), "--format", "csv"]) == 0
    assert "algorithm,metric,ratio,ci95_low,ci95_high,wins,n" in capsys.readouterr().out.replace("n_nodes,", "")


def test_paper_figures_use_the_papers_reward_extremes_and_either_link():
    from swiptopt.benchmark.experiment import paper_figures

    builtins = builtin_experiments()
    default = paper_figures()
    assert all(builtins[e.name] == e for e in default)  # the built-ins are these
    by_name = {e.name: e for e in default}
    for name in ("fig-throughput-vs-nodes", "fig-steps-to-data-target", "fig-efficiency-vs-nodes",
                 "fig-efficiency-per-node-vs-nodes", "fig-mobility-efficiency-vs-nodes"):
        assert by_name[name].scenario_for({"n_nodes": 10}, 0).reward_weight == 1.0, name
    for name in ("fig-harvested-vs-nodes", "fig-steps-to-energy-target"):
        s = by_name[name].scenario_for({"n_nodes": 10}, 0)
        assert (s.reward_weight, s.split_ratio) == (0.0, 0.0), name
    # the efficiency readings share their tasks: one run serves the four figures
    keys = {name: [t.key for t in by_name[name].tasks()]
            for name in ("fig-efficiency-vs-nodes", "fig-mobility-efficiency-vs-nodes")}
    assert keys["fig-efficiency-vs-nodes"] == keys["fig-mobility-efficiency-vs-nodes"]
    uplink = paper_figures("uplink")
    assert uplink and all(e.name.endswith("-uplink") for e in uplink)
    assert all(e.scenario_for(e.points()[0], 0).link == "uplink" for e in uplink)
    assert {e.name for e in paper_figures("downlink_split")} == set(by_name)
    assert {t.key for t in paper_figures("downlink_split")[1].tasks()} == {t.key for t in default[1].tasks()}
