"""Deep RL in the benchmark: models trained once, kept beside the store and reused; across-
layouts training shared by every task of a seed; plugins; observations; layouts as lists."""

import hashlib
import json
import sys
import textwrap

import pytest

from swiptopt.benchmark import algorithms, tables
from swiptopt.benchmark import experiment as experiment_module
from swiptopt.benchmark.algorithms import ALGORITHMS, get_algorithm, resolve_settings
from swiptopt.benchmark.experiment import MAX_LAYOUT, Experiment, Task
from swiptopt.benchmark.runner import execute
from swiptopt.benchmark.store import ResultStore
from swiptopt.cli import main
from swiptopt.errors import ConfigError
from tests.swiptopt.benchmark.test_store import cli_unprivileged

pytest.importorskip("stable_baselines3")

# a few hundred steps on the tiny preset, small networks, short rollouts: seconds per model
TINY_PPO = {"timesteps": 192, "n_steps": 64, "batch_size": 32, "net_arch": [16], "n_envs": 2, "n_epochs": 2}
TINY_DQN = {"timesteps": 192, "learning_starts": 32, "buffer_size": 500, "net_arch": [16], "n_envs": 2,
            "batch_size": 32, "gradient_steps": 1}


#: The tiny preset with link failures: small, and no exact optimum per task (that search
#: takes seconds; it runs only for deterministic tiny scenarios)
SCENARIO = {"preset": "tiny", "failure_prob_min": 0.05, "failure_prob_max": 0.1}


def tiny(**fields):
    fields.setdefault("name", "deep")
    fields.setdefault("scenario", SCENARIO)
    fields.setdefault("episodes", 2)
    return Experiment(**fields)


def run(experiment, store_path, workers=1):
    with ResultStore(store_path) as store:
        report = execute(experiment, store, workers=workers)
        assert report.failed == 0, report.failures
        results = store.get({t.key for t in experiment.tasks()})
        rows, missing = tables.aggregate(experiment, store)
    assert missing == 0
    return report, results, tables.to_markdown(rows)


def models(directory):
    return sorted(p.name for p in (directory / "models").glob("*.npz"))


# ------------------------------------------------------------------ reuse


def test_a_model_is_trained_once_and_reused_by_a_later_run(tmp_path):
    experiment = tiny(algorithms={"ppo": {**TINY_PPO, "training_seeds": 1}, "dqn": {**TINY_DQN, "training_seeds": 1}},
                      layouts=2)
    report, first, table = run(experiment, tmp_path / "a.sqlite")
    assert report.ran == 4
    assert len(models(tmp_path)) == 4  # per layout: one model per (algorithm, layout)
    assert not any(r["extra"]["model_loaded"] for r in first.values())
    assert all(r["extra"]["train_seconds"] > 0 for r in first.values())
    # the same store: nothing runs again
    again, _, same = run(experiment, tmp_path / "a.sqlite")
    assert again.ran == 0 and same == table
    # a new store in the same directory: every task runs, but loads its model
    fresh, second, reloaded = run(experiment, tmp_path / "b.sqlite")
    assert fresh.ran == 4 and all(r["extra"]["model_loaded"] for r in second.values())
    assert len(models(tmp_path)) == 4
    assert reloaded == table  # the loaded models act as the trained ones did
    assert [second[k]["records"] for k in sorted(second)] == [first[k]["records"] for k in sorted(first)]


def test_across_layouts_trains_once_per_seed_for_every_layout(tmp_path):
    experiment = tiny(algorithms={"ppo": {**TINY_PPO, "training": "across_layouts", "training_seeds": 2}},
                      layouts=[3, 4, 5], training_layouts=[10, 11])
    tasks = experiment.tasks()
    assert len(tasks) == 6 and {t.seed for t in tasks} == {3000, 3001, 4000, 4001, 5000, 5001}
    assert all(t.training_layouts == (10, 11) and "training_seeds" not in t.settings for t in tasks)
    _, results, _ = run(experiment, tmp_path / "s.sqlite", workers=2)  # two workers want each model
    assert len(models(tmp_path)) == 2
    extras = [r["extra"] for r in results.values()]
    assert sum(not e["model_loaded"] for e in extras) == 2  # one training per seed
    by_seed = {}
    for r in results.values():
        by_seed.setdefault(r["task"]["seed"] % 1000, set()).add(r["extra"]["model"])
    assert {s: len(m) for s, m in by_seed.items()} == {0: 1, 1: 1}
    assert by_seed[0] != by_seed[1]
    assert {e["training_seed"] for e in extras} == {0, 1}


