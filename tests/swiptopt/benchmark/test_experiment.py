"""Experiments refuse bad input before any task runs: settings, sweeps, names, sizes, files;
and what they write (figures, LaTeX) stays where and what it should be."""

import math
import os
import sqlite3
import subprocess
import sys

import pytest
from hypothesis import given
from hypothesis import strategies as st

from planners.policies import TOUR_COSTS
from planners.tsp import METHODS
from rl.training import BACKENDS
from swiptopt.benchmark import plots, tables
from swiptopt.benchmark.algorithms import ALGORITHMS, INTS, resolve_settings
from swiptopt.benchmark.experiment import SEEDS_PER_LAYOUT, Experiment
from swiptopt.benchmark.runner import execute
from swiptopt.benchmark.store import ResultStore
from swiptopt.errors import ConfigError
from swiptopt.limits import ENVIRONMENT, Limits, limits

SETTINGS = [(name, key) for name, a in ALGORITHMS.items() for key in a.settings]


def experiment(**fields):
    fields.setdefault("name", "t")
    fields.setdefault("scenario", {"preset": "tiny"})
    fields.setdefault("algorithms", {"random": {}})
    return Experiment(**fields)


def cli(*args, env_extra=None):
    env = dict(os.environ, **(env_extra or {}))
    return subprocess.run([sys.executable, "-m", "swiptopt.cli", *args], capture_output=True, text=True, env=env)


def one_line(result):
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    return lines[0]


def stored_results(path):
    if not path.exists():
        return 0
    with sqlite3.connect(path) as db:
        return db.execute("SELECT COUNT(*) FROM results").fetchone()[0]


# ------------------------------------------------------------------ algorithm settings


def bad_values(name, key):
    """A value of the wrong type and one out of range for a setting, from its schema."""
    spec = ALGORITHMS[name].settings[key]
    if spec.kind == "str":
        return [3, "no-such-choice"]
    if spec.kind == "bool":
        return ["yes", 2]
    if spec.kind == INTS:  # single items: the message check below drops commas
        return ["64", 64, [], [0], [True], [1.5], [spec.hi + 1]]
    wrong_type = "fast"
    if spec.upper() is not None:
        out = spec.upper() + 1
    else:  # the bound comes from the scenario: a tiny scenario is far below this
        out = 10**6
    return [wrong_type, out, spec.lo - 1, True, float("nan") if spec.kind == "float" else 1.5]


@pytest.mark.parametrize("name, key", SETTINGS)
def test_every_setting_is_declared_with_a_type_and_a_range(name, key):
    spec = ALGORITHMS[name].settings[key]
    assert spec.kind in ("int", "float", "str", "bool", INTS)
    if spec.kind == "str":
        assert spec.choices and spec.default in spec.choices
    if spec.kind in ("int", "float", INTS):
        assert spec.lo is not None and (spec.upper() is not None or spec.hi_of is not None)
    assert resolve_settings(name, {})[key] == spec.default  # the default is valid


@pytest.mark.parametrize("name, key", SETTINGS)
def test_every_bad_setting_fails_at_construction_naming_the_experiment_key(name, key):
    for value in bad_values(name, key):
        with pytest.raises(ConfigError) as info:
            experiment(algorithms={name: {key: value}}, world=ALGORITHMS[name].worlds[0])
        assert info.value.field == key
        message = str(info.value)
        assert f"algorithms.{name}.{key}" in message and repr(value) in message.replace(",", "")
        assert "\n" not in message


NUMERIC = [(n, k) for n, k in SETTINGS if ALGORITHMS[n].settings[k].kind in ("int", "float")]


#: Settings another setting must accompany (checked between settings): replay needs the
#: Python training loop.
COMPANIONS = {"replay_size": {"backend": "python"}}


