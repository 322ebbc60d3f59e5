import inspect
import subprocess
import sys
from collections.abc import Mapping

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv
from gymnasium.vector.utils import batch_space

import swiptopt
from swiptopt import kernel as K
from swiptopt.env import AuvSwiptEnv
from swiptopt.env_continuous import AuvSwiptContinuousEnv
from swiptopt.errors import ConfigError
from swiptopt.vector import AuvSwiptVectorEnv

#: Rician fading and link failures on, layouts drawn per episode, a battery small enough that
#: some episodes end by termination (battery spent) and others by truncation.
STOCHASTIC = {
    "channel": "rician",
    "failure_prob_min": 0.1,
    "failure_prob_max": 0.4,
    "episode_steps": 25,
    "battery_j": 150_000.0,
    "cone_half_angle_deg": 70.0,  # many nodes covered per step: the draw buffers refill mid-run
    "layout_seeds": range(8),
}
WORLDS = {
    "grid": ("paper", {"n_nodes": 40, "observation": "vector", **STOCHASTIC}),
    "continuous": ("harbour", {"n_nodes": 60, **STOCHASTIC}),
}
SINGLE = {"grid": AuvSwiptEnv, "continuous": AuvSwiptContinuousEnv}
MODES = [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP]


def _vector(world, n, backend="compiled", mode=AutoresetMode.NEXT_STEP, **changes):
    preset, kwargs = WORLDS[world]
    return AuvSwiptVectorEnv(n, world, preset=preset, backend=backend, autoreset_mode=mode, **{**kwargs, **changes})


def _sync(world, n, backend="compiled", mode=AutoresetMode.NEXT_STEP, **changes):
    preset, kwargs = WORLDS[world]
    cls = SINGLE[world]
    return SyncVectorEnv(
        [lambda: cls(preset=preset, backend=backend, **{**kwargs, **changes})] * n, autoreset_mode=mode
    )


def _actions(world, n, steps, seed=0):
    rng = np.random.default_rng(seed)
    if world == "grid":
        return list(rng.integers(0, K.N_ACTIONS, (steps, n)))
    return list(rng.uniform(-1.3, 1.3, (steps, n, 3)).astype(np.float32))  # some beyond the box: clipped


