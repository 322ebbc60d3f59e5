"""Experiments in either world: the world is validated and named before any task runs,
algorithms run only in the worlds they declare, grid tasks keep their keys, and the harbour
suite (the continuous world) runs, prints and repeats like the standard one."""

import json
import os
import subprocess
import sys
import textwrap

import pytest

from swiptopt.benchmark.algorithms import ALGORITHMS, check_world_of
from swiptopt.benchmark.experiment import Experiment, Task, builtin_experiments
from swiptopt.benchmark.runner import uses_ompl
from swiptopt.cli import main
from swiptopt.errors import ConfigError
from swiptopt.worlds import WORLDS


def cli(*args):
    return subprocess.run([sys.executable, "-m", "swiptopt.cli", *args], capture_output=True, text=True,
                          env=dict(os.environ))


def one_line(result):
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr and result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    return lines[0]


# ------------------------------------------------------------------ keys

#: Task keys computed on main before experiments had a world (commit c98fddf), for the
#: experiment below: a grid task's key must not change, or every stored result is lost.
#: (PPO's keys changed since, with its settings: vectorised training added n_envs,
#: n_epochs, ent_coef, gae_lambda and clip_range to every PPO task.)
KEYS_ON_MAIN = {
    ("random", 3000): "d0fcd640294622974819c80fb13f219606d7fddf06c2cfd1212fa8099fa72ca0",
    ("kmeans_tsp", 3000): "892cf8e373f7159a33adbf0fdc335115bf76dab689b054c2dcc0d5c9362c91bf",
}


def keys_experiment(**fields):
    return Experiment(name="keys", scenario={"preset": "tiny"}, layouts=[3], training_layouts=[1, 2], episodes=2,
                      **{"algorithms": {"random": {}, "kmeans_tsp": {}, "ppo": {"training": "across_layouts"}},
                         **fields})


def test_grid_task_keys_are_those_computed_before_worlds():
    for world in (None, "grid"):  # the default and the grid named
        e = keys_experiment() if world is None else keys_experiment(world=world)
        keys = {(t.algorithm, t.seed): t.key for t in e.tasks()}
        assert {k: keys[k] for k in KEYS_ON_MAIN} == KEYS_ON_MAIN
        assert all(t.world == "grid" for t in e.tasks())


def test_a_continuous_task_has_a_key_of_its_own_and_round_trips():
    grid = keys_experiment(algorithms={"random": {}, "ppo": {"training": "across_layouts"}})
    continuous = keys_experiment(algorithms={"random": {}, "ppo": {"training": "across_layouts"}}, world="continuous")
    pairs = list(zip(grid.tasks(), continuous.tasks()))
    assert all(g.key != c.key and c.world == "continuous" for g, c in pairs)
    assert all(Task(**json.loads(json.dumps(c.to_dict()))).key == c.key for _, c in pairs)
    # the stored configuration reads back as the same experiment; one stored before worlds is the grid's
    assert Experiment.from_dict(json.loads(json.dumps(continuous.to_dict()))) == continuous
    old = {k: v for k, v in grid.to_dict().items() if k != "world"}
    assert Experiment.from_dict(old) == grid
    # --quick keeps the world
    assert {t.world for t in continuous.quick().tasks()} == {"continuous"}


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize("world, words", [
    ("grd", ["world = 'grd' is not a world", "did you mean 'grid'", "'grid', 'continuous'"]),
    ("Continuous", ["world = 'Continuous'", "'grid', 'continuous'"]),
    (3, ["world = 3 is not a world"]),
    (None, ["world = None"]),
])
def test_an_unknown_world_is_one_line(world, words):
    with pytest.raises(ConfigError) as info:
        keys_experiment(world=world)
    assert info.value.field == "world" and "\n" not in str(info.value)
    assert all(w in str(info.value) for w in words), str(info.value)


@pytest.mark.parametrize("name, world, words", [
    ("q_learning", "continuous", ["algorithms.q_learning", "Q-learning runs in the grid world only",
                                  "world = 'continuous'", "sac", "ompl_tour", "straight_line"]),
    ("dqn", "continuous", ["algorithms.dqn", "DQN runs in the grid world only"]),
    ("kmeans_tsp", "continuous", ["k-means + TSP runs in the grid world only"]),
    ("sac", "grid", ["algorithms.sac", "SAC runs in the continuous world only", "world = 'grid'", "q_learning"]),
    ("ompl_tour", "grid", ["OMPL tour runs in the continuous world only"]),
    ("straight_line", "grid", ["straight line runs in the continuous world only"]),
])
def test_an_algorithm_outside_its_worlds_is_refused_naming_them(name, world, words):
    with pytest.raises(ConfigError) as info:
        Experiment(name="w", scenario={"preset": "tiny"}, algorithms={"random": {}, name: {}}, world=world)
    message = str(info.value)
    assert info.value.field == "world" and "\n" not in message
    assert all(w in message for w in words), message


