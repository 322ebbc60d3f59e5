"""The stop-choice environments (planners.stops): masks, rewards, executors, seeding, layouts,
the policy adapter, and MaskablePPO on them.

The continuous world's OMPL legs are planned in fresh child processes (OMPL's seed is
process-wide); the layout they are built for here is built once per test process (the
module's cache), and one test builds it again to hold the two builds to the same legs.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import swiptopt
from planners.policies import Plan, PlanExecutor, Stop
from planners.stops import (
    DWELLS,
    ContinuousStopChoiceEnv,
    Dwell,
    StopChoiceEnv,
    StopChoicePolicy,
    build_grid_stops,
    make_stop_env,
)
from planners.stops.continuous import ContinuousStopSettings, build_continuous_stops
from swiptopt import Scenario
from swiptopt import kernel as K
from swiptopt.env import AuvSwiptEnv
from swiptopt.env_continuous import AuvSwiptContinuousEnv
from swiptopt.errors import ConfigError

PAPER_10 = Scenario.preset("paper", n_nodes=10, layout_seed=2)


class ObservationGreedy:
    """A deterministic stand-in for a trained model, reading only the stop observation and the
    masks: the allowed action whose stop earns the most in one step per step of the way there,
    longer dwells slightly preferred."""

    def __init__(self, env):
        self.candidates = env.unwrapped.n_candidates
        self.dwells = len(env.unwrapped.settings.dwells)

    def predict(self, obs, deterministic=True, action_masks=None):
        features = np.asarray(obs)[-4 * self.candidates :].reshape(self.candidates, 4)
        per_stop = features[:, 1] / (features[:, 0] + 0.02)
        score = np.repeat(per_stop, self.dwells) * (1.0 + 0.01 * np.tile(np.arange(self.dwells), self.candidates))
        score = np.append(score, -1.0)
        score[~np.asarray(action_masks, dtype=bool)] = -np.inf
        return int(np.argmax(score)), None


def random_episode(env, seed, rng_seed=0, options=None):
    """One episode of uniformly random allowed actions: (observations, rewards, infos)."""
    rng = np.random.default_rng(rng_seed)
    obs, _ = env.reset(seed=seed, options=options)
    observations, rewards, infos = [obs], [], []
    while True:
        action = int(rng.choice(np.flatnonzero(env.action_masks())))
        obs, reward, terminated, truncated, info = env.step(action)
        observations.append(obs)
        rewards.append(reward)
        infos.append(info)
        if terminated or truncated:
            return observations, rewards, infos


def stop_env_returns(env, model, seed, episodes):
    """The kernel returns of the model's episodes in the stop env on seeds seed, seed + 1, ..."""
    out = []
    for i in range(episodes):
        obs, _ = env.reset(seed=seed + i)
        while True:
            action, _ = model.predict(obs, deterministic=True, action_masks=env.action_masks())
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                out.append(info["episode_metrics"]["return"])
                break
    return out


# ----------------------------------------------------------------------------- candidates


def one_step_value(scenario, cell):
    """(n_nodes,) the reward one hover step at ``cell`` earns from each node, by running the
    kernel itself (a deterministic channel), from a fresh state."""
    tables = K.build_tables(scenario)
    state = K.new_state(tables)
    state.where[K.W_CELL] = cell
    uniforms, normals = K.noise_buffers(tables)
    K.refill_noise(np.random.default_rng(0), tables, uniforms, normals, state.where)
    K.step(K.HOVER, uniforms, normals, K.step_args(tables, state))
    p = tables.params
    return (p[K.P_GAMMA] * state.collected / p[K.P_DATA_REF]
            + (1 - p[K.P_GAMMA]) * state.delivered / p[K.P_ENERGY_REF])