def assert_same(a, b, where="result"):
    """Equal bit for bit, with equal types, dtypes, shapes and keys, recursively."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        assert type(a) is type(b) and a.dtype == b.dtype and a.shape == b.shape, f"{where}: {a!r} vs {b!r}"
        if a.dtype == object:
            for i, (x, y) in enumerate(zip(a, b)):
                assert_same(x, y, f"{where}[{i}]")
        else:
            assert a.tobytes() == b.tobytes(), f"{where}: {a!r} vs {b!r}"
    elif isinstance(a, Mapping):
        assert type(a) is type(b) and set(a) == set(b), f"{where}: keys {sorted(a)} vs {sorted(b)}"
        for key in a:
            assert_same(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, (tuple, list)):
        assert type(a) is type(b) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    else:
        assert type(a) is type(b) and repr(a) == repr(b), f"{where}: {a!r} vs {b!r}"  # repr: floats exactly, NaN = NaN


def _run(env, seed, actions, mask_resets=False):
    """Everything ``env`` returns over ``actions`` from ``reset(seed=seed)``; with
    ``mask_resets`` (DISABLED autoreset) the ended copies are reset with a reset mask."""
    out = [env.reset(seed=seed)]
    for a in actions:
        result = env.step(a)
        out.append(result)
        if mask_resets and np.any(result[2] | result[3]):
            out.append(env.reset(options={"reset_mask": result[2] | result[3]}))
    return out


def _assert_runs_equal(ours, theirs):
    assert len(ours) == len(theirs)
    for k, (x, y) in enumerate(zip(ours, theirs)):
        assert len(x) == len(y)
        for j, (u, v) in enumerate(zip(x, y)):
            assert_same(u, v, f"call {k}, item {j}")


def _episode_ends(run):
    steps = [r for r in run if len(r) == 5]
    return int(sum(np.sum(r[2]) for r in steps)), int(sum(np.sum(r[3]) for r in steps))


# ----------------------------------------------------------------- the vector env = N single envs


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.name)
@pytest.mark.parametrize("world", ["grid", "continuous"])
def test_equals_sync_vector_env_of_single_envs(world, mode, monkeypatch):
    n, steps = 3, 160
    actions = _actions(world, n, steps)
    refills = []
    real_refill = K.refill_noise
    monkeypatch.setattr(K, "refill_noise", lambda *args: (refills.append(1), real_refill(*args)))
    ours = _run(_vector(world, n, mode=mode), 4, actions)
    ours_refills = len(refills)
    theirs = _run(_sync(world, n, mode=mode), 4, actions)
    _assert_runs_equal(ours, theirs)

    # the test saw what it is meant to: episodes ending both ways, draws refilled mid-run,
    # several layouts per copy across its episodes, different layouts across the copies
    terminated, truncated = _episode_ends(ours)
    assert terminated >= 3 and truncated >= 3, (terminated, truncated)
    assert ours_refills > n  # more refills than the seeded resets' first steps
    layouts = [ours[0][1]["layout_seed"].tolist()]
    for result in ours[1:]:
        infos = result[4]
        if "layout_seed" in infos:
            layouts.append(np.where(infos["_layout_seed"], infos["layout_seed"], -1).tolist())
    per_copy = [{row[i] for row in layouts} - {-1} for i in range(n)]
    assert all(len(s) >= 3 for s in per_copy) and len(set(layouts[0])) > 1, layouts
    # the infos hold what the single envs give
    ended = [r[4] for r in ours[1:] if np.any(r[2] | r[3])]
    where = (lambda i: i["final_info"]) if mode is AutoresetMode.SAME_STEP else (lambda i: i)
    for infos in ended:
        m = where(infos)["episode_metrics"][np.flatnonzero(where(infos)["_episode_metrics"])[0]]
        assert isinstance(m, swiptopt.env.EpisodeMetrics) and 1 <= m["length"] <= 25
    assert {"throughput", "harvest", "movement"} <= set(ours[5][4]["reward_parts"])


@pytest.mark.parametrize("world", ["grid", "continuous"])
def test_python_backend_equals_the_python_single_envs_and_the_compiled_backend(world):
    n, steps = 2, 60
    actions = _actions(world, n, steps, seed=1)
    python = _run(_vector(world, n, backend="python", mode=AutoresetMode.SAME_STEP), 9, actions)
    _assert_runs_equal(python, _run(_sync(world, n, backend="python", mode=AutoresetMode.SAME_STEP), 9, actions))
    _assert_runs_equal(python, _run(_vector(world, n, backend="compiled", mode=AutoresetMode.SAME_STEP), 9, actions))


@pytest.mark.parametrize("world", ["grid", "continuous"])
def test_disabled_autoreset_with_reset_masks_equals_sync(world):
    n, steps = 3, 80
    actions = _actions(world, n, steps, seed=2)
    mode = AutoresetMode.DISABLED
    ours = _run(_vector(world, n, mode=mode), 0, actions, mask_resets=True)
    _assert_runs_equal(ours, _run(_sync(world, n, mode=mode), 0, actions, mask_resets=True))
    # stepping a copy whose episode ended, without resetting it, is an error
    env = _vector(world, 2, mode=mode, episode_steps=1)
    env.reset(seed=0)
    env.step(actions[0][:2])
    with pytest.raises(RuntimeError, match="reset_mask"):
        env.step(actions[1][:2])


def test_tabular_observation_equals_sync():
    n, steps = 3, 120
    actions = _actions("grid", n, steps, seed=3)
    ours = _run(_vector("grid", n, observation="tabular"), 1, actions)
    _assert_runs_equal(ours, _run(_sync("grid", n, observation="tabular"), 1, actions))
    assert ours[1][0].dtype == np.int64 and ours[1][0].shape == (n,)


def test_seeds_and_options_as_sync_passes_them():
    n = 3
    actions = _actions("grid", n, 40, seed=4)
    for seed in (7, [11, 3, 8]):
        _assert_runs_equal(_run(_vector("grid", n), seed, actions), _run(_sync("grid", n), seed, actions))
    # options go to every copy's reset
    ours, theirs = _vector("grid", n), _sync("grid", n)
    assert_same(ours.reset(seed=0, options={"layout_seed": 77}), theirs.reset(seed=0, options={"layout_seed": 77}))
    assert {env.scenario.layout_seed for env in ours.envs} == {77}
    for a in actions:  # later episodes draw their layouts again
        assert_same(ours.step(a), theirs.step(a))
    # a reset mask resets only those copies, as Gymnasium's
    mask = np.array([False, True, False])
    assert_same(ours.reset(options={"reset_mask": mask}), theirs.reset(options={"reset_mask": mask.copy()}))
    assert_same(ours.step(actions[0]), theirs.step(actions[0]))


def test_a_layout_covering_more_pairs_widens_the_rows():
    # the rows start as wide as the scenario's own layout; a layout covering more pairs widens them
    preset, kwargs = WORLDS["grid"]
    fields = {k: v for k, v in kwargs.items() if k not in ("observation", "layout_seeds")}
    nnz = {
        k: K.build_tables(swiptopt.Scenario.preset(preset, **fields, layout_seed=k)).cov_node.size for k in range(12)
    }
    small, big = min(nnz, key=nnz.get), max(nnz, key=nnz.get)
    assert nnz[big] > nnz[small]
    changes = {"layout_seed": small, "layout_seeds": None}
    ours, theirs = _vector("grid", 2, **changes), _sync("grid", 2, **changes)
    width = ours._copies.cov_node.shape[1]
    assert width == nnz[small]
    actions = _actions("grid", 2, 60, seed=5)
    assert_same(ours.reset(seed=1, options={"layout_seed": big}), theirs.reset(seed=1, options={"layout_seed": big}))
    assert ours._copies.cov_node.shape[1] >= nnz[big] > width
    for a in actions:
        assert_same(ours.step(a), theirs.step(a))


def test_controllers_see_the_rows():
    env = _vector("continuous", 2, layout_seeds=None, battery_j=1e9)
    env.reset(seed=0)
    for a in _actions("continuous", 2, 7):
        _, _, _, _, infos = env.step(a)
    for controller in env.envs:
        assert controller.state.t == 7  # its state is the row the compiled step wrote
        assert controller.episode_metrics()["length"] == 7
    np.testing.assert_array_equal(env.positions, infos["position"])
    grid = _vector("grid", 2)
    grid.reset(seed=0)
    grid.step(np.array([K.HOVER, 0]))
    cells = [c.state.cell for c in grid.envs]
    np.testing.assert_array_equal(grid.positions, grid.scenario.cell_centers_m[cells])
    assert grid.get_attr("layout_seeds") == (range(8), range(8))


# ----------------------------------------------------------------- the vector env API


@pytest.mark.parametrize("world", ["grid", "continuous"])
def test_vector_env_checks(world):
    n = 4
    env = _vector(world, n)
    single = SINGLE[world](preset=WORLDS[world][0], **WORLDS[world][1])
    assert isinstance(env, gym.vector.VectorEnv) and env.num_envs == n and env.unwrapped is env
    assert env.single_observation_space == single.observation_space
    assert env.single_action_space == single.action_space
    assert env.observation_space == batch_space(single.observation_space, n)
    assert env.action_space == batch_space(single.action_space, n)
    assert env.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    params = inspect.signature(env.reset).parameters
    assert params["seed"].kind is params["options"].kind is inspect.Parameter.KEYWORD_ONLY
    obs, info = env.reset(seed=0)
    assert isinstance(info, dict) and obs.dtype == np.float32 and obs.shape == (n, 4 + 6 * single.scenario.n_nodes)
    assert obs in env.observation_space
    env.action_space.seed(0)
    result = env.step(env.action_space.sample())
    assert len(result) == 5
    obs2, rewards, terminated, truncated, infos = result
    assert obs2 in env.observation_space and isinstance(infos, dict)
    assert rewards.dtype == np.float64 and rewards.shape == (n,)
    assert terminated.dtype == truncated.dtype == np.bool_ and terminated.shape == truncated.shape == (n,)
    assert not np.shares_memory(obs, obs2)  # fresh arrays: callers may keep them
    obs2[:] = 9.0
    assert env.step(env.action_space.sample())[0].max() <= 1.0
    # the same seed gives the same run, another seed another
    actions = _actions(world, n, 30, seed=6)
    first = _run(_vector(world, n), 5, actions)
    _assert_runs_equal(first, _run(_vector(world, n), 5, actions))
    other = _run(_vector(world, n), 6, actions)
    assert any(not np.array_equal(a[1], b[1]) for a, b in zip(first[1:], other[1:]))
    assert len(env.np_random) == n and env.np_random_seed == tuple(range(n))
    env.close()
    assert env.closed


@pytest.mark.parametrize("env_id, world", [(swiptopt.ENV_ID, "grid"), (swiptopt.CONTINUOUS_ENV_ID, "continuous")])
def test_make_vec_with_the_vector_entry_point(env_id, world):
    kwargs = {"preset": "paper", "n_nodes": 25, "layout_seeds": range(4)}
    if world == "grid":
        kwargs["observation"] = "vector"
    env = gym.make_vec(env_id, num_envs=8, vectorization_mode="vector_entry_point", **kwargs)
    assert isinstance(env, AuvSwiptVectorEnv) and env.num_envs == 8 and env.world == world
    assert env.spec.id == env_id and env.single_observation_space.shape == (4 + 6 * 25,)
    assert isinstance(gym.make_vec(env_id, num_envs=2, **kwargs), AuvSwiptVectorEnv)  # the default mode
    # the same episodes as Gymnasium's own vectorisation of the registered single env
    sync = gym.make_vec(env_id, num_envs=8, vectorization_mode="sync", **kwargs)
    assert isinstance(sync, SyncVectorEnv)
    actions = _actions(world, 8, 70, seed=7)
    _assert_runs_equal(_run(env, 3, actions), _run(sync, 3, actions))


def test_import_swiptopt_stays_light():
    code = "import sys, swiptopt; print([m for m in ('swiptopt.vector', 'numba') if m in sys.modules])"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"num_envs": 0}, "num_envs"),
        ({"num_envs": 2.5}, "num_envs"),
        ({"num_envs": True}, "num_envs"),
        ({"world": "grd"}, "world"),
        ({"observation": "image"}, "observation"),
        ({"world": "continuous", "observation": "tabular"}, "observation"),
        ({"backend": "fast"}, "backend"),
        ({"autoreset_mode": "sometimes"}, "autoreset_mode"),
        ({"render_mode": "human"}, "render_mode"),
        ({"layout_seeds": []}, "layout_seeds"),
        ({"layout_seeds": [1, -2]}, "layout_seeds"),
        ({"n_nodez": 3}, "n_nodez"),
        ({"n_nodes": 0}, "n_nodes"),
        ({"max_episode_steps": 10}, "max_episode_steps"),
        ({"scenario": "paper"}, "scenario"),
    ],
)
def test_bad_arguments_are_one_config_error_naming_the_argument(kwargs, field):
    kwargs = {"num_envs": 2, "preset": "tiny", **kwargs}
    with pytest.raises(ConfigError) as error:
        AuvSwiptVectorEnv(**kwargs)
    assert error.value.field == field and field in str(error.value)


def test_bad_calls():
    env = AuvSwiptVectorEnv(2, preset="tiny", observation="vector")
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(2, dtype=np.int64))
    with pytest.raises(ConfigError, match="seed") as error:
        env.reset(seed=[1, 2, 3])
    assert error.value.field == "seed"
    with pytest.raises(ConfigError, match=r"unknown reset option 'layout'") as error:
        env.reset(options={"layout": 3})
    assert error.value.field == "options"
    with pytest.raises(ConfigError, match="reset_mask"):
        env.reset(options={"reset_mask": [True, False]})
    with pytest.raises(ConfigError, match="layout_seed"):
        env.reset(options={"layout_seed": -1})
    env.reset(seed=0)
    for bad in (np.zeros(3, dtype=np.int64), np.array([0, 7]), np.array([0.5, 1.0]), np.array([-1, 0]), "up"):
        with pytest.raises(ValueError, match="actions"):
            env.step(bad)
    env.step(np.array([1.0, 6.0]))  # integral floats are integers
    continuous = AuvSwiptVectorEnv(2, "continuous", preset="tiny")
    continuous.reset(seed=0)
    for bad in (np.zeros(3), np.zeros((2, 2)), [["a", "b", "c"]] * 2, np.full((2, 3), 0.5 + 0.5j)):
        with pytest.raises(ValueError, match="actions"):
            continuous.step(bad)
    for big in (np.zeros((10**6, 3)), np.zeros(10**6, dtype=np.int64)):  # messages stay one short line
        with pytest.raises(ValueError) as info:
            (continuous if big.ndim == 2 else env).step(big)
        assert len(str(info.value)) < 200 and "\n" not in str(info.value)
    with pytest.raises(ConfigError, match="world"):
        gym.make_vec(swiptopt.ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", world="continuous")