@pytest.mark.parametrize("name, key", NUMERIC)
@given(value=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-(10**12), 10**12)))
def test_numeric_settings_accept_exactly_their_range(name, key, value):
    spec = ALGORITHMS[name].settings[key]
    upper = spec.upper()
    ok = math.isfinite(value) and spec.in_range(value, upper) and (spec.kind == "float" or float(value).is_integer())
    own = ALGORITHMS[name].settings
    settings = {key: value, **{k: v for k, v in COMPANIONS.get(key, {}).items() if k in own}}
    if ok:
        assert resolve_settings(name, settings)[key] == value
    else:
        with pytest.raises(ConfigError, match=f"algorithms.{name}.{key}"):
            resolve_settings(name, settings)


def test_schema_agrees_with_what_the_algorithms_accept():
    assert ALGORITHMS["kmeans_tsp"].settings["tour_costs"].choices == TOUR_COSTS
    assert set(ALGORITHMS["kmeans_tsp"].settings["tsp_method"].choices) == set(METHODS)
    for name in ("q_learning", "sarsa", "random"):
        assert set(ALGORITHMS[name].settings["backend"].choices) == set(BACKENDS)


def _declarations():
    from planners import GreedyPlanner, LawnmowerPlanner, RewardKMeansTspPlanner
    from planners.continuous import OmplTourPlanner, StraightLinePlanner
    from rl.config import TABULAR_PARAMETERS

    tabular = {key: TABULAR_PARAMETERS[key] for key in TABULAR_PARAMETERS}
    return [
        ("kmeans_tsp", RewardKMeansTspPlanner.parameters), ("lawnmower", LawnmowerPlanner.parameters),
        ("greedy", GreedyPlanner.parameters), ("ompl_tour", OmplTourPlanner.parameters),
        ("straight_line", StraightLinePlanner.parameters), ("q_learning", tabular), ("sarsa", tabular),
    ]


@pytest.mark.parametrize("name, declared", _declarations(), ids=lambda x: x if isinstance(x, str) else "")
def test_a_registry_entry_s_settings_are_its_class_s_declarations(name, declared):
    """Each setting is declared once, on the class that takes it; the registry reads it (a
    copy that drifted from the class would fail here)."""
    settings = ALGORITHMS[name].settings
    for key, param in declared.items():
        if key == "seed":
            assert key not in settings  # the task's seed
            continue
        spec = settings[key]
        for attribute in ("default", "kind", "lo", "hi", "lo_open", "hi_open", "choices", "optional", "unit", "doc"):
            assert getattr(spec, attribute) == getattr(param, attribute), (name, key, attribute)
    the_rest = set(settings) - set(declared)
    assert the_rest <= {"train_episodes", "backend"}, the_rest  # the training loop's, the registry's own


def test_values_are_normalised_so_equal_settings_give_equal_tasks():
    a = experiment(algorithms={"kmeans_tsp": {"tsp_time_limit_s": 60}})  # the default, 60.0, as an int
    b = experiment(algorithms={"kmeans_tsp": {}})
    assert [t.key for t in a.tasks()] == [t.key for t in b.tasks()]
    assert resolve_settings("greedy", {"max_dwell_steps": 4.0})["max_dwell_steps"] == 4


@pytest.mark.parametrize(
    "algorithms, sweep, words",
    [
        ({"lawnmower": {"depth_cell": 2}}, {}, ["algorithms.lawnmower.depth_cell = 2", "[0, 1]"]),
        ({"kmeans_tsp": {"k": 4}}, {}, ["algorithms.kmeans_tsp.k = 4", "[1, 3]", "n_nodes"]),
        ({"kmeans_tsp": {"k": 3}}, {"n_nodes": [3, 2]}, ["k = 3", "sweep point {'n_nodes': 2}", "[1, 2]"]),
    ],
)
def test_settings_bounded_by_the_scenario_are_checked_at_every_sweep_point(algorithms, sweep, words):
    with pytest.raises(ConfigError) as info:
        experiment(algorithms=algorithms, sweep=sweep)
    for word in words:
        assert word in str(info.value)
    experiment(algorithms={"lawnmower": {"depth_cell": 1}, "kmeans_tsp": {"k": 2}}, sweep={"n_nodes": [3, 2]})