def test_tiny_candidates_are_the_cells_above_the_nodes_and_the_shared_cell():
    scenario = Scenario.preset("tiny")  # 3 x 3 x 2 cells of 10 m, the start at (1, 1, 0), 8 steps
    env = StopChoiceEnv(scenario)
    env.reset(seed=0)
    stops = env.stops_layout()
    cells = [tuple(int(v) for v in scenario.cell_of_index(c)) for c in stops.cells]
    # node 0 at (28.3, 9.5, 14.4) m and node 1 at (3.8, 12.7, 13.0) m: their own stops are the
    # top cells right above them; node 2 at 5.4 m depth, 3.3 m across from the nearest top
    # cell's centre, is outside every 60-degree cone (no stop). The cell between nodes 0 and
    # 1 (the start) covers both: node 0's shared stop; node 1's is the same cell (a copy).
    assert cells[:2] == [(2, 0, 0), (0, 1, 0)]
    assert cells[3] == (1, 1, 0)
    assert stops.valid.tolist() == [True, True, False, True, False, False]
    assert "no reachable cell covers node 2" in stops.why_invalid[2]
    assert stops.why_invalid[4] == "its cell is stop 3's"

    # the brute force: every cell's one-step value from each node, by the kernel itself
    values = np.array([one_step_value(scenario, c) for c in range(scenario.n_cells)])  # (cells, nodes)
    for node in (0, 1):
        best = max(range(scenario.n_cells), key=lambda c: (values[c, node], values[c].sum(), -c))
        assert stops.cells[node] == best
    shared = max((c for c in range(scenario.n_cells) if values[c, 0] >= 0.5 * values[:, 0].max()),
                 key=lambda c: (values[c].sum(), values[c, 0], -c))
    assert stops.cells[3] == shared


def test_tiny_masks_follow_the_distances_and_the_steps_left():
    env = StopChoiceEnv(Scenario.preset("tiny"))
    env.reset(seed=0)
    masks = env.action_masks()
    d = len(DWELLS)
    table = masks[:-1].reshape(6, d)
    # stop 0 is two moves away: a fixed dwell of 8 takes 2 + 8 - 1 = 9 > 8 steps, masked;
    # everything else at stops 0, 1 (one move) and 3 (here) fits the 8 steps
    assert table[0].tolist() == [True, True, True, True, False, True, True]
    assert table[1].all() and table[3].all()
    assert not table[[2, 4, 5]].any()
    assert not masks[-1]  # the fallback only when nothing else is allowed


# ----------------------------------------------------------------------------- returns


@pytest.mark.parametrize("seed", [11, 12])
def test_the_episode_return_is_the_kernel_return_of_the_same_kernel_actions(seed):
    env = StopChoiceEnv(PAPER_10)
    _, rewards, infos = random_episode(env, seed, rng_seed=seed)
    actions = list(env.kernel_actions)
    assert sum(i["kernel_steps"] for i in infos) == len(actions)
    kernel = AuvSwiptEnv(PAPER_10, observation="vector")
    kernel.reset(seed=seed)
    kernel_rewards = []
    for a in actions:
        _, r, terminated, truncated, info = kernel.step(a)
        kernel_rewards.append(r)
    assert terminated or truncated
    assert info["episode_metrics"] == infos[-1]["episode_metrics"]  # the same kernel episode
    assert math.fsum(rewards) == pytest.approx(math.fsum(kernel_rewards), rel=1e-12, abs=1e-12)
    assert math.fsum(rewards) == pytest.approx(infos[-1]["episode_metrics"]["return"], rel=1e-12, abs=1e-12)
    parts = math.fsum(sum(i["reward_parts"].values()) for i in infos)
    assert parts == pytest.approx(math.fsum(rewards), rel=1e-12, abs=1e-12)


def test_a_fixed_dwell_takes_the_moves_plus_the_dwell_and_never_overruns_the_episode():
    env = StopChoiceEnv(PAPER_10)
    checked = 0
    for seed in range(6):
        rng = np.random.default_rng(seed)
        env.reset(seed=seed)
        while True:
            masks = env.action_masks()
            action = int(rng.choice(np.flatnonzero(masks)))
            stop, dwell = env._episode.decode(action)
            steps_left = PAPER_10.episode_steps - env.env.state.t
            moves = int(env.stops_layout().dist_to[stop, env.env.state.cell]) if stop >= 0 else 0
            _, _, terminated, truncated, info = env.step(action)
            if stop >= 0 and DWELLS[dwell].until is None and not terminated:
                expected = moves + DWELLS[dwell].steps - (moves > 0)
                assert expected <= steps_left
                assert info["kernel_steps"] == expected
                checked += 1
            if terminated or truncated:
                break
    assert checked > 20


