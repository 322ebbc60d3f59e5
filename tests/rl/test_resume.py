"""Exact resume (:mod:`rl.resume`): a training cut short and gone on from its saved state
trains the uninterrupted run's model, bit for bit, for every learner the benchmark trains;
a state file is data, and one that does not fit is refused in one line."""

import zipfile

import numpy as np
import pytest

import planners.stops  # noqa: F401  (registers the stop-choice envs)
import swiptopt
from rl.deep import lineage_hash, reporting_progress, resumable, state_path, train_deep, train_or_load_deep

pytest.importorskip("stable_baselines3")

TINY = swiptopt.Scenario.preset("tiny")
HARBOUR = swiptopt.Scenario.preset("harbour", n_nodes=4, episode_steps=20)
FLEET = swiptopt.Scenario.preset("paper", n_nodes=8, n_auvs=2, episode_steps=20)
NET = {"net_arch": [16]}

#: (algorithm, scenario, total steps, train_deep arguments): every kind of learner the
#: benchmark trains, at tiny sizes (a rollout of PPO is n_envs x n_steps steps).
RUNS = {
    "sac": ("sac", HARBOUR, 256, dict(world="continuous", n_envs=4, layout_seeds=(0, 1), hyperparams={
        "buffer_size": 1_000, "learning_starts": 40, "batch_size": 32, "gradient_steps": 2})),
    "ppo-continuous": ("ppo", HARBOUR, 512, dict(world="continuous", n_envs=4, hyperparams={
        "n_steps": 32, "batch_size": 64, "n_epochs": 2})),
    "dqn": ("dqn", TINY, 256, dict(n_envs=2, hyperparams={
        "buffer_size": 1_000, "learning_starts": 32, "train_freq": 2, "target_update_interval": 50,
        "exploration_steps": 100})),
    "stop-ppo": ("maskable_ppo", TINY, 128, dict(env_id="swiptopt/AuvSwiptStops-v0", n_envs=2, hyperparams={
        "n_steps": 16, "batch_size": 32, "n_epochs": 2})),
    "shared-ppo": ("ppo", FLEET, 512, dict(env_id="swiptopt/FleetShared", n_envs=2, hyperparams={
        "n_steps": 32, "batch_size": 64, "n_epochs": 2})),
}


class Crash(Exception):
    """The end of a session in the middle of a training."""


def _parameters(model):
    return {k: v.detach().numpy().copy() for k, v in model.policy.state_dict().items()}


def _same_model(a, b):
    pa, pb = _parameters(a.model), _parameters(b.model)
    assert pa.keys() == pb.keys()
    for key in pa:
        np.testing.assert_array_equal(pa[key], pb[key], err_msg=key)
    np.testing.assert_array_equal(a.episode_returns, b.episode_returns)


def _crash_after(monkeypatch, saves):
    """Save a state at every rollout's start and stop the training after ``saves`` saves."""
    import rl.deep
    import rl.resume

    monkeypatch.setattr(rl.deep, "STATE_INTERVAL_S", 0.0)
    original, count = rl.resume.save_state, [0]

    def save_then_crash(*args, **kwargs):
        original(*args, **kwargs)
        count[0] += 1
        if count[0] == saves:
            raise Crash

    monkeypatch.setattr(rl.resume, "save_state", save_then_crash)


@pytest.mark.parametrize("name", list(RUNS))
def test_a_training_cut_short_goes_on_to_the_uninterrupted_runs_model(name, tmp_path, monkeypatch):
    algorithm, scenario, steps, kwargs = RUNS[name]
    kwargs = {**kwargs, "policy_kwargs": NET}
    whole = train_deep(algorithm, scenario, steps, 5, **kwargs)
    with monkeypatch.context() as patch:
        _crash_after(patch, 3)
        with pytest.raises(Crash):
            train_or_load_deep(tmp_path, algorithm, scenario, steps, 5, **kwargs)
    from rl.deep import DeepConfig
    from rl.resume import read_state

    config = DeepConfig(algorithm, steps, 5, kwargs["hyperparams"], NET, kwargs.get("layout_seeds"),
                        kwargs.get("world", "grid"), kwargs["n_envs"], kwargs.get("env_id"))
    state = state_path(tmp_path, config, scenario)
    header, _ = read_state(state, header_only=True)
    assert 0 < header["steps"] < steps and header["lineage"] == lineage_hash(config, scenario)
    reports = []
    with reporting_progress(lambda done, total, finished: reports.append(done)):
        resumed = train_or_load_deep(tmp_path, algorithm, scenario, steps, 5, **kwargs)
    assert reports[0] == header["steps"] and reports[-1] == steps  # it went on from the state, not from 0
    assert not resumed.loaded and resumed.note == ""
    _same_model(whole, resumed)
    assert len(resumed.episode_returns) > 0
    assert not state.exists()  # a finished run drops its state unless asked to keep it


def test_a_longer_run_goes_on_from_the_kept_state_of_a_shorter_one(tmp_path):
    algorithm, scenario, steps, kwargs = RUNS["sac"]
    kwargs = {**kwargs, "policy_kwargs": NET}
    short = train_or_load_deep(tmp_path, algorithm, scenario, steps, 2, keep_state=True, **kwargs)
    from rl.resume import read_state

    (state,) = tmp_path.glob("*.state.npz")
    assert read_state(state, header_only=True)[0]["steps"] == steps
    reports = []
    with reporting_progress(lambda done, total, finished: reports.append(done)):
        longer = train_or_load_deep(tmp_path, algorithm, scenario, 2 * steps, 2, keep_state=True, **kwargs)
    assert reports[0] == steps
    _same_model(train_deep(algorithm, scenario, 2 * steps, 2, **kwargs), longer)
    assert read_state(state, header_only=True)[0]["steps"] == 2 * steps
    # the shorter run's model is stored, and a shorter run never writes over a longer one's state
    again = train_or_load_deep(tmp_path, algorithm, scenario, steps, 2, keep_state=True, **kwargs)
    assert again.loaded and again.sha256 == short.sha256
    assert read_state(state, header_only=True)[0]["steps"] == 2 * steps


