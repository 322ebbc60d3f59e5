import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import swiptopt
from rl import DeepConfig, deep_config_hash, load_deep, save_deep, train_deep, train_or_load_deep
from rl.deep import file_sha256, model_path, read_manifest, read_weights, reporting_progress
from swiptopt.env import AuvSwiptEnv

pytest.importorskip("stable_baselines3")

TINY = swiptopt.Scenario.preset("tiny")
# tiny budgets: a few hundred steps, updates early and often, small networks
SETTINGS = {
    "ppo": {"n_steps": 64, "batch_size": 32, "n_epochs": 2},
    "dqn": {"buffer_size": 2_000, "learning_starts": 64, "train_freq": 2, "target_update_interval": 100},
}
NET = {"net_arch": [32, 32]}


def _train(algorithm, seed=0, scenario=TINY, timesteps=600, **kw):
    return train_deep(algorithm, scenario, timesteps, seed, hyperparams=SETTINGS[algorithm], policy_kwargs=NET, **kw)


def _parameters(model):
    return {k: v.detach().numpy().copy() for k, v in model.policy.state_dict().items()}


def _scores(model, obs):
    import torch

    with torch.no_grad():
        t = torch.as_tensor(obs)
        if hasattr(model, "q_net"):
            return model.q_net(t).numpy()
        return model.policy.get_distribution(t).distribution.logits.numpy()


def _observations(n=200):
    env = AuvSwiptEnv(TINY, observation="vector", layout_seeds=range(20))
    rng = np.random.default_rng(0)
    out = [env.reset(seed=0)[0]]
    while len(out) < n:
        obs, _, term, trunc, _ = env.step(int(rng.integers(7)))
        out.append(obs)
        if term or trunc:
            out.append(env.reset()[0])
    return np.array(out)


@pytest.mark.parametrize("algorithm", ["ppo", "dqn"])
def test_train_save_load_act_and_evaluate_identically(algorithm, tmp_path):
    result = _train(algorithm)
    assert result.config_hash == deep_config_hash(result.config, TINY)
    assert len(result.episode_returns) >= 600 // TINY.episode_steps - 1
    # the returns collected from our info key agree with SB3's Monitor (rounded to 1e-6)
    monitor = [e["r"] for e in result.model.ep_info_buffer]
    np.testing.assert_allclose(result.episode_returns[-len(monitor):], monitor, atol=1e-5)

    path = save_deep(result, tmp_path / "model.zip")
    loaded = load_deep(path, algorithm)
    obs = _observations()
    trained_actions, _ = result.model.predict(obs, deterministic=True)
    loaded_actions, _ = loaded.predict(obs, deterministic=True)
    np.testing.assert_array_equal(trained_actions, loaded_actions)
    scores = _scores(result.model, obs)  # Q-values or action logits: equal to the last bit
    np.testing.assert_array_equal(scores, _scores(loaded, obs))
    assert np.ptp(scores, axis=0).max() > 0  # they depend on the observation
    for name, value in _parameters(result.model).items():
        np.testing.assert_array_equal(value, _parameters(loaded)[name])

    env = AuvSwiptEnv(TINY, observation="vector")
    a = swiptopt.evaluate(result.model, env, 3, seed=50)
    b = swiptopt.evaluate(loaded, env, 3, seed=50)
    assert a.records == b.records
    assert swiptopt.evaluate(result, env, 3, seed=50).records == a.records  # a result is a policy too


@pytest.mark.parametrize("algorithm", ["ppo", "dqn"])
def test_the_same_seed_trains_the_same_model(algorithm):
    first, again, other = _train(algorithm, seed=3), _train(algorithm, seed=3), _train(algorithm, seed=4)
    p1, p2, p3 = _parameters(first.model), _parameters(again.model), _parameters(other.model)
    for name in p1:
        np.testing.assert_array_equal(p1[name], p2[name])
    assert any(not np.array_equal(p1[n], p3[n]) for n in p1)
    np.testing.assert_array_equal(first.episode_returns, again.episode_returns)
    env = AuvSwiptEnv(TINY, observation="vector", layout_seeds=range(5))
    records = swiptopt.evaluate(first.model, env, 4, seed=9).records
    assert records == swiptopt.evaluate(again.model, env, 4, seed=9).records
    assert first.config_hash == again.config_hash != other.config_hash