@pytest.mark.parametrize(
    "toml, words",
    [
        ("[algorithms.kmeans_tsp]\ntsp_time_limit_s = 'fast'\n", ["algorithms.kmeans_tsp.tsp_time_limit_s", "'fast'"]),
        ("[algorithms.lawnmower]\nlane_spacing_cells = 0\n", ["algorithms.lawnmower.lane_spacing_cells = 0"]),
        ("[algorithms.random]\nbackend = 'gpu'\n", ["algorithms.random.backend = 'gpu'", "'compiled'"]),
        ("[algorithms.q_learning]\ntrain_episodes = 1_000_000_000\n",
         ["train_episodes", "1,000,000,000", "10,000,000", "SWIPTOPT_MAX_TRAINING_EPISODES", "59.6 GiB"]),
    ],
)
def test_cli_refuses_a_bad_setting_before_running_anything(tmp_path, toml, words):
    path = tmp_path / "e.toml"
    # the first algorithm would run and be stored if validation came late
    path.write_text('name = "e"\nlayouts = 1\nepisodes = 1\n[scenario]\npreset = "tiny"\n[algorithms.greedy]\n' + toml)
    store = tmp_path / "s.sqlite"
    line = one_line(cli("run", str(path), "--store", str(store), "--workers", "1"))
    for word in words:
        assert word in line
    assert stored_results(store) == 0


# ------------------------------------------------------------------ sweeps, names, keys


@pytest.mark.parametrize(
    "sweep, words",
    [
        ({"n_nodes": [3, 3]}, ["sweep.n_nodes lists 3 twice"]),
        ({"n_nodes": [2, 3, 2.0]}, ["sweep.n_nodes lists 2 and 2.0", "same scenario"]),
        ({"split_ratio": [0.5, 0.2], "n_nodes": [2, 3, 3]}, ["sweep.n_nodes lists 3 twice"]),
        ({"start_cell": [[0, 0, 0], [1, 1, 0], [0, 0, 0]]}, ["sweep.start_cell lists [0, 0, 0] twice"]),
    ],
)
def test_duplicate_sweep_values_are_refused(sweep, words):
    with pytest.raises(ConfigError) as info:
        experiment(sweep=sweep)
    for word in words:
        assert word in str(info.value)


def test_task_seeds_are_unique_within_every_sweep_point():
    exp = experiment(layouts=3, seeds=SEEDS_PER_LAYOUT)
    seeds = [t.seed for t in exp.tasks()]
    assert len(seeds) == len(set(seeds)) == 3 * SEEDS_PER_LAYOUT
    with pytest.raises(ConfigError, match=r"seeds = 1001 is out of range: must be an integer in \[1, 1000\]"):
        experiment(seeds=SEEDS_PER_LAYOUT + 1)


@pytest.mark.parametrize("name", ["../evil", "/etc/evil", "a/b", "..", ".", "", "x" * 101, "a b", "é", 3, None])
def test_unsafe_experiment_names_are_refused(name):
    with pytest.raises(ConfigError) as info:
        experiment(name=name)
    assert info.value.field == "name"


def test_safe_names_are_accepted():
    for name in ("fig-1.v2_a", "compare", "A.b-c_d"):
        assert experiment(name=name).name == name


@pytest.mark.parametrize(
    "fields, field, words",
    [
        ({"figure": {"metric": "return"}}, "figure", ["needs a [sweep]"]),
        ({"figure": {"x": "split_ratio"}, "sweep": {"n_nodes": [2, 3]}}, "x",
         ["'split_ratio' is not swept", "n_nodes"]),
        ({"figure": {"title": 3}, "sweep": {"n_nodes": [2, 3]}}, "title", ["figure.title = 3"]),
        ({"scenario": {"preset": "tiny", "layout_seed": 3}}, "layout_seed", ["layouts"]),
        ({"scenario": {"preset": "tiny", 3: 1}}, "scenario", ["key 3"]),
        ({"algorithms": {"random": {3: 1}}}, "random", ["key 3"]),
        ({"sweep": {None: [1, 2]}}, "sweep", ["key None"]),
        ({"sweep": "n_nodes"}, "sweep", ["[sweep]"]),
        ({"description": 3}, "description", ["description = 3"]),
        ({"layouts": 2.5}, "layouts", ["layouts = 2.5"]),
    ],
)
def test_malformed_experiment_fields(fields, field, words):
    with pytest.raises(ConfigError) as info:
        experiment(**fields)
    assert info.value.field == field
    for word in words:
        assert word in str(info.value)