def test_a_state_that_does_not_fit_is_refused_and_train_or_load_trains_from_the_start(tmp_path):
    algorithm, scenario, steps, kwargs = RUNS["ppo-continuous"]
    kwargs = {**kwargs, "policy_kwargs": NET}
    path = tmp_path / "run.state.npz"
    train_deep(algorithm, scenario, steps // 2, 1, state_file=path, **kwargs)
    with pytest.raises(swiptopt.ConfigError, match="another training run") as info:  # another seed: another lineage
        train_deep(algorithm, scenario, steps, 2, state_file=path, **kwargs)
    assert info.value.field == "state_file"

    # a state whose actions do not replay to its observation is refused, naming the file
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["actions"] = arrays["actions"][::-1].copy()
    np.savez(path, **arrays)
    with pytest.raises(swiptopt.ConfigError, match=r"run\.state\.npz: cannot resume.*replaying"):
        train_deep(algorithm, scenario, steps, 1, state_file=path, **kwargs)

    # a state file holding a pickle is never unpickled: it is not a state
    arrays["header"] = np.array([{"format": "swiptopt-training-state-1"}], dtype=object)
    np.savez(path, **arrays)
    with pytest.raises(swiptopt.ConfigError, match="is not a swiptopt training state"):
        train_deep(algorithm, scenario, steps, 1, state_file=path, **kwargs)

    # train_or_load_deep deletes a state it cannot use and trains from the start, saying so
    from rl.deep import DeepConfig

    config = DeepConfig(algorithm, steps, 1, kwargs["hyperparams"], NET, None, "continuous", kwargs["n_envs"])
    state = state_path(tmp_path / "models", config, scenario)
    state.parent.mkdir()
    with zipfile.ZipFile(state, "w") as broken:
        broken.writestr("header.npy", b"not an array")
    result = train_or_load_deep(tmp_path / "models", algorithm, scenario, steps, 1, **kwargs)
    assert "not a readable training state" in result.note and not state.exists()
    _same_model(train_deep(algorithm, scenario, steps, 1, **kwargs), result)


def test_runs_whose_training_depends_on_their_total_keep_no_state(tmp_path):
    from rl.deep import DeepConfig

    dqn = DeepConfig("stable_baselines3:DQN", 256, 0, RUNS["dqn"][3]["hyperparams"] | {}, NET, n_envs=2)
    dqn = dqn.replace(hyperparams={k: v for k, v in dqn.hyperparams.items() if k != "exploration_steps"})
    assert not resumable(dqn, TINY)  # SB3's own DQN explores over a share of its total
    assert resumable(DeepConfig("dqn", 256, 0, RUNS["dqn"][3]["hyperparams"], NET, n_envs=2), TINY)
    with pytest.raises(swiptopt.ConfigError, match="cannot go on from a saved state") as info:
        train_deep("stable_baselines3:DQN", TINY, 256, 0, hyperparams=dqn.hyperparams, policy_kwargs=NET, n_envs=2,
                   state_file=tmp_path / "s.state.npz")
    assert info.value.field == "state_file"
    train_or_load_deep(tmp_path, "stable_baselines3:DQN", TINY, 256, 0, hyperparams=dqn.hyperparams,
                       policy_kwargs=NET, n_envs=2, keep_state=True)
    assert not list(tmp_path.glob("*.state.npz"))


def test_the_runner_asks_only_each_lineages_longest_training_to_keep_its_state():
    from swiptopt.benchmark.experiment import builtin_experiments
    from swiptopt.benchmark.runner import KEEP_STATE, _batches

    tasks = builtin_experiments()["learning-curve"].quick().tasks()
    trainers, followers = _batches(tasks, 2, "/tmp/models", keep_state=True)
    kept = [d for batch in trainers for d in batch if d.get(KEEP_STATE)]
    assert kept and all(d["checkpoints"] is not None for d in kept)
    assert not any(d.get(KEEP_STATE) for batch in followers for d in batch)
    assert not any(d.get(KEEP_STATE) for stage in _batches(tasks, 2, "/tmp/models") for b in stage for d in b)


def test_what_a_killed_writer_left_behind_is_deleted_and_a_live_ones_kept(tmp_path):
    import os
    import subprocess
    import sys

    from rl.deep import DeepConfig, _check_state

    algorithm, scenario, steps, kwargs = RUNS["ppo-continuous"]
    config = DeepConfig(algorithm, steps, 1, kwargs["hyperparams"], NET, None, "continuous", kwargs["n_envs"])
    state = state_path(tmp_path, config, scenario)
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    orphan = tmp_path / f".{state.name}.{int(gone.stdout)}.tmp"
    alive = tmp_path / f".{state.name}.{os.getpid()}.tmp"
    other = tmp_path / f".other.state.npz.{int(gone.stdout)}.tmp"
    for path in (orphan, alive, other):
        path.write_bytes(b"half a state")
    assert _check_state(state, tmp_path, config, scenario, {}) == ""
    assert not orphan.exists() and alive.exists() and other.exists()
