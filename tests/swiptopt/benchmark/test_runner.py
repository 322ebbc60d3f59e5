"""The runner keeps its promises: failed tasks are recorded and the run goes on, a crashing
worker loses nothing, OMPL tasks are isolated and repeatable, workers die with their parent,
and every executor prints the same table."""

import faulthandler
import os
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

from swiptopt.benchmark import runner
from swiptopt.benchmark.algorithms import ALGORITHMS, Algorithm
from swiptopt.benchmark.experiment import Experiment
from swiptopt.benchmark.runner import execute
from swiptopt.benchmark.store import ResultStore
from swiptopt.cli import main
from tests.swiptopt.benchmark.test_processes import descendants, kill_all, needs_ompl, running, wait_until_gone

REAL_RUN_TASK = runner.run_task
#: Layout 1's seed: the task that the test algorithms below break.
BROKEN_SEED = 1000
FLAKY = {"fail": True}


def _flaky_build(env, settings, seed, context):
    if FLAKY["fail"] and seed == BROKEN_SEED:
        raise ValueError("cell 7 cannot be reached from cell 3")
    from planners.policies import GreedyPlanner

    return GreedyPlanner()


def crashing_run_task(task):
    """run_task, except that the broken task kills its process (SIGSEGV) in any process but
    the test's own: in pool workers and in fresh processes alike."""
    spare = os.environ.get("SWIPTOPT_TEST_SPARE_PID")
    if spare and os.getpid() != int(spare) and task["seed"] == BROKEN_SEED:
        faulthandler.disable()  # a pool worker inherits pytest's handler: keep its dump off the log
        os.kill(os.getpid(), signal.SIGSEGV)
    return REAL_RUN_TASK(task)


FLAKY_TOML = """
name = "flaky"
layouts = 3
episodes = 1
[scenario]
preset = "paper"
n_nodes = 6
[algorithms.flaky]
[algorithms.random]
"""


@pytest.fixture
def flaky(monkeypatch):
    monkeypatch.setitem(ALGORITHMS, "flaky", Algorithm("flaky", "flaky", "planner", {}, _flaky_build))
    monkeypatch.setitem(FLAKY, "fail", True)


@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_failing_task_is_recorded_and_the_run_goes_on(tmp_path, capsys, flaky, workers):
    exp = tmp_path / "flaky.toml"
    exp.write_text(FLAKY_TOML)
    store = tmp_path / "s.sqlite"
    reason = "ValueError: cell 7 cannot be reached from cell 3"
    code = main(["run", str(exp), "--store", str(store), "--workers", workers])
    out, err = capsys.readouterr()
    assert code == 1  # finished, with a failure to report
    assert f"(1 task failed: {reason})" in out  # the table says so in its title
    assert "1 task failed" in err and f"1 x {reason}" in err  # and the run's end says why
    experiment = Experiment.from_toml(exp)
    broken = {t.key for t in experiment.tasks() if t.algorithm == "flaky" and t.seed == BROKEN_SEED}
    with ResultStore(store, readonly=True) as s:
        assert s.count() == 5 and s.failures() == {broken.pop(): reason}
    # table reports it too, in the title or (for text formats) on stderr
    assert main(["table", str(store)]) == 0
    assert f"(1 task failed: {reason})" in capsys.readouterr().out
    assert main(["table", str(store), "--format", "csv"]) == 0
    assert f"flaky: 1 task failed: {reason}" in capsys.readouterr().err
    # a rerun retries the failed task only
    FLAKY["fail"] = False
    assert main(["run", str(exp), "--store", str(store), "--workers", workers]) == 0
    out, err = capsys.readouterr()
    assert "6 tasks: 5 already stored, 1 run" in err and "failed" not in out + err
    with ResultStore(store, readonly=True) as s:
        assert s.count() == 6 and s.failures() == {}


def test_a_worker_that_crashes_loses_only_the_crashing_task(tmp_path, monkeypatch):
    monkeypatch.setattr(runner, "run_task", crashing_run_task)
    monkeypatch.setenv("SWIPTOPT_TEST_SPARE_PID", str(os.getpid()))
    experiment = Experiment.from_dict({
        "name": "crash", "layouts": 4, "episodes": 1, "scenario": {"preset": "paper", "n_nodes": 6},
        "algorithms": {"random": {}, "greedy": {}},
    })
    with ResultStore(tmp_path / "s.sqlite") as s:
        report = execute(experiment, s, workers=2)
        broken = {t.key for t in experiment.tasks() if t.seed == BROKEN_SEED}
        assert {f.key for f in report.failures} == broken
        assert all("SIGSEGV" in f.reason for f in report.failures)
        assert s.count() == len(experiment.tasks()) - len(broken)
        assert set(s.failures()) == broken