def test_non_string_top_level_keys_and_non_utf8_files(tmp_path):
    with pytest.raises(ConfigError, match="key 3"):
        Experiment.from_dict({3: 1, "algorithms": {"random": {}}})
    path = tmp_path / "latin1.toml"
    path.write_bytes('name = "café"\n[algorithms.random]\n'.encode("latin-1"))
    with pytest.raises(ConfigError, match="not a UTF-8 text file"):
        Experiment.from_toml(path)
    line = one_line(cli("run", str(path), "--store", str(tmp_path / "s.sqlite")))
    assert str(path) in line and "UTF-8" in line and "0xe9" in line


# ------------------------------------------------------------------ sizes


def test_sizes_that_cannot_fit_fail_fast_with_the_size_and_the_limit(monkeypatch):
    from swiptopt.scenario import Scenario

    def no_work(*args, **kwargs):
        raise AssertionError("a scenario was built before the size check")

    # an 800 k-point sweep: refused on the count, before a single scenario is validated
    monkeypatch.setattr(Scenario, "from_dict", no_work)
    with pytest.raises(ConfigError) as info:
        experiment(sweep={"split_ratio": [i / 800_000 for i in range(800_000)]}, layouts=1)
    assert "800,000 sweep points" in str(info.value) and "100,000" in str(info.value)
    assert "SWIPTOPT_MAX_TASKS" in str(info.value) and info.value.field == "sweep"
    with pytest.raises(ConfigError, match=r"100,000 layouts x 1,000 \(algorithm, seed\) pairs\): 100,000,000, over"):
        experiment(layouts=100_000, seeds=1000)
    with pytest.raises(ConfigError, match="evaluation episodes .* SWIPTOPT_MAX_EVALUATION_EPISODES"):
        experiment(layouts=1000, episodes=100_000)


def test_limits_are_overridable_by_the_environment(monkeypatch):
    assert limits() == Limits()
    assert set(ENVIRONMENT.values()) == {"SWIPTOPT_" + k.upper() for k in Limits.__dataclass_fields__}
    monkeypatch.setenv("SWIPTOPT_MAX_TASKS", "5")
    with pytest.raises(ConfigError, match=r"tasks .*: 6, over the limit of 5 \(set SWIPTOPT_MAX_TASKS"):
        experiment(layouts=6)
    assert len(experiment(layouts=5).tasks()) == 5
    monkeypatch.setenv("SWIPTOPT_MAX_TASKS", "lots")
    with pytest.raises(ConfigError, match="SWIPTOPT_MAX_TASKS = 'lots' must be a positive integer") as info:
        experiment()
    assert info.value.field == "SWIPTOPT_MAX_TASKS"


def test_cli_reports_a_size_limit_in_one_line(tmp_path):
    path = tmp_path / "big.toml"
    path.write_text('name = "big"\n[scenario]\npreset = "paper"\ncell_size_m = 0.01\n[algorithms.random]\n')
    line = one_line(cli("run", str(path), "--store", str(tmp_path / "s.sqlite")))
    assert "cell_size_m = 0.01" in line and "10,000 x 10,000 x 5,000" in line and "SWIPTOPT_MAX_CELLS" in line
    result = cli("run", str(path), "--store", str(tmp_path / "s.sqlite"), "--quick",
                 env_extra={"SWIPTOPT_MAX_CELLS": "5e11"})
    assert "SWIPTOPT_MAX_CELLS = '5e11' must be a positive integer" in one_line(result)


# ------------------------------------------------------------------ figures and LaTeX


