"""Plugins run code from outside swiptopt, so swiptopt runs it only where the user asked:
an experiment file's [plugins] only with --allow-plugins, only a factory defined in the
module named, every exception of the plugin's one line, a native crash of its code only its
own tasks' loss; and reading a store runs none of it."""

import json
import os
import subprocess
import sys
import textwrap

import pytest

from swiptopt.benchmark import algorithms, tables
from swiptopt.benchmark.algorithms import load_plugin
from swiptopt.benchmark.experiment import Experiment
from swiptopt.benchmark.runner import execute
from swiptopt.benchmark.store import ResultStore
from swiptopt.cli import main
from swiptopt.errors import ConfigError

#: The tiny preset with link failures (no exact optimum per task: that search takes seconds).
SCENARIO = {"preset": "tiny", "failure_prob_min": 0.05, "failure_prob_max": 0.1}

#: A plugin that hovers; importing it leaves a mark (the file named by SWIPTOPT_TEST_MARK).
HOVER = textwrap.dedent('''
    import os

    from swiptopt.benchmark.algorithms import Algorithm, Setting

    if os.environ.get("SWIPTOPT_TEST_MARK"):
        with open(os.environ["SWIPTOPT_TEST_MARK"], "a") as mark:
            mark.write("imported\\n")


    class Hover:
        def __init__(self, moves):
            self.moves = moves
            self.step = 0

        def predict(self, obs, deterministic=True):
            self.step += 1
            return 6 if self.step > self.moves else 0


    def hover():
        return Algorithm("ignored", "always hover", "planner",
                         {"moves": Setting(default=3, kind="int", lo=0, hi=100, doc="steps north first")},
                         lambda env, settings, seed, context: Hover(settings["moves"]))


    def crash():
        import ctypes

        def build(env, settings, seed, context):
            ctypes.string_at(0)  # a segfault in native code

        return Algorithm("ignored", "crashes", "planner", {}, build)


    def exits():
        raise SystemExit(0)


    def exits_in_build():
        def build(env, settings, seed, context):
            raise SystemExit(0)

        return Algorithm("ignored", "exits", "planner", {}, build)


    def interrupted():
        raise KeyboardInterrupt


    def needs_an_argument(x):
        return hover()
''')


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """The module ``swiptopt_test_hover`` on the path, not imported yet and no plugin
    registered in this process; returns the file its import marks."""
    (tmp_path / "swiptopt_test_hover.py").write_text(HOVER, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "swiptopt_test_hover", raising=False)
    monkeypatch.setattr(algorithms, "_PLUGINS", {})
    mark = tmp_path / "imported.txt"
    monkeypatch.setenv("SWIPTOPT_TEST_MARK", str(mark))
    return mark


def cli(*args, pythonpath=None, env=None):
    """``swiptopt ARGS`` in a fresh process (a crash there cannot take the tests with it)."""
    environment = dict(os.environ if env is None else env)
    if pythonpath:
        environment["PYTHONPATH"] = os.pathsep.join(filter(None, [str(pythonpath), environment.get("PYTHONPATH")]))
    return subprocess.run([sys.executable, "-m", "swiptopt.cli", *args], capture_output=True, text=True,
                          env=environment)


def write_toml(path, plugins, algorithms="[algorithms.random]\n"):
    path.write_text(textwrap.dedent('''
        name = "plug"
        layouts = 2
        episodes = 1
        [scenario]
        preset = "tiny"
        failure_prob_min = 0.05
        failure_prob_max = 0.1
    ''') + "[plugins]\n" + "".join(f'{k} = "{v}"\n' for k, v in plugins.items())
        + "".join(f"[algorithms.{k}]\n" for k in plugins) + algorithms, encoding="utf-8")
    return path


def one_line(code, err):
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# ------------------------------------------------------------------ consent