def test_a_damaged_stored_model_is_retrained_and_gives_the_same_table(tmp_path):
    experiment = tiny(algorithms={"dqn": {**TINY_DQN, "training_seeds": 1}}, layouts=1)
    _, first, table = run(experiment, tmp_path / "a.sqlite")
    (path,) = (tmp_path / "models").glob("*.npz")
    path.write_bytes(b"PK\x03\x04 not really a zip")
    _, second, again = run(experiment, tmp_path / "b.sqlite")
    (extra,) = [r["extra"] for r in second.values()]
    assert not extra["model_loaded"] and "retrained" in extra["model_note"] and "differs" in extra["model_note"]
    assert again == table
    # a whole model of another configuration copied under this name is not the file recorded
    other = next(iter((tmp_path / "models").glob("*.npz")))
    experiment2 = tiny(algorithms={"dqn": {**TINY_DQN, "training_seeds": 1, "timesteps": 160}}, layouts=1)
    run(experiment2, tmp_path / "c.sqlite")
    newer = [p for p in (tmp_path / "models").glob("*.npz") if p != other]
    other.write_bytes(newer[0].read_bytes())
    _, third, again = run(experiment, tmp_path / "d.sqlite")
    (extra,) = [r["extra"] for r in third.values()]
    assert "differs from the file recorded" in extra["model_note"] and again == table


def test_a_planted_model_runs_nothing_and_is_retrained(tmp_path):
    """A file planted under a model's predictable name (an SB3 zip whose pickle would write a
    file, or weights the manifest does not vouch for) is never loaded: the task retrains and
    says so."""
    import pickle
    import zipfile

    experiment = tiny(algorithms={"ppo": {**TINY_PPO, "training_seeds": 1}}, layouts=1)
    _, first, table = run(experiment, tmp_path / "a.sqlite")
    (path,) = (tmp_path / "models").glob("*.npz")
    marker = tmp_path / "planted-payload-ran"

    class Payload:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    (tmp_path / "models" / "manifest.json").unlink()
    with zipfile.ZipFile(path, "w") as z:  # an SB3-style zip with a pickled payload
        z.writestr("data", pickle.dumps(Payload()))
    path.with_suffix(".zip").write_bytes(path.read_bytes())
    _, second, again = run(experiment, tmp_path / "b.sqlite")
    (extra,) = [r["extra"] for r in second.values()]
    assert not extra["model_loaded"] and "not recorded" in extra["model_note"]
    assert not marker.exists() and again == table


def test_the_seed_spread_column_shows_each_seeds_mean(tmp_path):
    experiment = tiny(algorithms={"ppo": {**TINY_PPO, "training": "across_layouts"}, "random": {}},
                      layouts=2, training_layouts=[7], baseline="random")
    _, results, table = run(experiment, tmp_path / "s.sqlite")
    with ResultStore(tmp_path / "s.sqlite") as store:
        rows, _ = tables.aggregate(experiment, store)
        pairs = tables.paired(experiment, store)
    (ppo,) = [r for r in rows if r.algorithm == "ppo"]
    per_seed = {}
    for r in results.values():
        if r["task"]["algorithm"] == "ppo":
            mean = sum(e["return"] for e in r["records"]) / len(r["records"])
            per_seed.setdefault(r["task"]["seed"] % 1000, []).append(mean)
    means = [sum(v) / len(v) for _, v in sorted(per_seed.items())]
    spread = ppo.summaries[tables.SEED_SPREAD]
    assert spread.n == 3 and spread.min == pytest.approx(min(means)) and spread.max == pytest.approx(max(means))
    assert ppo.tasks == 6 and "return by seed" in table and "(3 seeds)" in table
    (pair,) = pairs
    assert pair.ratios["return"].n == 2  # paired by layout, the three seeds averaged


# ------------------------------------------------------------------ observations


@pytest.mark.parametrize("name, value, valid", [("q_learning", "vector", "tabular"), ("sarsa", "vector", "tabular"),
                                                 ("ppo", "tabular", "vector"), ("dqn", "tabular", "vector")])
def test_an_algorithm_on_the_wrong_observation_is_a_config_error(name, value, valid):
    with pytest.raises(ConfigError) as info:
        tiny(algorithms={name: {"observation": value}})
    message = str(info.value)
    assert f"algorithms.{name}.observation = {value!r}" in message and f"{valid!r}" in message
    assert info.value.field == "observation" and "\n" not in message
    assert resolve_settings(name, {"observation": valid}) == resolve_settings(name, {})