def run_small(tmp_path, **fields):
    # a fading channel: the runner's exact optimum of deterministic tiny scenarios (a search of
    # seconds) is not what these tests are about
    fields.setdefault("scenario", {"preset": "tiny", "name": "small", "channel": "rician"})
    exp = experiment(layouts=1, episodes=1, **fields)
    store = ResultStore(tmp_path / "r.sqlite")
    execute(exp, store, workers=1)
    return exp, store


def test_figure_against_a_named_sweep_value_with_a_second_swept_key(tmp_path):
    exp, store = run_small(
        tmp_path, sweep={"harvester": ["linear", "logistic"], "n_nodes": [2, 3]},
        algorithms={"random": {}, "greedy": {}}, figure={"metric": "data_bits"},
    )
    with store:
        figure = plots.experiment_figure(exp, store, tmp_path / "fig")
    assert not figure.skipped
    assert sorted(p.name for p in figure.paths) == ["t.csv", "t.pdf", "t.png"]
    lines = (tmp_path / "fig" / "t.csv").read_text().splitlines()
    assert lines[0] == "algorithm,n_nodes,harvester,data_bits_mean,ci95,min,max,n,missing"
    # one line per algorithm and node count, each over both harvesters
    assert sorted(tuple(line.split(",")[:3]) for line in lines[1:]) == sorted(
        (a, n, h) for a in ("random", "greedy") for n in ("2", "3") for h in ("linear", "logistic")
    )


def test_figure_without_results_is_skipped_with_the_reason(tmp_path):
    exp = experiment(sweep={"n_nodes": [2, 3]}, figure={"metric": "return"})
    with ResultStore(tmp_path / "empty.sqlite") as store:
        figure = plots.experiment_figure(exp, store, tmp_path / "fig")
    assert figure.paths == [] and "none of its results" in figure.skipped
    assert not (tmp_path / "fig").exists()


def test_figure_files_never_leave_the_output_directory(tmp_path):
    with pytest.raises(ConfigError):
        plots._output_path(tmp_path, "../evil.png")
    with pytest.raises(ConfigError):
        plots._output_path(tmp_path, "/tmp/evil.png")
    assert plots._output_path(tmp_path, "ok.png") == tmp_path / "ok.png"


@pytest.mark.parametrize(
    "old, new, words",
    [
        ('"name": "t"', '"name": "../evil"', ["name = '../evil'"]),
        ('"name": "t"', '"name": "/tmp/evil"', ["name = '/tmp/evil'"]),
        ('"figure": {"metric": "return"}', '"figure": {"metric": "return", "x": "split_ratio"}',
         ["figure.x = 'split_ratio' is not swept"]),
        ('"sweep": {"n_nodes": [2, 3]}', '"sweep": {}', ["[figure] needs a [sweep]"]),
    ],
)
def test_plot_refuses_a_stored_experiment_it_cannot_draw_safely(tmp_path, old, new, words):
    _, store = run_small(tmp_path / "run", sweep={"n_nodes": [2, 3]}, figure={"metric": "return"})
    store.close()
    store_path = tmp_path / "run" / "r.sqlite"
    with sqlite3.connect(store_path) as db:  # a store written by hand or by an old version
        assert db.execute("UPDATE runs SET config = replace(config, ?, ?)", (old, new)).rowcount == 1
        assert new in db.execute("SELECT config FROM runs").fetchone()[0]
    outdir = tmp_path / "out" / "fig"
    line = one_line(cli("plot", str(store_path), "--outdir", str(outdir)))
    for word in words:
        assert word in line
    assert not any(p.name.startswith(("evil", "t.")) for p in tmp_path.rglob("*"))


def latex_rows(text):
    return [line for line in text.splitlines() if line.endswith(r"\\") or line.endswith(r"\hline")]


def unescaped(line, char):
    return line.replace("\\" + char, "").count(char)