def test_every_algorithm_declares_its_worlds():
    assert all(a.worlds and set(a.worlds) <= set(WORLDS) for a in ALGORITHMS.values())
    both = {n for n, a in ALGORITHMS.items() if set(a.worlds) == set(WORLDS)}
    assert both == {"ppo", "stop_ppo", "random"}
    assert {n for n, a in ALGORITHMS.items() if a.worlds == ("continuous",)} == {"sac", "ompl_tour", "straight_line"}
    for name, algorithm in ALGORITHMS.items():
        for world in algorithm.worlds:
            check_world_of(name, world)  # no error


def test_the_harbour_suite_is_the_continuous_world_with_a_straight_line_baseline():
    harbour = builtin_experiments()["harbour"]
    assert harbour.world == "continuous" and harbour.scenario == {"preset": "harbour"}
    assert set(harbour.algorithms) == {"ompl_tour", "straight_line", "sac", "ppo", "stop_ppo", "random"}
    assert harbour.baseline == "straight_line" and harbour.layout_seeds() == tuple(range(8))
    assert harbour.training_layouts == harbour.layout_seeds()
    assert all(t.world == "continuous" for t in harbour.tasks())
    assert builtin_experiments()["compare"].world == "grid"


def test_ompl_tasks_are_named_by_their_algorithm():
    harbour = builtin_experiments()["harbour"].quick()
    by_algorithm = {t.algorithm: uses_ompl(t.to_dict()) for t in harbour.tasks()}
    assert by_algorithm == {"ompl_tour": True, "straight_line": False, "sac": False, "ppo": False, "stop_ppo": False,
                            "random": False}
    grid = Experiment(name="g", scenario={"preset": "tiny"},
                      algorithms={"kmeans_tsp": {"tour_costs": "ompl"}, "greedy": {}})
    assert {t.algorithm: uses_ompl(t.to_dict()) for t in grid.tasks()} == {"kmeans_tsp": True, "greedy": False}


BAD_FILES = {
    "unknown": ('name = "w"\nworld = "ocean"\n[scenario]\npreset = "harbour"\n[algorithms.random]\n',
                ["world = 'ocean' is not a world"]),
    "in scenario": ('name = "w"\n[scenario]\npreset = "harbour"\nworld = "continuous"\n[algorithms.random]\n',
                    ["scenario.world", "world = 'continuous'", "top of the file"]),
    "in an algorithm": ('name = "w"\nworld = "continuous"\n[scenario]\npreset = "harbour"\n'
                        '[algorithms.random]\nworld = "continuous"\n', ["algorithms.random.world", "top of the file"]),
    "swept": ('name = "w"\n[scenario]\npreset = "tiny"\n[sweep]\nworld = ["grid", "continuous"]\n'
              '[algorithms.random]\n', ["sweep.world", "one experiment per world"]),
    "mismatch": ('name = "w"\nworld = "continuous"\n[scenario]\npreset = "harbour"\n[algorithms.q_learning]\n',
                 ["algorithms.q_learning", "grid world only"]),
}


@pytest.mark.parametrize("case", list(BAD_FILES))
def test_a_bad_world_in_a_file_exits_2_in_one_line_before_any_task(tmp_path, case):
    text, words = BAD_FILES[case]
    path = tmp_path / "w.toml"
    path.write_text(text)
    store = tmp_path / "s.sqlite"
    line = one_line(cli("run", str(path), "--store", str(store)))
    assert str(path) in line and all(w in line for w in words), line
    assert not store.exists()