def test_the_observation_of_each_algorithm():
    assert {n for n, a in ALGORITHMS.items() if a.observation == "vector"} == {"ppo", "dqn", "sac", "shared_ppo"}
    assert {n for n, a in ALGORITHMS.items() if a.observation == "tabular"} == {
        "q_learning", "sarsa", "random", "fleet_q_learning", "fleet_random"}
    with pytest.raises(ConfigError, match="'tabular', 'vector'"):
        resolve_settings("greedy", {"observation": "pixels"})


# ------------------------------------------------------------------ layouts


@pytest.mark.parametrize("fields, words", [
    ({"layouts": [1, 2, 1]}, "layouts lists layout 1 more than once"),
    ({"layouts": [-1]}, "layouts[0] = -1"),
    ({"layouts": [MAX_LAYOUT + 1]}, "layouts[0]"),
    ({"layouts": []}, "non-empty list"),
    ({"layouts": [True]}, "layouts[0] = True"),
    ({"layouts": ["3"]}, "layouts[0] = '3'"),
    ({"layouts": "3"}, "layouts = '3'"),
    ({"training_layouts": [1, 2]}, "no algorithm trains across layouts"),
    ({"algorithms": {"ppo": {"training": "across_layouts"}}}, "needs training_layouts"),
    ({"algorithms": {"ppo": {"training": "across_layouts"}}, "training_layouts": [4, 4]}, "layout 4 more than once"),
    ({"algorithms": {"ppo": {"training": "across_layouts"}}, "training_layouts": {"start": 3}}, "'start' and 'count'"),
    ({"algorithms": {"ppo": {"training": "across_layouts"}}, "training_layouts": {"start": -3, "count": 2}},
     "training_layouts.start = -3"),
    ({"algorithms": {"ppo": {"training": "across_layouts"}}, "training_layouts": {"start": MAX_LAYOUT, "count": 2}},
     "largest layout seed"),
    ({"algorithms": {"ppo": {"training": "across_layouts"}}, "training_layouts": "all"}, "training_layouts"),
])
def test_bad_layouts_and_training_layouts_are_refused(fields, words):
    fields.setdefault("algorithms", {"random": {}})
    with pytest.raises(ConfigError) as info:
        tiny(**fields)
    assert words in str(info.value) and "\n" not in str(info.value)
    assert info.value.field in ("layouts", "training_layouts")


def test_layouts_as_a_list_and_training_layouts_as_a_range():
    e = tiny(algorithms={"random": {}, "ppo": {"training": "across_layouts"}}, layouts=[50, 7, 9],
             training_layouts={"start": 100, "count": 4})
    assert e.layout_seeds() == (50, 7, 9) and e.training_layouts == (100, 101, 102, 103)
    random_seeds = [t.seed for t in e.tasks() if t.algorithm == "random"]
    assert random_seeds == [50_000, 7000, 9000]  # one seed per layout: the experiment's seeds
    assert len([t for t in e.tasks() if t.algorithm == "ppo"]) == 9  # ppo: its 3 training seeds
    assert [t.scenario["layout_seed"] for t in e.tasks() if t.algorithm == "random"] == [50, 7, 9]
    # overlapping the evaluation layouts is allowed (the compare suite does it)
    assert tiny(algorithms={"ppo": {"training": "across_layouts"}}, layouts=2, training_layouts=[0, 1])
    # --quick keeps the first two layouts and one training seed
    quick = e.quick()
    assert quick.layout_seeds() == (50, 7) and len([t for t in quick.tasks() if t.algorithm == "ppo"]) == 2
    # the stored configuration reads back as the same experiment
    assert Experiment.from_dict(json.loads(json.dumps(e.to_dict()))) == e


def test_task_keys_without_the_new_fields_are_those_of_earlier_versions():
    e = tiny(algorithms={"random": {}}, layouts=[3])
    (task,) = e.tasks()
    old = json.dumps({"scenario": task.scenario, "algorithm": "random", "settings": task.settings, "seed": 3000,
                      "episodes": 2}, sort_keys=True, separators=(",", ":"))
    assert task.key == hashlib.sha256(old.encode()).hexdigest()
    assert Task(**{**task.to_dict(), "training_layouts": [1]}).key != task.key
    assert Task(**{**task.to_dict(), "plugin": "m:f"}).key != task.key


# ------------------------------------------------------------------ plugins

PLUGIN = textwrap.dedent('''
    from swiptopt.benchmark.algorithms import Setting, sb3_algorithm


    def a2c():
        return sb3_algorithm("stable_baselines3:A2C", "A2C",
                             {"n_steps": Setting(default=5, kind="int", lo=1, hi=10_000)})


    def broken():
        raise RuntimeError("no licence")


    def not_an_algorithm():
        return {"name": "a2c"}
''')


