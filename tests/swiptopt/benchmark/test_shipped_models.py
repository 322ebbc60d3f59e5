"""The models shipped with swiptopt: the manifest vouches for every file, compare loads them,
and retraining reproduces a shipped model's evaluation exactly."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import pytest

from rl.deep import file_sha256, read_manifest, read_weights
from swiptopt.benchmark.algorithms import ALGORITHMS
from swiptopt.benchmark.experiment import builtin_experiments
from swiptopt.benchmark.runner import PRETRAINED_DIR, check_retrain, execute, models_to_train
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
def test_every_model_compare_needs_is_shipped(suite, tmp_path):
    """`compare` (both suites, full budgets, a new store) trains nothing: each deep-RL task's
    model is in the shipped directory, vouched for by its manifest; without it, every
    contender's three training seeds would each train one model (trained across layouts)."""
    experiment = builtin_experiments()[suite]
    contenders = sorted(a for a in experiment.algorithms if ALGORITHMS[a].trained_model is not None)
    with ResultStore(tmp_path / "s.sqlite") as store:
        assert models_to_train(experiment, store, (str(PRETRAINED_DIR),)) == []
        assert sorted(models_to_train(experiment, store)) == sorted(contenders * 3)


def test_compare_says_first_when_the_installation_names_no_shipped_model(tmp_path, monkeypatch):
    """Models are named for the versions of torch, SB3, sb3-contrib and Gymnasium: an
    installation with others finds none of the shipped models, and compare says so (how
    many, which, and why) before it starts training them; with the pinned ones, nothing."""
    import io

    from rich.console import Console

    import rl.deep
    from swiptopt.cli import _say_what_trains

    experiments = [builtin_experiments()[name] for name in ("compare", "harbour")]
    with ResultStore(tmp_path / "s.sqlite") as store:
        said = io.StringIO()
        _say_what_trains(Console(file=said, width=400), experiments, store)
        assert said.getvalue() == ""
        pinned = rl.deep.model_versions()
        monkeypatch.setattr(rl.deep, "model_versions", lambda: {**pinned, "torch": "0.1"})
        _say_what_trains(Console(file=said, width=400), experiments, store)
        _say_what_trains(Console(file=said, width=400), [e.quick() for e in experiments], store, quick=True)
    lines = said.getvalue().splitlines()
    assert len(lines) == 2, lines
    # standard: PPO, DQN, stop-choosing PPO; harbour: PPO, SAC, stop-choosing PPO; 3 training
    # seeds each (one with --quick)
    assert lines[0].startswith("18 deep-RL models (3 dqn, 6 ppo, 3 sac, 6 stop_ppo) are neither")
    assert lines[1].startswith("6 deep-RL models (1 dqn, 2 ppo, 1 sac, 2 stop_ppo) are neither")
    assert all("torch 0.1" in line for line in lines)
    assert lines[0].endswith("trained now, which takes hours on 2 cores") and lines[1].endswith("trained now")


def test_the_packages_that_name_a_model_are_pinned_for_every_python():
    """constraints.txt pins torch, SB3, sb3-contrib and Gymnasium without a Python marker,
    at the versions installed here (the shipped models' names hold them), so that `make`
    on any Python installs the versions the shipped models are named for."""
    from pathlib import Path

    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    from rl.deep import model_versions

    root = Path(__file__).resolve().parents[3]
    pins = {}
    for line in (root / "constraints.txt").read_text(encoding="utf-8").splitlines():
        if line.strip() and not line.startswith("#"):
            requirement = Requirement(line)
            pins[canonicalize_name(requirement.name)] = requirement
    for package, installed in model_versions().items():
        requirement = pins[canonicalize_name(package)]
        assert requirement.marker is None, f"{package} is pinned for one Python only: {requirement}"
        assert str(requirement.specifier) == f"=={installed}", (package, installed, str(requirement))