def test_latex_escapes_every_cell_and_heading(tmp_path):
    hostile = [r"\input{/etc/hostname}", "a & b", "50% #1 $x$ ^_~{} <|>"]
    exp, store = run_small(tmp_path, sweep={"name": hostile}, algorithms={"random": {}, "greedy": {}},
                           baseline="random")
    with store:
        rows, _ = tables.aggregate(exp, store)
        pairs = tables.paired(exp, store)
    for text, columns in ((tables.to_latex(rows), len(tables._headings(rows))),
                          (tables.render_paired(pairs, "latex"), 2 + len(tables.PAIRED))):
        assert r"\input{" not in text and r"\textbackslash{}input\{/etc/hostname\}" in text
        assert r"a \& b" in text and r"50\% \#1 \$x\$ \textasciicircum{}\_\textasciitilde{}\{\}" in text
        body = latex_rows(text)
        assert len(body) >= 3
        for line in body:
            if line.startswith("\\hline") and "&" not in line:
                continue
            assert unescaped(line, "&") == columns - 1, line  # no cell adds a column
            assert unescaped(line, "$") % 2 == 0, line  # math only in matched pairs
            # every backslash starts a known macro or an escape
            stripped = line
            for macro in (r"\textbackslash{}", r"\textasciicircum{}", r"\textasciitilde{}", r"\textless{}",
                          r"\textgreater{}", r"\textbar{}", r"\pm", r"\times", r"\hline", r"\\"):
                stripped = stripped.replace(macro, "")
            for esc in "{}$&#%_":
                stripped = stripped.replace("\\" + esc, "")
            assert "\\" not in stripped, line


def test_latex_escape_maps_each_special_character():
    assert tables.latex_escape(r"\{}$&#%_^~") == (
        r"\textbackslash{}\{\}\$\&\#\%\_\textasciicircum{}\textasciitilde{}"
    )
    assert tables.latex_escape("1.5 ± 0.2, 2×, 1–2, é\nx") == r"1.5 $\pm$ 0.2, 2$\times$, 1--2, é x"


def test_a_run_on_a_walled_volume_completes_for_every_planner(tmp_path):
    path = tmp_path / "wall.toml"
    path.write_text(
        'name = "wall"\nlayouts = 1\nepisodes = 1\n[scenario]\npreset = "paper"\nn_nodes = 12\n'
        '[[scenario.obstacles]]\nkind = "box"\nmin_m = [60, 0, 0]\nmax_m = [70, 100, 50]\n'
        "[algorithms.kmeans_tsp]\ntsp_time_limit_s = 0.2\n[algorithms.lawnmower]\n[algorithms.greedy]\n"
    )
    exp = Experiment.from_toml(path)
    with ResultStore(tmp_path / "s.sqlite") as store:
        report = execute(exp, store, workers=1)
        assert report.ran == 3 and store.count() == 3
        rows, missing = tables.aggregate(exp, store)
    assert missing == 0 and all(r.summaries["data_bits"].mean > 0 for r in rows)


def test_table_one_replay_is_a_setting_that_needs_the_python_loop(tmp_path):
    from swiptopt.benchmark.algorithms import build_policy, resolve_settings
    from swiptopt.env import AuvSwiptEnv

    resolved = resolve_settings("q_learning", {"replay_size": 1000, "backend": "python"})
    assert (resolved["replay_size"], resolved["replay_batch"]) == (1000, 4)
    with pytest.raises(ConfigError,
                       match=r"algorithms\.sarsa\.replay_size = 1000 needs algorithms\.sarsa\.backend = 'python'"):
        resolve_settings("sarsa", {"replay_size": 1000})
    # refused with the experiment, before any task runs
    with pytest.raises(ConfigError, match="replay_size"):
        experiment(algorithms={"q_learning": {"replay_size": 10}})
    # the setting reaches the agent: replay changes what it learns
    env = AuvSwiptEnv(preset="tiny")
    plain = build_policy("q_learning", env, resolve_settings("q_learning", {"train_episodes": 30, "backend": "python"}),
                         seed=0)
    replayed = build_policy(
        "q_learning", env,
        resolve_settings("q_learning", {"train_episodes": 30, "backend": "python", "replay_size": 50}), seed=0
    )
    assert replayed.config.replay_size == 50 and replayed.config.replay_batch == 4
    assert not (plain.q_table_ == replayed.q_table_).all()
