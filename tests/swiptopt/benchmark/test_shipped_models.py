"""The models shipped with swiptopt: the manifest vouches for every file, compare loads them,
and retraining reproduces a shipped model's evaluation exactly."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import pytest

from rl.deep import file_sha256, read_manifest, read_weights
from swiptopt.benchmark.experiment import builtin_experiments
from swiptopt.benchmark.runner import PRETRAINED_DIR, check_retrain, execute
from swiptopt.benchmark.store import ResultStore
from swiptopt.errors import ConfigError

pytest.importorskip("stable_baselines3")


def test_every_shipped_file_is_the_one_its_manifest_records():
    manifest = read_manifest(PRETRAINED_DIR)
    files = sorted(p.name for p in PRETRAINED_DIR.glob("*.npz"))
    assert files and sorted(manifest) == files
    for name, record in manifest.items():
        assert file_sha256(PRETRAINED_DIR / name) == record["sha256"]
        header, params = read_weights(PRETRAINED_DIR / name)
        assert header["config_hash"] == record["config_hash"] and name.endswith(f"{record['config_hash']}.npz")
        assert params  # weights, nothing else


def _deep_only(name: str):
    """The suite's --quick experiment with its deep-RL algorithms only (their tasks, their keys)."""
    suite = builtin_experiments()[name].quick()
    deep = {k: v for k, v in suite.algorithms.items() if k in ("ppo", "dqn", "sac", "stop_ppo")}
    return dataclasses.replace(suite, algorithms=deep, baseline="")


@pytest.mark.parametrize("suite", ["compare"])
def test_retraining_reproduces_the_shipped_models_evaluations(suite, tmp_path):
    experiment = _deep_only(suite)
    keys = {t.key for t in experiment.tasks()}
    with ResultStore(tmp_path / "shipped" / "s.sqlite") as store:
        assert execute(experiment, store, workers=2, pretrained=(str(PRETRAINED_DIR),)).failed == 0
        shipped = store.get(keys)
    with ResultStore(tmp_path / "retrained" / "s.sqlite") as store:
        assert execute(experiment, store, workers=2).failed == 0
        retrained = store.get(keys)
    assert set(shipped) == set(retrained) == keys
    assert all(r["extra"]["model_loaded"] and r["extra"]["model_shipped"] for r in shipped.values())
    # retrained here: no shipped file used, and each model trained once (the other layouts'
    # tasks of a model trained across layouts load it from this run's own models/)
    assert not any(r["extra"]["model_shipped"] for r in retrained.values())
    assert {r["extra"]["model"] for r in retrained.values() if not r["extra"]["model_loaded"]} == {
        r["extra"]["model"] for r in retrained.values()}
    for key in keys:
        assert shipped[key]["records"] == retrained[key]["records"]
        assert shipped[key]["extra"]["model"] == retrained[key]["extra"]["model"]
    # --retrain refuses the store of shipped models' results (it would report them, not
    # retrain), before any task runs, and takes the retrained one
    with ResultStore(tmp_path / "shipped" / "s.sqlite") as store:
        with pytest.raises(ConfigError, match=r"already holds \d+ results of 'compare' .*\(dqn, ppo, stop_ppo\)"):
            check_retrain(experiment, store)
        count = store.count()
    with ResultStore(tmp_path / "retrained" / "s.sqlite") as store:
        check_retrain(experiment, store)
    result = subprocess.run([sys.executable, "-m", "swiptopt.cli", "compare", "--quick", "--suite", "standard",
                             "--retrain", "--store", str(tmp_path / "shipped" / "s.sqlite")],
                            capture_output=True, text=True)
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1 and "--retrain" in lines[0] and "new --store" in lines[0]
    with ResultStore(tmp_path / "shipped" / "s.sqlite") as store:
        assert store.count() == count


@pytest.mark.parametrize("suite", ["compare", "harbour"])
def test_every_model_compare_needs_is_shipped(suite):
    """`compare` (both suites, full budgets, a new store) trains nothing: each deep-RL task's
    model is in the shipped directory, vouched for by its manifest."""
    from rl.deep import find_model
    from swiptopt.benchmark.algorithms import ALGORITHMS, BuildContext
    from swiptopt.benchmark.experiment import SEEDS_PER_LAYOUT
    from swiptopt.scenario import Scenario

    needed = set()
    for t in builtin_experiments()[suite].tasks():
        algorithm = ALGORITHMS[t.algorithm]
        if algorithm.trained_model is None:
            continue
        context = BuildContext(Scenario.from_dict(t.scenario), t.seed % SEEDS_PER_LAYOUT, tuple(t.training_layouts),
                               None, t.world, (), (str(PRETRAINED_DIR),))
        config, scenario = algorithm.trained_model(t.settings, t.seed, context)
        found, note = find_model([PRETRAINED_DIR], config, scenario)
        assert found is not None, f"{suite}: {t.algorithm} seed {t.seed}: {note}"
        needed.add(found.name)
    # three training seeds of each deep-RL contender, one model each (trained across layouts)
    assert len(needed) == 3 * len([a for a in builtin_experiments()[suite].algorithms if ALGORITHMS[a].trains_model
                                   and ALGORITHMS[a].trained_model is not None])