def test_the_moves_to_a_stop_are_the_planners_executors():
    class OneStop(PlanExecutor):
        def __init__(self, cell, steps):
            super().__init__(linger_steps=0)
            self.stop = Stop(cell, steps)

        def make_plan(self, env):
            return Plan([self.stop])

    env = StopChoiceEnv(PAPER_10)
    env.reset(seed=3)
    stops = env.stops_layout()
    far = int(np.argmax(np.where(stops.valid, stops.dist_to[:, env.env.state.cell], -1)))
    action = far * len(DWELLS) + 2  # dwell 3
    assert env.action_masks()[action]
    env.step(action)
    ours = list(env.kernel_actions)
    kernel = AuvSwiptEnv(PAPER_10, observation="vector")
    kernel.reset(seed=3)
    executor = OneStop(int(stops.cells[far]), 3)
    executor.begin_episode(kernel)
    theirs = []
    for _ in ours:
        theirs.append(executor.predict(None))
        kernel.step(theirs[-1])
    assert len(ours) == stops.dist_to[far, PAPER_10.start_cell_index] + 2
    assert ours == theirs


# ----------------------------------------------------------------------------- the adapter


@pytest.mark.parametrize("observation", ["tabular", "vector"])
def test_the_adapter_plays_the_stop_envs_episodes_under_evaluate(observation):
    env = StopChoiceEnv(PAPER_10, layout_seeds=[2, 5])
    model = ObservationGreedy(env)
    returns = stop_env_returns(env, model, seed=100, episodes=4)
    policy = StopChoicePolicy.from_env(model, env)
    kernel = AuvSwiptEnv(PAPER_10, observation=observation, layout_seeds=[2, 5])
    result = swiptopt.evaluate(policy, kernel, episodes=4, seed=100)
    assert [r["return"] for r in result.records] == returns
    assert len({r["layout_seed"] for r in result.records}) == 2  # both layouts played


def test_the_adapter_plays_the_continuous_stop_envs_episodes_under_evaluate():
    env = ContinuousStopChoiceEnv(legs="straight")
    model = ObservationGreedy(env)
    returns = stop_env_returns(env, model, seed=7, episodes=2)
    policy = StopChoicePolicy.from_env(model, env)
    result = swiptopt.evaluate(policy, AuvSwiptContinuousEnv(), episodes=2, seed=7)
    assert [r["return"] for r in result.records] == returns


def test_the_adapter_says_what_to_do_before_begin_episode():
    env = StopChoiceEnv(PAPER_10)
    policy = StopChoicePolicy.from_env(ObservationGreedy(env), env)
    with pytest.raises(RuntimeError, match="begin_episode"):
        policy.predict(None)


# ----------------------------------------------------------------------------- seeding, spaces, layouts


def test_the_same_seed_and_actions_give_the_same_episode_bit_for_bit():
    first, second = StopChoiceEnv(PAPER_10), StopChoiceEnv(PAPER_10)
    a_obs, a_rewards, a_infos = random_episode(first, seed=5, rng_seed=1)
    b_obs, b_rewards, b_infos = random_episode(second, seed=5, rng_seed=1)
    assert all(np.array_equal(x, y) for x, y in zip(a_obs, b_obs)) and len(a_obs) == len(b_obs)
    assert a_rewards == b_rewards
    assert first.kernel_actions == second.kernel_actions
    assert a_infos[-1]["episode_metrics"] == b_infos[-1]["episode_metrics"]
    # another seed draws other link failures and fading: another episode
    _, c_rewards, _ = random_episode(second, seed=6, rng_seed=1)
    assert c_rewards != a_rewards


def test_check_env_passes_in_the_grid_world():
    from gymnasium.utils.env_checker import check_env

    # check_env steps with actions drawn from the action space, masks unknown to it: masked ones
    # are executed as one hover here instead of being refused
    check_env(StopChoiceEnv(PAPER_10, masked_action="hover"), skip_render_check=True)


def test_a_masked_action_is_refused_saying_why_or_hovers_when_asked():
    env = StopChoiceEnv(Scenario.preset("tiny"))
    env.reset(seed=0)
    d = len(DWELLS)
    with pytest.raises(ValueError, match=r"action 14 is masked: \(stop 2, dwell 1\): stop 2 does not exist"):
        env.step(2 * d)
    with pytest.raises(ValueError, match="do not fit the 8 steps left"):
        env.step(4)  # stop 0, dwell 8
    with pytest.raises(ValueError, match="the hover fallback is allowed only when no stop is"):
        env.step(env.action_space.n - 1)
    with pytest.raises(ValueError, match="one integer"):
        env.step(env.action_space.n)

    hovering = StopChoiceEnv(Scenario.preset("tiny"), masked_action="hover")
    hovering.reset(seed=0)
    _, _, _, _, info = hovering.step(2 * d)
    assert info["masked"] and info["kernel_steps"] == 1 and hovering.kernel_actions == [K.HOVER]


