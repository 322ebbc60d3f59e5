import subprocess
import sys
from collections.abc import Mapping

import gymnasium as gym
import numpy as np
import pytest

import swiptopt
from swiptopt.errors import ConfigError
from swiptopt.vector import AuvSwiptVectorEnv

pytest.importorskip("stable_baselines3")

from stable_baselines3.common.monitor import Monitor  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv  # noqa: E402

from rl.vec_env import Sb3VectorEnv, make_sb3_vec_env  # noqa: E402

#: Rician fading, link failures, layouts per episode, episodes ending both ways.
STOCHASTIC = {"channel": "rician", "failure_prob_min": 0.1, "failure_prob_max": 0.4, "episode_steps": 20,
              "battery_j": 120_000.0, "cone_half_angle_deg": 70.0, "layout_seeds": range(6)}
WORLDS = {
    "grid": (swiptopt.ENV_ID, {"preset": "paper", "n_nodes": 12, "observation": "vector", **STOCHASTIC}),
    "continuous": (swiptopt.CONTINUOUS_ENV_ID, {"preset": "harbour", "n_nodes": 12, **STOCHASTIC}),
}


def _ours(world, n, **changes):
    return make_sb3_vec_env(n, world, **{**WORLDS[world][1], **changes})


def _dummy(world, n, **changes):
    env_id, kwargs = WORLDS[world]
    return DummyVecEnv([lambda: gym.make(env_id, **{**kwargs, **changes})] * n)


def _actions(world, n, steps, seed=0):
    rng = np.random.default_rng(seed)
    if world == "grid":
        return list(rng.integers(0, 7, (steps, n)))
    return list(rng.uniform(-1, 1, (steps, n, 3)).astype(np.float32))