def _plugin_experiment(tmp_path, factory="a2c", name="a2c", module="swiptopt_test_plugin_a2c"):
    (tmp_path / f"{module}.py").write_text(PLUGIN, encoding="utf-8")
    path = tmp_path / "plugin.toml"
    path.write_text(textwrap.dedent(f'''
        name = "plugin"
        layouts = 2
        episodes = 2
        [scenario]
        preset = "tiny"
        failure_prob_min = 0.05
        failure_prob_max = 0.1
        [plugins]
        {name} = "{module}:{factory}"
        [algorithms.{name}]
        timesteps = 100
        net_arch = [16]
        training_seeds = 1
        [algorithms.random]
    '''), encoding="utf-8")
    return path


def test_a_plugin_named_in_an_experiment_file_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.syspath_prepend(str(tmp_path))
    path = _plugin_experiment(tmp_path)
    store = tmp_path / "s.sqlite"
    assert main(["run", str(path), "--store", str(store), "--workers", "1", "--format", "markdown",
                 "--allow-plugins"]) == 0
    out = capsys.readouterr().out
    assert "| A2C |" in out and "| random |" in out
    assert len(models(tmp_path)) == 2 and all(m.startswith("a2c-") for m in models(tmp_path))  # one per layout
    experiment = Experiment.from_toml(path, allow_plugins=True)
    assert {t.plugin for t in experiment.tasks() if t.algorithm == "a2c"} == {"swiptopt_test_plugin_a2c:a2c"}
    # `swiptopt table` reads the plugin's rows from the store, without the plugin
    assert main(["table", str(store), "--format", "csv"]) == 0
    assert "a2c,1,return" in capsys.readouterr().out.replace("\r", "")