def test_training_across_layouts():
    result = _train("ppo", layout_seeds=range(0, 50), timesteps=300)
    assert result.config.layout_seeds == range(50)
    assert result.config_hash != _train("ppo", timesteps=300).config_hash
    assert len(result.episode_returns) > 0 and np.all(np.isfinite(result.episode_returns))


def test_train_or_load_reuses_a_matching_model(tmp_path):
    first = train_or_load_deep(tmp_path, "dqn", TINY, 300, 1, hyperparams=SETTINGS["dqn"], policy_kwargs=NET)
    name = f"dqn-{first.config_hash}.npz"
    assert not first.loaded and sorted(p.name for p in tmp_path.glob("*.npz")) == [name]
    manifest = read_manifest(tmp_path)
    assert manifest[name]["sha256"] == file_sha256(tmp_path / name) == first.sha256
    assert manifest[name]["config_hash"] == first.config_hash
    second = train_or_load_deep(tmp_path, "dqn", TINY, 300, 1, hyperparams=SETTINGS["dqn"], policy_kwargs=NET)
    assert second.loaded and second.config_hash == first.config_hash and second.note == ""
    obs = _observations(50)
    np.testing.assert_array_equal(
        first.model.predict(obs, deterministic=True)[0], second.model.predict(obs, deterministic=True)[0]
    )
    for key, value in _parameters(first.model).items():
        np.testing.assert_array_equal(value, _parameters(second.model)[key])
    other = train_or_load_deep(
        tmp_path, "dqn", TINY.replace(split_ratio=0.3), 300, 1, hyperparams=SETTINGS["dqn"], policy_kwargs=NET
    )
    assert not other.loaded and len(list(tmp_path.glob("*.npz"))) == 2 and len(read_manifest(tmp_path)) == 2


def test_a_file_the_manifest_does_not_vouch_for_is_never_loaded(tmp_path):
    """A planted or altered file under a model's name is retrained over, and said so; the
    weights format holds no pickle, so even a file with one runs nothing."""
    kwargs = dict(hyperparams=SETTINGS["ppo"], policy_kwargs=NET)
    config = DeepConfig("ppo", 128, 0, SETTINGS["ppo"], NET)
    path = model_path(tmp_path, config, TINY)
    marker = tmp_path / "payload-ran"
    # an npz whose entry is a pickled object that would create the marker if unpickled
    np.savez(path, header=np.array([_Payload(marker)], dtype=object))
    result = train_or_load_deep(tmp_path, "ppo", TINY, 128, 0, **kwargs)
    assert not result.loaded and "not recorded" in result.note and not marker.exists()
    assert read_manifest(tmp_path)[path.name]["sha256"] == file_sha256(path)
    # now recorded; alter the file behind the manifest's back
    data = bytearray(path.read_bytes())
    data[-20] ^= 0xFF
    path.write_bytes(bytes(data))
    again = train_or_load_deep(tmp_path, "ppo", TINY, 128, 0, **kwargs)
    assert not again.loaded and "differs from the file recorded" in again.note
    third = train_or_load_deep(tmp_path, "ppo", TINY, 128, 0, **kwargs)
    assert third.loaded and third.note == ""
    with pytest.raises(swiptopt.ConfigError, match="not a swiptopt weights file"):
        read_weights(tmp_path / "junk.npz") if (tmp_path / "junk.npz").write_bytes(b"PK junk") else None


class _Payload:
    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def test_a_zip_checked_against_its_recorded_digest_runs_nothing_when_it_differs(tmp_path):
    import pickle
    import zipfile

    result = _train("ppo", timesteps=128)
    path = save_deep(result, tmp_path / "model.zip")
    digest = file_sha256(path)
    assert load_deep(path, "ppo", sha256=digest).predict(_observations(5), True)[0].shape == (5,)
    marker = tmp_path / "payload-ran"
    planted = tmp_path / "planted.zip"
    with zipfile.ZipFile(planted, "w") as z:
        z.writestr("data", pickle.dumps(_Payload(marker)))
    with pytest.raises(swiptopt.ConfigError, match="SHA-256"):
        load_deep(planted, "ppo", sha256=digest)
    assert not marker.exists()