def assert_same(a, b, where="result"):
    """Equal bit for bit, with equal types, dtypes and shapes, and dict keys in the same order."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        assert type(a) is type(b) and a.dtype == b.dtype and a.shape == b.shape, f"{where}: {a!r} vs {b!r}"
        assert a.tobytes() == b.tobytes(), f"{where}: {a!r} vs {b!r}"
    elif isinstance(a, Mapping):
        assert type(a) is type(b) and list(a) == list(b), f"{where}: keys {list(a)} vs {list(b)}"
        for key in a:
            assert_same(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, (list, tuple)):
        assert type(a) is type(b) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    else:
        assert type(a) is type(b) and repr(a) == repr(b), f"{where}: {a!r} vs {b!r}"


def _run(venv, seed, actions, reset_every=None):
    venv.seed(seed)
    out = [venv.reset(), [dict(i) for i in venv.reset_infos]]
    for k, a in enumerate(actions):
        out.append(venv.step(a))
        out.append([dict(i) for i in venv.reset_infos])
        if reset_every and (k + 1) % reset_every == 0:
            out.append(venv.reset())  # unseeded: the seed served one reset only
    return out


@pytest.mark.parametrize("world", ["grid", "continuous"])
def test_equals_dummy_vec_env_step_for_step(world):
    n, steps = 3, 130
    actions = _actions(world, n, steps)
    ours, theirs = _run(_ours(world, n), 5, actions, reset_every=50), _run(_dummy(world, n), 5, actions, reset_every=50)
    assert len(ours) == len(theirs)
    for k, (x, y) in enumerate(zip(ours, theirs)):
        assert_same(x, y, f"call {k}")
    # episodes ended both ways, with the infos SB3 reads
    steps_out = [r for r in ours if isinstance(r, tuple)]
    dones = [(i, info) for _, _, done, infos in steps_out for i, info in zip(done, infos) if i]
    assert len(dones) >= 6
    limited = [info["TimeLimit.truncated"] for _, info in dones]
    assert any(limited) and not all(limited)
    for _, info in dones:
        assert info["terminal_observation"].dtype == np.float32 and "episode_metrics" in info
    obs, rewards, done, infos = steps_out[0]
    assert obs.dtype == np.float32 and rewards.dtype == np.float32 and done.dtype == np.bool_


def test_per_copy_options_and_the_attribute_methods():
    n = 3
    ours, theirs = _ours("grid", n), _dummy("grid", n)
    options = [{"layout_seed": 40}, {}, {"layout_seed": 41}]
    for venv in (ours, theirs):
        venv.seed(2)
        venv.set_options(options)
    assert_same(ours.reset(), theirs.reset())
    assert_same(ours.reset_infos, theirs.reset_infos)
    assert [info["layout_seed"] for info in ours.reset_infos][::2] == [40, 41]
    for a in _actions("grid", n, 12):
        assert_same(ours.step(a), theirs.step(a))
    assert ours.get_attr("layout_seeds") == theirs.get_attr("layout_seeds")
    assert [s.layout_seed for s in ours.get_attr("scenario")] == [s.layout_seed for s in theirs.get_attr("scenario")]
    metrics = [[dict(m) for m in venv.env_method("episode_metrics")] for venv in (ours, theirs)]
    assert_same(*metrics)
    assert_same(ours.env_method("episode_metrics", indices=[2]), theirs.env_method("episode_metrics", indices=[2]))
    ours.set_attr("note", "x", indices=[0, 2])
    assert ours.get_attr("note", indices=[0, 2]) == ["x", "x"] and not ours.has_attr("note")
    assert ours.env_is_wrapped(Monitor) == theirs.env_is_wrapped(Monitor) == [False] * n
    # the single env's action masks (when it has them) reach SB3 the same way; otherwise neither has them
    assert ours.has_attr("action_masks") == theirs.has_attr("action_masks")
    if theirs.has_attr("action_masks"):
        assert_same(ours.env_method("action_masks"), theirs.env_method("action_masks"))
    else:
        with pytest.raises(AttributeError):
            ours.env_method("action_masks")
    assert isinstance(ours, VecEnv) and ours.num_envs == n and ours.render_mode is None
    ours.close()


def _ppo_parameters(venv, seed):
    from stable_baselines3 import PPO

    from rl.deep import pin_torch

    pin_torch()
    model = PPO("MlpPolicy", venv, n_steps=16, batch_size=32, n_epochs=2, seed=seed, device="cpu",
                policy_kwargs={"net_arch": [16]})
    model.learn(256)
    return {k: v.detach().numpy().copy() for k, v in model.policy.state_dict().items()}


@pytest.mark.parametrize("world", ["grid", "continuous"])
def test_ppo_trains_the_same_parameters_on_either(world):
    ours = _ppo_parameters(_ours(world, 4), 3)
    theirs = _ppo_parameters(_dummy(world, 4), 3)
    assert list(ours) == list(theirs)
    for name in ours:
        assert ours[name].tobytes() == theirs[name].tobytes(), name
    other = _ppo_parameters(_ours(world, 4), 4)  # the comparison can fail: another seed, other parameters
    assert any(ours[name].tobytes() != other[name].tobytes() for name in ours)


def test_bad_arguments():
    with pytest.raises(ConfigError, match="SAME_STEP") as error:
        Sb3VectorEnv(AuvSwiptVectorEnv(2, preset="tiny"))
    assert error.value.field == "autoreset_mode"
    with pytest.raises(ConfigError, match="AuvSwiptVectorEnv"):
        Sb3VectorEnv(gym.make(swiptopt.ENV_ID, preset="tiny"))
    with pytest.raises(ConfigError, match="autoreset_mode"):
        make_sb3_vec_env(2, preset="tiny", autoreset_mode="NextStep")
    with pytest.raises(ConfigError) as error:
        make_sb3_vec_env(0, preset="tiny")
    assert error.value.field == "num_envs"


def test_import_rl_vec_env_loads_no_sb3():
    code = ("import sys, rl, rl.vec_env; "
            "print([m for m in ('torch', 'stable_baselines3', 'numba') if m in sys.modules])")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"