@pytest.mark.parametrize("factory, name, module, words", [
    ("a2c", "a2c", "swiptopt_no_such_module", "cannot import 'swiptopt_no_such_module'"),
    ("missing", "a2c", "swiptopt_test_plugin_bad1", "has no 'missing'"),
    ("broken", "a2c", "swiptopt_test_plugin_bad2", "the factory failed (RuntimeError: no licence)"),
    ("not_an_algorithm", "a2c", "swiptopt_test_plugin_bad3", "returned dict, not a swiptopt"),
    ("a2c", "ppo", "swiptopt_test_plugin_bad4", "'ppo' is a built-in algorithm"),
])
def test_a_bad_plugin_is_one_line_and_exit_2_before_any_task(tmp_path, monkeypatch, capsys, factory, name, module,
                                                              words):
    monkeypatch.syspath_prepend(str(tmp_path))
    path = _plugin_experiment(tmp_path, factory, name, module)
    if module == "swiptopt_no_such_module":
        (tmp_path / f"{module}.py").unlink()
    store = tmp_path / "s.sqlite"
    assert main(["run", str(path), "--store", str(store), "--allow-plugins"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err and "Traceback" not in err
    assert not store.exists()


ENTRY_POINT_MODULE = textwrap.dedent('''
    from swiptopt.benchmark.algorithms import Algorithm


    class Hover:
        def predict(self, obs, deterministic=True):
            return 6


    def hover():
        return Algorithm("ignored", "always hover", "planner", {}, lambda env, settings, seed, context: Hover())
''')


def test_an_algorithm_from_an_installed_entry_point_runs(tmp_path, monkeypatch):
    (tmp_path / "swiptopt_test_ep.py").write_text(ENTRY_POINT_MODULE, encoding="utf-8")
    info = tmp_path / "swiptopt_test_ep-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: swiptopt-test-ep\nVersion: 0.1\n", encoding="utf-8")
    (info / "entry_points.txt").write_text("[swiptopt.algorithms]\nhover_ep = swiptopt_test_ep:hover\n",
                                           encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert get_algorithm("hover_ep").label == "always hover" and get_algorithm("hover_ep").name == "hover_ep"
    experiment = tiny(algorithms={"hover_ep": {}}, layouts=1)
    _, results, table = run(experiment, tmp_path / "s.sqlite")
    (result,) = results.values()
    assert "| always hover |" in table
    assert all(r["length"] == experiment.scenario_for({}, 0).episode_steps for r in result["records"])
    with pytest.raises(ConfigError, match="unknown algorithm 'hover_e'.*did you mean 'hover_ep'"):
        tiny(algorithms={"hover_e": {}})
    # reading the store looks up no entry point: the rows come from the stored data
    def refuse(*args):
        raise AssertionError("reading a store loaded an algorithm")

    monkeypatch.setattr(algorithms, "_entry_point", refuse)
    monkeypatch.setattr(algorithms, "load_plugin", refuse)
    monkeypatch.setattr(experiment_module, "load_plugin", refuse)
    with ResultStore(tmp_path / "s.sqlite", readonly=True) as s:
        (stored,) = s.experiments()
        rows, missing = tables.aggregate(stored, s)
    assert missing == 0 and [r.algorithm for r in rows] == ["hover_ep"]
    assert [t.key for t in stored.tasks()] == [t.key for t in experiment.tasks()]


# ------------------------------------------------------------------ the models directory

MODELS_TOML = textwrap.dedent(f"""
    name = "models"
    layouts = 1
    episodes = 1
    [scenario]
    preset = "tiny"
    failure_prob_min = 0.05
    failure_prob_max = 0.1
    [algorithms.ppo]
    {chr(10).join(f"{k} = {json.dumps(v)}" for k, v in TINY_PPO.items())}
    training_seeds = 1
    [algorithms.random]
""")


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A directory with an experiment file, its store and the models/ its run trained."""
    directory = tmp_path_factory.mktemp("trained")
    (directory / "e.toml").write_text(MODELS_TOML, encoding="utf-8")
    assert main(["run", str(directory / "e.toml"), "--store", str(directory / "s.sqlite"), "--workers", "1",
                 "--format", "csv"]) == 0
    (name,) = models(directory)
    return directory, name


def _refused(capsys, store, *words):
    code = main(["run", str(store.parent / "e.toml"), "--store", str(store), "--workers", "1"])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2 and len(err) == 1 and "Traceback" not in err[0], err
    assert all(w in err[0] for w in words), err
    with ResultStore(store, readonly=True) as s:
        assert s.runs() == [] and s.count() == 0 and s.failures() == {}  # refused before any task


@pytest.mark.parametrize("where", ["models", "model", "lock", "manifest.json", "manifest.json.lock"])
def test_a_models_directory_that_would_fail_the_tasks_is_refused_before_any(trained, tmp_path, capsys, where):
    directory, name = trained
    (tmp_path / "e.toml").write_text(MODELS_TOML, encoding="utf-8")
    if where == "models":
        (tmp_path / "models").write_text("not a directory", encoding="utf-8")
        _refused(capsys, tmp_path / "s.sqlite", str(tmp_path / "models"), "is a file")
        return
    blocked = tmp_path / "models" / {"model": name, "lock": name + ".lock"}.get(where, where)
    blocked.mkdir(parents=True)
    _refused(capsys, tmp_path / "s.sqlite", str(blocked), "is a directory")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="drops Linux capabilities when root")
def test_a_read_only_models_directory_with_the_models_is_used_as_it_is(trained, tmp_path):
    directory, name = trained
    ready = tmp_path / "ready"
    ready.mkdir()
    (ready / "e.toml").write_text(MODELS_TOML, encoding="utf-8")
    (ready / "models").mkdir()
    for file in (directory / "models").iterdir():
        if not file.name.endswith(".lock"):
            (ready / "models" / file.name).write_bytes(file.read_bytes())
    empty = tmp_path / "empty"
    (empty / "models").mkdir(parents=True)
    (empty / "e.toml").write_text(MODELS_TOML, encoding="utf-8")
    for folder in (ready, empty):
        (folder / "models").chmod(0o555)
    try:
        result = cli_unprivileged("run", str(ready / "e.toml"), "--store", str(ready / "s.sqlite"), "--workers", "1",
                                  "--format", "csv")
        assert result.returncode == 0, result.stderr
        assert sorted(p.name for p in (ready / "models").iterdir()) == sorted(
            p.name for p in (directory / "models").iterdir() if not p.name.endswith(".lock"))  # no lock made
        with ResultStore(ready / "s.sqlite", readonly=True) as s:
            extras = [r["extra"] for r in s.get(s.keys()).values() if r["task"]["algorithm"] == "ppo"]
        assert [e["model_loaded"] for e in extras] == [True] and extras[0]["model_file"] == name
        # one that lacks a model the run needs is refused before any task
        result = cli_unprivileged("run", str(empty / "e.toml"), "--store", str(empty / "s.sqlite"), "--workers", "1")
        lines = result.stderr.strip().splitlines()
        assert result.returncode == 2 and len(lines) == 1, result.stderr
        assert "not writable" in lines[0] and name in lines[0]
    finally:
        for folder in (ready, empty):
            (folder / "models").chmod(0o755)