def test_pretrained_directories_are_used_only_with_their_manifest(tmp_path):
    kwargs = dict(hyperparams=SETTINGS["ppo"], policy_kwargs=NET)
    shipped = tmp_path / "shipped"
    made = train_or_load_deep(shipped, "ppo", TINY, 128, 0, **kwargs)
    fresh = tmp_path / "models"
    reused = train_or_load_deep(fresh, "ppo", TINY, 128, 0, pretrained=[shipped], **kwargs)
    assert reused.loaded and reused.path == made.path and not list(fresh.glob("*.npz"))
    (shipped / "manifest.json").unlink()
    retrained = train_or_load_deep(tmp_path / "other", "ppo", TINY, 128, 0, pretrained=[shipped], **kwargs)
    assert not retrained.loaded and "not recorded" in retrained.note
    for key, value in _parameters(made.model).items():  # retraining gives the same model
        np.testing.assert_array_equal(value, _parameters(retrained.model)[key])


def test_a_directory_this_process_cannot_write_is_only_read(tmp_path, monkeypatch):
    """A read-only models directory (as an unprivileged user sees one: os.access says no)
    gives its trusted model without a lock file, or a ConfigError naming the directory and
    the model; it never trains."""
    import os

    kwargs = dict(hyperparams=SETTINGS["ppo"], policy_kwargs=NET)
    ready, empty = tmp_path / "ready", tmp_path / "empty"
    made = train_or_load_deep(ready, "ppo", TINY, 128, 0, **kwargs)
    for lock in ready.glob("*.lock"):
        lock.unlink()
    empty.mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda path, mode, **kw: False if mode & os.W_OK and Path(path) in (
        ready, empty) else real_access(path, mode, **kw))
    before = sorted(p.name for p in ready.iterdir())
    read = train_or_load_deep(ready, "ppo", TINY, 128, 0, **kwargs)
    assert read.loaded and read.path == made.path and read.sha256 == made.sha256
    assert sorted(p.name for p in ready.iterdir()) == before  # no lock, nothing written
    for key, value in _parameters(made.model).items():
        np.testing.assert_array_equal(value, _parameters(read.model)[key])
    # pretrained directories are read too; a model in neither is refused, not trained
    assert train_or_load_deep(empty, "ppo", TINY, 128, 0, pretrained=[ready], **kwargs).path == made.path
    with pytest.raises(swiptopt.ConfigError, match=f"{empty}.* is not writable and holds no trusted "
                                                   f"{made.path.name}") as refused:
        train_or_load_deep(empty, "ppo", TINY, 128, 0, **kwargs)
    assert refused.value.field == "models" and not any(empty.iterdir())


def test_a_checkpoint_is_the_model_of_the_shorter_run(tmp_path):
    kwargs = dict(hyperparams=SETTINGS["ppo"], policy_kwargs=NET, n_envs=2)
    long = train_or_load_deep(tmp_path, "ppo", TINY, 512, 0, checkpoints=[256], **kwargs)
    short = train_or_load_deep(tmp_path, "ppo", TINY, 256, 0, **kwargs)
    assert short.loaded  # the checkpoint, recorded under the shorter run's name
    alone = train_deep("ppo", TINY, 256, 0, **kwargs)
    for key, value in _parameters(alone.model).items():
        np.testing.assert_array_equal(value, _parameters(short.model)[key])
    assert any(not np.array_equal(v, _parameters(long.model)[k]) for k, v in _parameters(short.model).items())
    with pytest.raises(swiptopt.ConfigError, match="checkpoint at 200 steps"):
        train_or_load_deep(tmp_path, "ppo", TINY, 512, 0, checkpoints=[200], **kwargs)  # not a rollout's end
    with pytest.raises(swiptopt.ConfigError, match="checkpoint"):  # SB3's DQN explores over a share of the total
        train_or_load_deep(tmp_path, "stable_baselines3:DQN", TINY, 512, 0, checkpoints=[256],
                           hyperparams=SETTINGS["dqn"], policy_kwargs=NET)
    # the project's DQN explores over a number of steps: its checkpoint is the shorter run's model
    dqn = dict(hyperparams={**SETTINGS["dqn"], "exploration_steps": 200}, policy_kwargs=NET, n_envs=2)
    train_or_load_deep(tmp_path, "dqn", TINY, 512, 0, checkpoints=[256], **dqn)
    short_dqn = train_or_load_deep(tmp_path, "dqn", TINY, 256, 0, **dqn)
    assert short_dqn.loaded
    for key, value in _parameters(train_deep("dqn", TINY, 256, 0, **dqn).model).items():
        np.testing.assert_array_equal(value, _parameters(short_dqn.model)[key])