def test_a_pool_that_breaks_while_it_is_handed_batches_loses_nothing(tmp_path, monkeypatch):
    """A pool can break (a worker died) between two submissions, so that ``submit`` itself
    raises: the batch it refused runs with the next pool, and no task is lost."""
    import concurrent.futures
    from concurrent.futures.process import BrokenProcessPool

    calls = []

    class BreaksOnce(concurrent.futures.ProcessPoolExecutor):
        def submit(self, fn, /, *args, **kwargs):
            calls.append(fn)
            if len(calls) == 3:
                raise BrokenProcessPool("a worker died (simulated)")
            return super().submit(fn, *args, **kwargs)

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", BreaksOnce)
    experiment = Experiment.from_dict({
        "name": "broken-pool", "layouts": 6, "episodes": 1, "scenario": {"preset": "paper", "n_nodes": 6},
        "algorithms": {"random": {}, "greedy": {}},
    })
    with ResultStore(tmp_path / "s.sqlite") as s:
        report = execute(experiment, s, workers=2)
        assert len(calls) > 3  # the pool did refuse a batch
        assert report.failed == 0 and s.count() == len(experiment.tasks()) == 12


@needs_ompl
def test_ompl_tasks_run_in_fresh_processes_and_repeat(tmp_path, monkeypatch):
    experiment = Experiment.from_dict({
        "name": "ompl", "layouts": 1, "episodes": 1, "scenario": {"preset": "paper", "n_nodes": 6},
        # two hover points: the tour is enumerated, so only OMPL could make the runs differ
        "algorithms": {"kmeans_tsp": {"tour_costs": "ompl", "ompl_time_limit_s": 0.05, "k": 2}},
    })
    results = []
    for name in ("a", "b"):
        with ResultStore(tmp_path / f"{name}.sqlite") as s:
            report = execute(experiment, s, workers=1)
            assert report.ran == 1 and not report.failures, report.failures
            results.append(s.get(s.keys()))
    (key, first), = results[0].items()
    assert results[1][key]["records"] == first["records"] and results[1][key]["extra"] == first["extra"]
    # a worker hands an OMPL task to a fresh process instead of running it itself
    here = []
    monkeypatch.setattr(runner, "run_task", lambda task: here.append(task) or REAL_RUN_TASK(task))
    again = runner.run_outcome(experiment.tasks()[0].to_dict())
    assert here == [] and again["records"] == first["records"]


def test_run_options_are_checked_before_anything_runs(tmp_path):
    experiment = Experiment.from_dict({"name": "x", "layouts": 1, "episodes": 1,
                                       "scenario": {"preset": "paper", "n_nodes": 4}, "algorithms": {"random": {}}})
    too_many = runner.MAX_WORKERS_PER_CORE * (os.cpu_count() or 1) + 1
    for options, words in (
        ({"workers": 0}, "workers = 0"),
        ({"workers": too_many}, f"workers = {too_many}"),
        ({"workers": 2, "scheduler": "local:2"}, "not both"),
        ({"scheduler": "::::"}, "not a scheduler address"),
        ({"scheduler": "local:0"}, "local:0"),
        ({"scheduler": "local:x"}, "local:x"),
        ({"scheduler": "tcp://host"}, "missing port"),
        ({"scheduler": "tcp://:8786"}, "needs a host"),
        ({"scheduler": "tcp://h:70000"}, "port"),
        ({"scheduler": "inproc://x"}, "unknown scheme"),
        ({"scheduler": ""}, "empty"),
    ):
        with ResultStore(tmp_path / "s.sqlite") as s, pytest.raises(runner.ConfigError, match=words):
            execute(experiment, s, **options)
    with ResultStore(tmp_path / "s.sqlite") as s:
        assert s.count() == 0 and s.runs() == []


SMALL_TOML = """
name = "small"
layouts = 1
episodes = 1
[scenario]
preset = "paper"
n_nodes = 4
[algorithms.random]
"""


def test_an_unreachable_scheduler_leaves_no_store_and_records_no_run(tmp_path, monkeypatch, capsys):
    pytest.importorskip("distributed")
    monkeypatch.setattr(runner, "SCHEDULER_TIMEOUT_S", 1.0, raising=False)
    exp = tmp_path / "e.toml"
    exp.write_text(SMALL_TOML)
    store = tmp_path / "s.sqlite"
    code = main(["run", str(exp), "--store", str(store), "--scheduler", "tcp://127.0.0.1:1"])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2 and len(err) == 1 and "cannot reach the Dask scheduler at 'tcp://127.0.0.1:1'" in err[0], err
    assert not store.exists()
    # through the API, on a store of its own: no run is recorded
    with ResultStore(tmp_path / "t.sqlite") as s:
        with pytest.raises(runner.ConfigError, match="cannot reach"):
            execute(Experiment.from_toml(exp), s, scheduler="tcp://127.0.0.1:1")
        assert s.runs() == [] and s.count() == 0