def test_an_experiment_files_plugins_need_allow_plugins(tmp_path, plugin, capsys):
    path = write_toml(tmp_path / "e.toml", {"x": "swiptopt_test_hover:hover"})
    store = tmp_path / "s.sqlite"
    line = one_line(main(["run", str(path), "--store", str(store)]), capsys.readouterr().err)
    assert "plugins.x" in line and "--allow-plugins" in line and str(path) in line
    assert not plugin.exists() and not store.exists()  # nothing imported, nothing written
    for load in (lambda: Experiment.from_toml(path), lambda: Experiment.from_dict(
            {"name": "p", "algorithms": {"x": {}}, "plugins": {"x": "swiptopt_test_hover:hover"}})):
        with pytest.raises(ConfigError, match="plugins.x .*--allow-plugins"):
            load()
    assert not plugin.exists()
    # with consent it runs; in Python an experiment built in code loads its plugins as it did
    assert main(["run", str(path), "--store", str(store), "--allow-plugins", "--format", "markdown"]) == 0
    assert "| always hover |" in capsys.readouterr().out and plugin.exists()
    assert Experiment.from_toml(path, allow_plugins=True).plugins == {"x": "swiptopt_test_hover:hover"}
    assert Experiment(name="p", scenario=SCENARIO, algorithms={"x": {}}, plugins={"x": "swiptopt_test_hover:hover"})


@pytest.mark.parametrize("source", ["os:abort", "os:fork", "sys:exit", "os:_exit", "builtins:print", "json:dumps",
                                    "swiptopt_test_hover:Setting", "swiptopt_test_hover:needs_an_argument",
                                    "swiptopt_test_hover:os.getcwd"])
def test_only_a_function_of_the_named_module_is_called_as_a_factory(tmp_path, plugin, capsys, source):
    """Builtins, classes, functions another module defines and functions that need
    arguments are refused without being called, even with consent."""
    path = write_toml(tmp_path / "e.toml", {"x": source})
    line = one_line(main(["run", str(path), "--store", str(tmp_path / "s.sqlite"), "--allow-plugins"]),
                    capsys.readouterr().err)
    assert f"plugins.x = {source!r} is not a factory" in line
    if source.startswith(("sys", "builtins", "json")):  # harmless to call in this process on any version
        with pytest.raises(ConfigError, match="is not a factory"):
            load_plugin("x", source)


def test_a_package_may_re_export_its_factory(tmp_path, plugin):
    package = tmp_path / "swiptopt_test_package"
    package.mkdir()
    (package / "__init__.py").write_text("from swiptopt_test_package.factories import hover\n", encoding="utf-8")
    (package / "factories.py").write_text("from swiptopt_test_hover import hover as made\n\n\n"
                                          "def hover():\n    return made()\n", encoding="utf-8")
    assert load_plugin("x", "swiptopt_test_package:hover").label == "always hover"
    with pytest.raises(ConfigError, match="is not a factory"):  # defined elsewhere, imported here
        load_plugin("y", "swiptopt_test_package.factories:made")


@pytest.mark.parametrize("source, words", [
    ("swiptopt_test_exits_on_import:hover", "cannot import 'swiptopt_test_exits_on_import' (SystemExit: 3)"),
    ("swiptopt_test_hover:exits", "the factory failed (SystemExit: 0)"),
    ("swiptopt_test_hover:interrupted", "the factory failed (KeyboardInterrupt)"),
])
def test_whatever_a_plugin_raises_is_one_line_and_exit_2(tmp_path, plugin, capsys, source, words):
    (tmp_path / "swiptopt_test_exits_on_import.py").write_text("raise SystemExit(3)\n", encoding="utf-8")
    try:
        load_plugin("x", source)
    except ConfigError as exc:
        assert words in str(exc) and "\n" not in str(exc)
    except BaseException as exc:  # noqa: BLE001 - what escaped is the fault this test is about
        pytest.fail(f"{type(exc).__name__} escaped load_plugin")
    else:
        pytest.fail("no error")
    path = write_toml(tmp_path / "e.toml", {"x": source})
    store = tmp_path / "s.sqlite"
    line = one_line(main(["run", str(path), "--store", str(store), "--allow-plugins"]), capsys.readouterr().err)
    assert words in line and not store.exists()