def test_the_fleets_shared_env_trains_like_the_vector_env_given_and_keeps_exact_checkpoints(tmp_path):
    """Parameter-shared PPO through :data:`rl.deep.FLEET_SHARED_ENV_ID` (so its models are kept
    by hash and checkpointed like every deep model) trains the very model of the same PPO
    handed the fleet's shared vector env; its rollout counts every AUV of every copy, and a
    checkpoint at a rollout's end is the shorter run's model."""
    pytest.importorskip("pettingzoo")
    from rl.deep import FLEET_SHARED_ENV_ID, DeepConfig, rollout_steps
    from rl.fleet import make_shared_vec_env

    fleet = swiptopt.Scenario.preset("paper", n_nodes=8, n_auvs=2, episode_steps=20)
    hp = {"n_steps": 32, "batch_size": 64, "n_epochs": 2, "ent_coef": 0.01}
    kwargs = dict(hyperparams=hp, policy_kwargs=NET, n_envs=2, env_id=FLEET_SHARED_ENV_ID)
    given = train_deep("ppo", make_shared_vec_env(2, fleet), 512, 3, hyperparams=hp, policy_kwargs=NET)
    named = train_or_load_deep(tmp_path, "ppo", fleet, 512, 3, checkpoints=[256], **kwargs)
    for key, value in _parameters(given.model).items():
        np.testing.assert_array_equal(value, _parameters(named.model)[key])
    config = DeepConfig("ppo", 512, 3, hp, NET, n_envs=2, env_id=FLEET_SHARED_ENV_ID)
    assert rollout_steps(config, fleet) == 32 * 2 * 2
    with pytest.raises(swiptopt.ConfigError, match="n_auvs"):
        rollout_steps(config)
    short = train_or_load_deep(tmp_path, "ppo", fleet, 256, 3, **kwargs)
    assert short.loaded and not named.loaded
    for key, value in _parameters(train_deep("ppo", fleet, 256, 3, **kwargs).model).items():
        np.testing.assert_array_equal(value, _parameters(short.model)[key])
    with pytest.raises(swiptopt.ConfigError, match="checkpoint at 192 steps"):  # not the end of a rollout of 128
        train_or_load_deep(tmp_path, "ppo", fleet, 512, 3, checkpoints=[192], **kwargs)
    with pytest.raises(swiptopt.ConfigError, match="layout_seeds must be None"):
        train_deep("ppo", fleet, 256, 3, layout_seeds=[0, 1], **kwargs)


def test_a_training_reports_its_progress_and_trains_the_same_model(monkeypatch):
    import rl.deep

    monkeypatch.setattr(rl.deep, "PROGRESS_INTERVAL_S", 0.0)  # a report at every rollout's start
    reports = []
    with reporting_progress(lambda *report: reports.append(report)):
        watched = train_deep("ppo", TINY, 384, 2, hyperparams=SETTINGS["ppo"], policy_kwargs=NET, n_envs=2)
    # rollouts of 2 x 64 steps: reported as each starts, then once finished
    assert reports == [(0, 384, False), (128, 384, False), (256, 384, False), (384, 384, True)]
    quiet = train_deep("ppo", TINY, 384, 2, hyperparams=SETTINGS["ppo"], policy_kwargs=NET, n_envs=2)
    for key, value in _parameters(quiet.model).items():
        np.testing.assert_array_equal(value, _parameters(watched.model)[key])
    reports.clear()
    train_deep("ppo", TINY, 128, 2, hyperparams=SETTINGS["ppo"], policy_kwargs=NET, n_envs=2)
    assert reports == []  # outside the block nothing is reported


