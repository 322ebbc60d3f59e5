import subprocess
import sys

import numpy as np
import pytest

import swiptopt
from rl import DeepConfig, deep_config_hash, load_deep, save_deep, train_deep, train_or_load_deep
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
    assert swiptopt.evaluate(first.model, env, 4, seed=9).records == swiptopt.evaluate(again.model, env, 4, seed=9).records
    assert first.config_hash == again.config_hash != other.config_hash


def test_training_across_layouts():
    result = _train("ppo", layout_seeds=range(0, 50), timesteps=300)
    assert result.config.layout_seeds == range(50)
    assert result.config_hash != _train("ppo", timesteps=300).config_hash
    assert len(result.episode_returns) > 0 and np.all(np.isfinite(result.episode_returns))


def test_train_or_load_reuses_a_matching_model(tmp_path):
    first = train_or_load_deep(tmp_path, "dqn", TINY, 300, 1, hyperparams=SETTINGS["dqn"], policy_kwargs=NET)
    assert not first.loaded and list(tmp_path.glob("*.zip")) == [tmp_path / f"dqn-{first.config_hash}.zip"]
    second = train_or_load_deep(tmp_path, "dqn", TINY, 300, 1, hyperparams=SETTINGS["dqn"], policy_kwargs=NET)
    assert second.loaded and second.config_hash == first.config_hash
    obs = _observations(50)
    np.testing.assert_array_equal(first.model.predict(obs, True)[0], second.model.predict(obs, True)[0])
    other = train_or_load_deep(tmp_path, "dqn", TINY.replace(split_ratio=0.3), 300, 1, hyperparams=SETTINGS["dqn"], policy_kwargs=NET)
    assert not other.loaded and len(list(tmp_path.glob("*.zip"))) == 2


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
    with pytest.raises(swiptopt.ConfigError, match=r"'pp0'.*did you mean 'ppo'.*\['dqn', 'ppo', 'sac'\]"):
        train_deep("pp0", TINY, 100)
    with pytest.raises(swiptopt.ConfigError, match=r"unknown ppo setting 'nsteps' \(did you mean 'n_steps'\?\).*batch_size"):
        train_deep("ppo", TINY, 100, hyperparams={"nsteps": 64})
    with pytest.raises(swiptopt.ConfigError, match="seed"):
        train_deep("ppo", TINY, 100, hyperparams={"seed": 1})  # set through the argument only
    with pytest.raises(swiptopt.ConfigError, match="timesteps"):
        train_deep("dqn", TINY, 0)
    with pytest.raises(swiptopt.ConfigError, match="layout_seeds"):
        DeepConfig("dqn", 10, layout_seeds=[3, -1])
    with pytest.raises(swiptopt.ConfigError, match="vector"):
        train_deep("dqn", AuvSwiptEnv(TINY), 100)  # the tabular observation
    with pytest.raises(swiptopt.ConfigError, match="rejected"):
        train_deep("ppo", TINY, 100, hyperparams={"batch_size": 1})
    with pytest.raises(swiptopt.ConfigError, match="no saved model"):
        load_deep(tmp_path / "missing.zip", "ppo")
    (tmp_path / "junk.zip").write_bytes(b"not a zip file")
    with pytest.raises(swiptopt.ConfigError, match="not a saved dqn model"):
        load_deep(tmp_path / "junk.zip", "dqn")


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