def test_when_nothing_is_allowed_only_the_fallback_is_and_it_hovers_one_step():
    # from a deep corner cell every stop is at least three moves away, and there are two steps
    scenario = Scenario.preset("tiny", start_cell=(2, 2, 1), episode_steps=2)
    env = StopChoiceEnv(scenario)
    obs, _ = env.reset(seed=0)
    masks = env.action_masks()
    assert masks[-1] and not masks[:-1].any()
    assert not obs[-4 * 6 :].reshape(6, 4)[:, 3].any()  # no candidate flagged allowed
    _, _, terminated, truncated, info = env.step(env.action_space.n - 1)
    assert info["kernel_steps"] == 1 and env.kernel_actions == [K.HOVER] and not (terminated or truncated)
    _, _, terminated, truncated, info = env.step(env.action_space.n - 1)
    assert truncated and "episode_metrics" in info


def test_the_mask_is_never_all_false_and_the_fallback_only_when_nothing_else_is():
    env = StopChoiceEnv(PAPER_10)
    fallbacks = 0
    for seed in range(8):
        rng = np.random.default_rng(seed)
        env.reset(seed=seed)
        while True:
            masks = env.action_masks()
            assert masks[-1] == (not masks[:-1].any())
            fallbacks += int(masks[-1])
            _, _, terminated, truncated, _ = env.step(int(rng.choice(np.flatnonzero(masks))))
            if terminated or truncated:
                break
    assert fallbacks > 0  # random tours end with steps too few to reach anything


def test_layouts_per_episode_build_their_own_candidates():
    env = StopChoiceEnv(PAPER_10, layout_seeds=range(20))
    _, info = env.reset(seed=0, options={"layout_seed": 7})
    assert info["layout_seed"] == 7 and env.scenario.layout_seed == 7
    direct = build_grid_stops(K.build_tables(PAPER_10.replace(layout_seed=7)), PAPER_10.replace(layout_seed=7),
                              env.settings)
    assert np.array_equal(env.stops_layout().cells, direct.cells)
    first = env.stops_layout().cells.copy()
    _, info = env.reset(seed=1, options={"layout_seed": 3})
    assert not np.array_equal(env.stops_layout().cells, first)
    seen = {env.reset(seed=s)[1]["layout_seed"] for s in range(10)}
    assert len(seen) > 3 and seen <= set(range(20))
    assert env.observation_space.contains(env.reset(seed=2)[0])


def test_bad_settings_are_refused_naming_the_setting():
    with pytest.raises(ConfigError, match="candidates"):
        StopChoiceEnv(PAPER_10, candidates="all")
    with pytest.raises(ConfigError, match="shared_fraction"):
        StopChoiceEnv(PAPER_10, shared_fraction=0.0)
    with pytest.raises(ConfigError, match="Dwell.until"):
        StopChoiceEnv(PAPER_10, dwells=[1, Dwell(3, "forever")])
    with pytest.raises(ConfigError, match="legs"):
        ContinuousStopChoiceEnv(legs="curvy")
    with pytest.raises(ConfigError, match="world"):
        make_stop_env("water", PAPER_10)


def test_make_stop_env_builds_each_world():
    assert type(make_stop_env("grid", PAPER_10, layout_seeds=[1, 2], candidates="own")) is StopChoiceEnv
    env = make_stop_env("continuous", "harbour", legs="straight")
    assert type(env) is ContinuousStopChoiceEnv and env.observation_space.shape == (4 + 6 * 20 + 4 * 20,)


# ----------------------------------------------------------------------------- the continuous world


@pytest.fixture(scope="module")
def harbour():
    """The continuous stop env on the harbour with OMPL legs (built once per test process)."""
    return ContinuousStopChoiceEnv()