def test_copies_of_the_environment_train_reproducibly():
    first = train_deep("ppo", TINY, 256, 1, hyperparams=SETTINGS["ppo"], policy_kwargs=NET, n_envs=4)
    again = train_deep("ppo", TINY, 256, 1, hyperparams=SETTINGS["ppo"], policy_kwargs=NET, n_envs=4)
    single = train_deep("ppo", TINY, 256, 1, hyperparams=SETTINGS["ppo"], policy_kwargs=NET)
    assert first.config.n_envs == 4 and first.config_hash != single.config_hash
    for key, value in _parameters(first.model).items():
        np.testing.assert_array_equal(value, _parameters(again.model)[key])
    assert len(first.episode_returns) == 256 // TINY.episode_steps * 0 + len(again.episode_returns) > 0


def test_the_hash_names_every_part_of_the_configuration():
    base = DeepConfig("ppo", 1000, 0, {"n_steps": 64}, {"net_arch": [32]})
    key = deep_config_hash(base, TINY)
    assert key == deep_config_hash(DeepConfig("ppo", 1000, 0, {"n_steps": 64}, {"net_arch": [32]}), TINY)
    variants = [
        (DeepConfig("dqn", 1000, 0, {}, {"net_arch": [32]}), TINY),
        (DeepConfig("ppo", 1001, 0, {"n_steps": 64}, {"net_arch": [32]}), TINY),
        (DeepConfig("ppo", 1000, 1, {"n_steps": 64}, {"net_arch": [32]}), TINY),
        (DeepConfig("ppo", 1000, 0, {"n_steps": 128}, {"net_arch": [32]}), TINY),
        (DeepConfig("ppo", 1000, 0, {"n_steps": 64}, {"net_arch": [64]}), TINY),
        (DeepConfig("ppo", 1000, 0, {"n_steps": 64}, {"net_arch": [32]}, (0, 1)), TINY),
        (base, TINY.replace(layout_seed=1)),
    ]
    keys = {deep_config_hash(c, s) for c, s in variants}
    assert len(keys) == len(variants) and key not in keys


def test_bad_configurations_are_config_errors(tmp_path):
    with pytest.raises(swiptopt.ConfigError,
                       match=r"'pp0'.*did you mean 'ppo'.*\['dqn', 'maskable_ppo', 'ppo', 'sac'\]"):
        train_deep("pp0", TINY, 100)
    with pytest.raises(swiptopt.ConfigError,
                       match=r"unknown ppo setting 'nsteps' \(did you mean 'n_steps'\?\).*batch_size"):
        train_deep("ppo", TINY, 100, hyperparams={"nsteps": 64})
    with pytest.raises(swiptopt.ConfigError, match="seed"):
        train_deep("ppo", TINY, 100, hyperparams={"seed": 1})  # set through the argument only
    with pytest.raises(swiptopt.ConfigError, match="timesteps"):
        train_deep("dqn", TINY, 0)
    with pytest.raises(swiptopt.ConfigError, match="layout_seeds"):
        DeepConfig("dqn", 10, layout_seeds=[3, -1])
    with pytest.raises(swiptopt.ConfigError, match="vector"):
        train_deep("dqn", AuvSwiptEnv(TINY), 100)  # the tabular observation
    with pytest.raises(swiptopt.ConfigError,
                       match=r"hyperparams.batch_size = 1 is out of range: must be an integer in \[2, 1073741824\]"):
        train_deep("ppo", TINY, 100, hyperparams={"batch_size": 1})
    with pytest.raises(swiptopt.ConfigError, match="no saved model"):
        load_deep(tmp_path / "missing.zip", "ppo")
    (tmp_path / "junk.zip").write_bytes(b"not a zip file")
    with pytest.raises(swiptopt.ConfigError, match="not a saved dqn model"):
        load_deep(tmp_path / "junk.zip", "dqn")