@pytest.mark.parametrize("factory, reason", [("crash", "SIGSEGV"), ("exits_in_build", "SystemExit: 0")])
def test_a_plugin_that_crashes_or_exits_loses_only_its_tasks(tmp_path, plugin, factory, reason):
    path = write_toml(tmp_path / "e.toml", {"boom": f"swiptopt_test_hover:{factory}"})
    store = tmp_path / "s.sqlite"
    result = cli("run", str(path), "--store", str(store), "--workers", "1", "--allow-plugins", "--format", "markdown",
                 pythonpath=tmp_path)
    assert result.returncode == 1, result.stderr  # as for any failed task
    assert "2 tasks failed" in result.stderr and reason in result.stderr
    assert "| random |" in result.stdout
    with ResultStore(store, readonly=True) as s:
        stored = s.get(s.keys())
        assert sorted(r["task"]["algorithm"] for r in stored.values()) == ["random", "random"]
        assert len(s.failures()) == 2


# ------------------------------------------------------------------ reading a store


def test_reading_a_store_imports_no_plugin_and_prints_its_rows(tmp_path, plugin):
    """A store of a run with a plugin: `table` prints the plugin's rows (labelled by its
    name) from the stored data, where the plugin is not installed and where it is, without
    importing it."""
    experiment = Experiment(name="plug", scenario=SCENARIO, layouts=2, episodes=1,
                            algorithms={"random": {}, "hover": {}}, plugins={"hover": "swiptopt_test_hover:hover"},
                            sweep={"moves": [1.0, 5]})  # a swept setting of the plugin, normalised to integers
    store = tmp_path / "s.sqlite"
    with ResultStore(store) as s:
        assert execute(experiment, s, workers=1).failed == 0
        rows, missing = tables.aggregate(experiment, s)
    assert missing == 0
    live = {(r.point["moves"], r.algorithm): r.summaries["return"].mean for r in rows}
    assert len(live) == 4
    plugin.unlink()
    for pythonpath in (None, tmp_path):  # not importable here; importable, and never imported
        result = cli("table", str(store), "--format", "csv", pythonpath=pythonpath)
        assert result.returncode == 0 and "missing" not in result.stderr, result.stderr
        assert not plugin.exists()
        read = {(float(row[0]), row[1]): float(row[4]) for row in
                (line.split(",") for line in result.stdout.splitlines()[1:]) if row[3] == "return"}
        assert read == live
        markdown = cli("table", str(store), "--format", "markdown", pythonpath=pythonpath).stdout
        assert "| moves=1.0 | hover |" in markdown and "| moves=5 | hover |" in markdown
    assert not plugin.exists()


@pytest.mark.parametrize("source", ["os:abort", "sys:exit", "swiptopt_test_hover:hover"])
def test_a_store_that_names_code_in_its_plugins_runs_none_of_it(tmp_path, plugin, source):
    experiment = Experiment(name="evil", scenario=SCENARIO, layouts=1, episodes=1, algorithms={"random": {}})
    store = tmp_path / "s.sqlite"
    config = json.loads(json.dumps(experiment.to_dict()))
    config["algorithms"]["x"] = {}
    config["plugins"] = {"x": source}
    with ResultStore(store) as s:
        execute(experiment, s, workers=1)
        s.add_run("evil", config)  # as a store from elsewhere may say
    result = cli("table", str(store), "--format", "markdown", pythonpath=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "| random |" in result.stdout and not plugin.exists()
    assert "evil: 1 tasks missing" in result.stderr  # the row of x cannot be found: it is counted, not run