# ------------------------------------------------------------------ parent death

KILL_TOML = """
name = "kill"
layouts = 20
episodes = 2
[scenario]
preset = "paper"
n_nodes = 10
[sweep]
n_nodes = [8, 10]
[algorithms.q_learning]
train_episodes = 4000
[algorithms.random]
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("executor", [["--workers", "2"], ["--scheduler", "local:2"]])
def test_workers_die_with_a_killed_run(tmp_path, executor):
    exp = tmp_path / "kill.toml"
    exp.write_text(KILL_TOML)
    store = tmp_path / "kill.sqlite"
    proc = subprocess.Popen([sys.executable, "-m", "swiptopt.cli", "run", str(exp), "--store", str(store), *executor],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    seen: set[int] = set()
    try:
        deadline = time.monotonic() + 180  # a wait limit for the workers to start, not a speed check
        stored = 0
        while time.monotonic() < deadline and proc.poll() is None and stored < 1:
            time.sleep(0.2)
            seen |= descendants(proc.pid)
            if store.exists():
                try:
                    with sqlite3.connect(store, timeout=1) as db:
                        stored = db.execute("SELECT COUNT(*) FROM results").fetchone()[0]
                except sqlite3.OperationalError:
                    continue
        assert proc.poll() is None, "the run ended before it could be killed"
        seen |= descendants(proc.pid)
        workers = [p for p in seen if running(p)]
        assert len(workers) >= 2, "the workers are not running"
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        assert not wait_until_gone(seen), "workers outlived their parent"
    finally:
        proc.kill()
        proc.wait()
        kill_all(p for p in seen if running(p))


# ------------------------------------------------------------------ identical tables


def test_compare_prints_the_same_tables_on_every_executor_and_every_run(tmp_path):
    # --quick: every algorithm of compare's standard suite (the MILP at its quick budget, PPO
    # and DQN at 1024 steps, one training seed) on 2 layouts, so the test takes a minute
    # rather than several (the harbour suite's twin is in test_worlds.py)
    tables = {}
    # one local worker against a Dask cluster of two: the two ways tasks can be run (a pool of
    # two local workers is the Dask case's scheduling with the local pool's processes; the
    # harbour suite's twin runs it)
    for name, executor in (("workers1", ["--workers", "1"]), ("dask", ["--scheduler", "local:2"])):
        output = tmp_path / f"{name}.md"
        result = subprocess.run(
            [sys.executable, "-m", "swiptopt.cli", "compare", "--suite", "standard", "--quick", "--store",
             str(tmp_path / f"{name}.sqlite"),
             *executor,
             "--format", "markdown", "--output", str(output)],
            capture_output=True, text=True,
        )
        assert result.returncode == 0, result.stderr
        assert "22 tasks: 0 already stored, 22 run" in result.stderr and "missing" not in result.stderr
        tables[name] = output.read_text()
        assert tables[name] == result.stdout
    assert "| k-means + TSP |" in tables["workers1"] and "×" in tables["workers1"]
    assert "| MILP |" in tables["workers1"] and "milp (expected)" in tables["workers1"]
    # deep RL too: the models trained by one worker, two, or Dask's give the same rows
    assert "| PPO |" in tables["workers1"] and "| DQN |" in tables["workers1"]
    reference = tables["workers1"].splitlines()
    differences = {name: [line for line in text.splitlines() if line not in reference]
                   for name, text in tables.items() if text != tables["workers1"]}
    assert not differences, f"rows that differ from the first --workers 1 run: {differences}"


# ------------------------------------------------------------------ native threads


def _report_threads(batch):
    from tests.swiptopt.benchmark.test_processes import thread_report

    return [{**thread_report(None), "pid": os.getpid()} for _ in batch]


def test_pool_workers_run_one_native_thread_per_pool(monkeypatch):
    monkeypatch.setattr(runner, "run_batch", _report_threads)  # forked workers see it
    reports = [r for batch in runner._local([[{}]] * 6, 2, ("sklearn.cluster",)) for r in batch]
    assert len(reports) == 6 and all(r["pid"] != os.getpid() for r in reports)
    for r in reports:
        assert r["omp"] == "1" and r["pools"] and set(r["pools"]) == {1}, r


def test_dask_workers_run_one_native_thread_per_pool():
    from dask.distributed import Client, LocalCluster

    from swiptopt.benchmark.dask_plugin import PrepareWorker

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None,
                      silence_logs=50) as cluster, Client(cluster) as client:
        client.register_plugin(PrepareWorker(("sklearn.cluster",), watch_parent=True))
        reports = client.gather([client.submit(_report_threads, [i], pure=False) for i in range(4)])
    for (r,) in reports:
        assert r["omp"] == "1" and r["pools"] and set(r["pools"]) == {1}, r