@pytest.mark.parametrize(("algorithm", "hyperparams", "policy_kwargs", "field", "words"), [
    ("ppo", {}, {"net_arch": [-1]}, "policy_kwargs", "policy_kwargs.net_arch = [-1] must be a list"),
    ("ppo", {}, {"net_arch": {"pi": [8], "vf": [0]}}, "policy_kwargs", "policy_kwargs.net_arch.vf = [0]"),
    ("dqn", {}, {"net_arch": "wide"}, "policy_kwargs", "policy_kwargs.net_arch = 'wide'"),
    ("ppo", {}, {"bogus": 1}, "policy_kwargs", "unknown policy_kwargs key 'bogus': ActorCriticPolicy takes"),
    ("ppo", {}, {"activation_fn": "relu"}, "policy_kwargs", "ppo rejected its policy_kwargs: TypeError"),
    ("ppo", {"n_epochs": 0}, {}, "hyperparams",
     "hyperparams.n_epochs = 0 is out of range: must be an integer in [1, 10000]"),
    ("ppo", {"learning_rate": -1.0}, {}, "hyperparams",
     "hyperparams.learning_rate = -1.0 is out of range: must be a number in (0, inf)"),
    ("dqn", {"gamma": 1.5}, {}, "hyperparams", "hyperparams.gamma = 1.5 is out of range: must be a number in [0, 1]"),
    ("sac", {"tau": 0.0}, {}, "hyperparams", "hyperparams.tau = 0.0 is out of range: must be a number in (0, 1]"),
])
def test_settings_sb3_would_fail_on_name_the_right_argument(algorithm, hyperparams, policy_kwargs, field, words):
    """Refused before training, in one line naming the argument (unchecked, n_epochs = 0 fails
    mid-training with SB3's UnboundLocalError and net_arch = [-1] with torch's RuntimeError),
    and a policy_kwargs error names policy_kwargs, not hyperparams."""
    world = "continuous" if algorithm == "sac" else "grid"
    scenario = swiptopt.Scenario.preset("harbour", n_nodes=3) if algorithm == "sac" else TINY
    with pytest.raises(swiptopt.ConfigError) as info:
        train_deep(algorithm, scenario, 64, hyperparams=hyperparams, policy_kwargs=policy_kwargs, world=world)
    assert info.value.field == field and words in str(info.value) and "\n" not in str(info.value)


def test_import_rl_loads_no_torch():
    code = "import sys, rl, rl.deep; print([m for m in ('torch', 'stable_baselines3') if m in sys.modules])"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"


# ------------------------------------------------------------------ the continuous world

#: A small harbour (its obstacles and current) for the continuous world: few nodes, short episodes
HARBOUR = swiptopt.Scenario.preset("harbour", n_nodes=4, episode_steps=20)
CONTINUOUS_SETTINGS = {
    "ppo": {"n_steps": 64, "batch_size": 32, "n_epochs": 2},
    "sac": {"buffer_size": 1_000, "learning_starts": 60, "batch_size": 32},
}


def _train_continuous(algorithm, seed=0, timesteps=128):
    return train_deep(algorithm, HARBOUR, timesteps, seed, hyperparams=CONTINUOUS_SETTINGS[algorithm],
                      policy_kwargs={"net_arch": [16]}, layout_seeds=(0, 1), world="continuous")


def _continuous_observations(n=100):
    from swiptopt.env_continuous import AuvSwiptContinuousEnv

    env = AuvSwiptContinuousEnv(HARBOUR, layout_seeds=range(5))
    rng = np.random.default_rng(0)
    out = [env.reset(seed=0)[0]]
    while len(out) < n:
        obs, _, term, trunc, _ = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
        out.append(obs)
        if term or trunc:
            out.append(env.reset()[0])
    return np.array(out)