def test_compare_refuses_an_unknown_suite_and_describes_both(capsys):
    assert main(["compare", "--suite", "harbor"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "'standard', 'harbour', 'all'" in err.replace('"', "'")
    assert main(["compare", "--help"]) == 0
    out = capsys.readouterr().out
    assert "standard suite" in out and "harbour suite" in out and "continuous" in out
    assert all(name in out for name in builtin_experiments()["harbour"].algorithms)


PLUGIN = textwrap.dedent('''
    from swiptopt.benchmark.algorithms import Algorithm


    class Hover:
        def predict(self, obs, deterministic=True):
            return [0.0, 0.0, 0.0]


    def hover():
        return Algorithm("ignored", "hover", "planner", {}, lambda env, settings, seed, context: Hover(),
                         worlds=("continuous",))


    def nowhere():
        return Algorithm("ignored", "hover", "planner", {}, lambda env, settings, seed, context: Hover(),
                         worlds=("ocean",))
''')


@pytest.mark.parametrize("name, settings", [
    ("random", {}), ("random", {"train_episodes": 10}), ("ppo", {}), ("ompl_tour", {}), ("straight_line", {}),
])
def test_the_continuous_world_has_one_observation(name, settings):
    """Every algorithm acts on the vector observation there: another is refused, naming it."""
    fields = dict(name="obs", scenario={"preset": "harbour"}, world="continuous")
    with pytest.raises(ConfigError) as info:
        Experiment(**fields, algorithms={name: {**settings, "observation": "tabular"}})
    message = str(info.value)
    assert f"algorithms.{name}.observation = 'tabular'" in message and "'vector'" in message
    assert info.value.field == "observation" and "\n" not in message
    vector = Experiment(**fields, algorithms={name: {**settings, "observation": "vector"}})
    assert vector.tasks() == Experiment(**fields, algorithms={name: settings}).tasks()
    assert vector.quick().tasks() == Experiment(**fields, algorithms={name: settings}).quick().tasks()


def test_a_plugin_declares_its_worlds(tmp_path, monkeypatch):
    (tmp_path / "swiptopt_test_world_plugin.py").write_text(PLUGIN, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    fields = dict(name="p", scenario={"preset": "harbour"}, algorithms={"hover": {}})
    assert Experiment(**fields, plugins={"hover": "swiptopt_test_world_plugin:hover"}, world="continuous")
    with pytest.raises(ConfigError, match="hover runs in the continuous world only"):
        Experiment(**fields, plugins={"hover": "swiptopt_test_world_plugin:hover"})
    with pytest.raises(ConfigError, match=r"worlds \('ocean',\).*'grid', 'continuous'"):
        Experiment(**{**fields, "algorithms": {"nowhere": {}}},
                   plugins={"nowhere": "swiptopt_test_world_plugin:nowhere"})


# ------------------------------------------------------------------ the harbour suite


def test_compare_quick_harbour_prints_the_same_tables_with_one_worker_or_two(tmp_path, capsys):
    """The harbour suite at --quick (2 layouts, SAC, PPO and the stop-choosing agent at small budgets, one training
    seed, the OMPL tour at its quick budget): run twice, the second time on two workers and a
    new store beside the first's models (so every task runs again: the OMPL tours in fresh
    processes, the deep-RL tasks on the loaded models), the same tables."""
    pytest.importorskip("planners.continuous")
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("ompl")
    args = ["compare", "--quick", "--suite", "harbour", "--format", "markdown"]
    assert main([*args, "--store", str(tmp_path / "a.sqlite"), "--workers", "1"]) == 0
    first, err = capsys.readouterr()
    assert "12 tasks: 0 already stored, 12 run" in err
    assert main([*args, "--store", str(tmp_path / "b.sqlite"), "--workers", "2"]) == 0
    second, err = capsys.readouterr()
    assert "12 tasks: 0 already stored, 12 run" in err
    assert second == first
    assert first.startswith("**harbour (continuous world)**")
    for label in ("OMPL tour", "straight line", "SAC", "PPO", "stop-choosing PPO", "random"):
        assert f"| {label} |" in first
    assert first.count("×") == 5 * 5  # the paired table: five algorithms against the straight line


def test_build_policy_reads_the_world_from_the_env():
    import numpy as np

    from swiptopt.benchmark.algorithms import build_policy
    from swiptopt.env import AuvSwiptEnv
    from swiptopt.env_continuous import AuvSwiptContinuousEnv

    env = AuvSwiptContinuousEnv(preset="harbour", n_nodes=4)
    policy = build_policy("random", env, {}, seed=7)
    actions = np.array([policy.predict(None) for _ in range(500)])
    assert actions.shape == (500, 3) and actions.dtype == np.float32
    assert np.all(actions >= -1) and np.all(actions <= 1) and np.all(np.ptp(actions, axis=0) > 1.9)
    again = build_policy("random", env, {}, seed=7)
    np.testing.assert_array_equal(actions, [again.predict(None) for _ in range(500)])  # seeded
    assert isinstance(build_policy("random", AuvSwiptEnv(preset="tiny"), {}, seed=7).predict(0), int)
    with pytest.raises(ConfigError, match="Q-learning runs in the grid world only"):
        build_policy("q_learning", env, {}, seed=0)