def test_ompl_legs_are_free_and_followed_without_giving_up(harbour):
    stops = harbour.stops_layout()
    sources = set(stops.sources.values())
    assert "ompl" in sources and "straight" in sources  # the pier blocks some straight legs
    from planners.paths3d import segments_free

    for (site, cand), path in stops.routes.items():
        if stops.route_steps[site, cand] > 0:
            assert segments_free(path[:-1], path[1:], harbour.scenario).all()
    for seed in (1, 2):
        _, rewards, infos = random_episode(harbour, seed, rng_seed=seed)
        assert not any(i["given_up"] for i in infos)


def test_the_continuous_return_is_the_kernel_return_of_the_same_actions(harbour):
    _, rewards, infos = random_episode(harbour, 4, rng_seed=4)
    kernel = AuvSwiptContinuousEnv()
    kernel.reset(seed=4)
    for a in harbour.kernel_actions:
        _, _, terminated, truncated, info = kernel.step(a)
    assert terminated or truncated
    assert info["episode_metrics"] == infos[-1]["episode_metrics"]
    assert math.fsum(rewards) == pytest.approx(info["episode_metrics"]["return"], rel=1e-12, abs=1e-12)


def test_ompl_legs_are_the_same_when_built_again_in_another_fresh_process(harbour):
    cached = harbour.stops_layout()
    again = build_continuous_stops(harbour.env.world, harbour.scenario, ContinuousStopSettings())
    assert cached.routes.keys() == again.routes.keys()
    assert all(np.array_equal(cached.routes[k], again.routes[k]) for k in cached.routes)
    assert np.array_equal(cached.route_steps, again.route_steps)


def test_check_env_passes_in_the_continuous_world(harbour):
    from gymnasium.utils.env_checker import check_env

    check_env(ContinuousStopChoiceEnv(masked_action="hover"), skip_render_check=True)


def test_straight_legs_through_the_pier_are_given_up_and_the_episode_goes_on():
    env = ContinuousStopChoiceEnv(legs="straight")
    given_up = 0
    for seed in range(4):
        _, rewards, infos = random_episode(env, seed, rng_seed=seed)
        given_up += sum(i["given_up"] for i in infos)
        assert sum(i["kernel_steps"] for i in infos) <= env.scenario.episode_steps
        assert "episode_metrics" in infos[-1]
    assert given_up > 0


def test_continuous_layouts_per_episode_and_the_same_seed_give_the_same_episode():
    first = ContinuousStopChoiceEnv(legs="straight", layout_seeds=[0, 3])
    second = ContinuousStopChoiceEnv(legs="straight", layout_seeds=[0, 3])
    a_obs, a_rewards, _ = random_episode(first, seed=9, rng_seed=2, options={"layout_seed": 3})
    b_obs, b_rewards, _ = random_episode(second, seed=9, rng_seed=2, options={"layout_seed": 3})
    assert first.scenario.layout_seed == 3
    assert a_rewards == b_rewards and all(np.array_equal(x, y) for x, y in zip(a_obs, b_obs))
    assert all(np.array_equal(x, y) for x, y in zip(first.kernel_actions, second.kernel_actions))
    points_3 = first.stops_layout().points_m.copy()
    first.reset(seed=9, options={"layout_seed": 0})
    assert not np.array_equal(first.stops_layout().points_m, points_3)


# ----------------------------------------------------------------------------- MaskablePPO


class RecordMasks(gym.Wrapper):
    """Records, for every action taken, whether the env's masks allowed it."""

    def __init__(self, env):
        super().__init__(env)
        self.allowed: list[bool] = []

    def action_masks(self):
        return self.env.action_masks()

    def step(self, action):
        self.allowed.append(bool(self.env.action_masks()[int(action)]))
        return self.env.step(action)


def test_maskable_ppo_never_takes_a_masked_action_and_its_adapter_plays_its_episodes():
    from sb3_contrib import MaskablePPO

    from rl.deep import pin_torch

    pin_torch()
    env = RecordMasks(StopChoiceEnv(PAPER_10, masked_action="hover"))  # "hover": a masked action would not stop the run
    model = MaskablePPO("MlpPolicy", env, n_steps=64, batch_size=64, n_epochs=2, seed=0, device="cpu")
    model.learn(512)
    assert len(env.allowed) >= 512 and all(env.allowed)

    returns = stop_env_returns(env.unwrapped, model, seed=1_000, episodes=3)
    policy = StopChoicePolicy.from_env(model, env)
    result = swiptopt.evaluate(policy, AuvSwiptEnv(PAPER_10), episodes=3, seed=1_000)
    assert [r["return"] for r in result.records] == returns