@pytest.mark.parametrize("algorithm", ["sac", "ppo"])
def test_continuous_control_trains_saves_loads_and_acts_identically(algorithm, tmp_path):
    from swiptopt.env_continuous import AuvSwiptContinuousEnv

    result = _train_continuous(algorithm)
    assert result.config.world == "continuous" and result.config_hash == deep_config_hash(result.config, HARBOUR)
    assert len(result.episode_returns) >= 128 // HARBOUR.episode_steps - 1
    path = save_deep(result, tmp_path / "model.zip")
    loaded = load_deep(path, algorithm, config_hash=result.config_hash)
    obs = _continuous_observations()
    trained, _ = result.model.predict(obs, deterministic=True)
    again, _ = loaded.predict(obs, deterministic=True)
    assert trained.shape == (len(obs), 3) and np.all(np.abs(trained) <= 1)
    np.testing.assert_array_equal(trained, again)
    assert np.ptp(trained, axis=0).max() > 0  # the actions depend on the observation
    env = AuvSwiptContinuousEnv(HARBOUR)
    a = swiptopt.evaluate(result.model, env, 2, seed=5)
    assert swiptopt.evaluate(loaded, env, 2, seed=5).records == a.records
    # the same seed trains the same model
    twin = _train_continuous(algorithm)
    for name, value in _parameters(result.model).items():
        np.testing.assert_array_equal(value, _parameters(twin.model)[name])


def test_the_world_names_the_model():
    grid = DeepConfig("ppo", 1000, 0, {"n_steps": 64}, {"net_arch": [32]})
    continuous = DeepConfig("ppo", 1000, 0, {"n_steps": 64}, {"net_arch": [32]}, world="continuous")
    assert "world" not in grid.to_dict() and continuous.to_dict()["world"] == "continuous"
    assert deep_config_hash(grid, HARBOUR) != deep_config_hash(continuous, HARBOUR)
    with pytest.raises(swiptopt.ConfigError, match="world = 'grdi' is not a world"):
        DeepConfig("ppo", 10, world="grdi")


@pytest.mark.parametrize("algorithm, world, space", [("sac", "grid", "Discrete(7)"), ("dqn", "continuous", "Box")])
def test_an_algorithm_that_cannot_take_the_worlds_actions_is_one_line(algorithm, world, space):
    with pytest.raises(swiptopt.ConfigError) as info:
        train_deep(algorithm, HARBOUR, 100, world=world)
    message = str(info.value)
    assert f"{algorithm} cannot act on {space}" in message and f"the {world} world's actions" in message
    assert info.value.field == "world" and "\n" not in message


def test_training_writes_nothing_outside_the_directories_named(tmp_path, monkeypatch):
    """SB3's default logger makes a folder under the system's temporary directory per run;
    training here gives the model a logger that writes nothing."""
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    _train("ppo", timesteps=128)
    train_deep("dqn", TINY, 128, 0, hyperparams=SETTINGS["dqn"], policy_kwargs=NET, n_envs=2)
    assert list(tmp_path.iterdir()) == []


def test_a_model_trained_on_other_torch_cpu_paths_has_another_name(monkeypatch):
    """Under the pinned CPU paths (set or not yet set) the name is the one the shipped models
    carry; a user's other MKL or ATen setting names another model, whose lineage differs too,
    so neither a pretrained model nor a kept state of the pinned run is taken for it."""
    import platform

    from rl.deep import lineage_hash

    if platform.machine().lower() not in ("x86_64", "amd64"):
        pytest.skip("the pinned paths are x86-64's")
    config = DeepConfig("ppo", 1000, 0, {"n_steps": 64}, {"net_arch": [32]})
    for name in ("MKL_CBWR", "ATEN_CPU_CAPABILITY"):
        monkeypatch.delenv(name, raising=False)
    unset = deep_config_hash(config, TINY), lineage_hash(config, TINY)
    monkeypatch.setenv("MKL_CBWR", "compatible")
    monkeypatch.setenv("ATEN_CPU_CAPABILITY", "AVX2")
    assert (deep_config_hash(config, TINY), lineage_hash(config, TINY)) == unset
    names = {unset}
    for name, value in (("MKL_CBWR", "AVX2"), ("ATEN_CPU_CAPABILITY", "avx512")):
        with monkeypatch.context() as patched:
            patched.setenv(name, value)
            names.add((deep_config_hash(config, TINY), lineage_hash(config, TINY)))
    assert len(names) == 3 and len({key for pair in names for key in pair}) == 6
