"""The fleet's stop-choice environment (planners.stops.fleet): masks, rewards, the order of
decisions, no shared targets, a fleet of one against the single env, seeding, the policy
adapter and MaskablePPO on it."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from planners.stops import DWELLS, FleetStopChoiceEnv, FleetStopChoicePolicy, StopChoiceEnv
from swiptopt import Scenario
from swiptopt import kernel as K
from swiptopt.env_fleet import AuvFleetEnv
from swiptopt.evaluation import evaluate_fleet

SMALL = Scenario.preset("paper", n_nodes=10, episode_steps=40, layout_seed=2)


def random_episode(env, seed, rng_seed=0):
    """One episode of uniformly random allowed actions: (observations, rewards, infos, masks)."""
    rng = np.random.default_rng(rng_seed)
    obs, _ = env.reset(seed=seed)
    observations, rewards, infos, masks = [obs], [], [], []
    while True:
        masks.append(env.action_masks())
        obs, reward, terminated, truncated, info = env.step(int(rng.choice(np.flatnonzero(masks[-1]))))
        observations.append(obs)
        rewards.append(reward)
        infos.append(info)
        if terminated or truncated:
            return observations, rewards, infos, masks


@pytest.fixture(scope="module")
def pair():
    """The stop env of two AUVs on the small scenario (built once per test process)."""
    return FleetStopChoiceEnv(SMALL, n_auvs=2)


def test_random_allowed_play_sums_to_the_fleets_return(pair):
    assert pair.observation_space.shape == (4 + 6 * 10 + 4 * 20 + 8,)
    for seed in range(4):
        observations, rewards, infos, _ = random_episode(pair, seed, rng_seed=seed)
        assert not any(i["masked"] for i in infos)  # masked_action="raise": a masked action would have raised
        assert all(pair.observation_space.contains(o) for o in observations)
        assert sum(i["kernel_steps"] for i in infos) == len(pair.kernel_actions) == SMALL.episode_steps
        metrics = pair.episode_metrics()
        assert metrics == infos[-1]["episode_metrics"] and metrics["n_auvs"] == 2
        assert math.fsum(rewards) == pytest.approx(metrics["return"], rel=1e-9, abs=1e-12)
        parts = math.fsum(sum(i["reward_parts"].values()) for i in infos)
        assert parts == pytest.approx(metrics["return"], rel=1e-9, abs=1e-12)


def test_decisions_are_asked_in_auv_order_without_stepping(pair):
    _, info = pair.reset(seed=3)
    assert info["next_auv"] == 0 == pair.deciding_auv
    first = int(np.flatnonzero(pair.action_masks())[0])
    _, reward, _, _, info = pair.step(first)
    # AUV 1 needs its first decision at the same step: no step taken, no reward
    assert (info["auv"], info["next_auv"], info["kernel_steps"], reward) == (0, 1, 0, 0.0)
    for _ in range(6):
        before = pair.deciding_auv
        _, _, _, _, info = pair.step(int(np.flatnonzero(pair.action_masks())[0]))
        assert info["auv"] == before
        # the next to decide: the first AUV whose assignment is done
        assert info["next_auv"] == min(k for k, c in enumerate(pair.targets()) if c < 0) == pair.deciding_auv


def test_a_candidate_another_auv_heads_to_is_masked_and_refused(pair):
    pair.reset(seed=0)
    stops = pair.stops_layout()
    cells = pair.env.fleet_state.cells
    d = len(DWELLS)
    # a stop with a dwell of 1 that AUV 0 may take and that is close to AUV 1 too
    ok = [a for a in np.flatnonzero(pair.action_masks()[:-1])
          if a % d == 0 and stops.dist_to[a // d, cells[1]] <= 10]
    action = int(ok[0])
    pair.step(action)
    assert pair.deciding_auv == 1 and pair.targets()[0] == action // d
    assert not pair.action_masks()[action // d * d : action // d * d + d].any()
    with pytest.raises(ValueError, match=f"another AUV is heading to or dwelling at stop {action // d}"):
        pair.step(action)


def test_two_auvs_never_have_the_same_target():
    env = FleetStopChoiceEnv(SMALL, n_auvs=3)
    claimed = 0
    for seed in range(6):
        rng = np.random.default_rng(seed)
        env.reset(seed=seed)
        while True:
            k = env.deciding_auv
            masks = env.action_masks()
            others = {c for j, c in enumerate(env.targets()) if j != k and c >= 0}
            claimed += len(others)
            for c in others:
                assert not masks[c * len(DWELLS) : (c + 1) * len(DWELLS)].any()
            _, _, terminated, truncated, info = env.step(int(rng.choice(np.flatnonzero(masks))))
            targets = [c for c in env.targets() if c >= 0]
            assert len(targets) == len(set(targets))
            if terminated or truncated:
                break
    assert claimed > 50


def test_a_move_blocked_in_a_row_is_given_up_and_the_auv_decides_again():
    env = FleetStopChoiceEnv(SMALL, n_auvs=3)
    seen = 0
    for seed in range(12):
        rng = np.random.default_rng(seed)
        env.reset(seed=seed)
        while True:
            _, _, terminated, truncated, info = env.step(int(rng.choice(np.flatnonzero(env.action_masks()))))
            for k in info["given_up_auvs"]:
                agent = f"auv_{k}"
                last = [step[agent] for step in env.kernel_actions[-3:]]
                assert all(a != K.HOVER for a in last) and len(set(last)) == 1  # the same move tried 3 times
                assert len(set(env.env.paths[k][-4:])) == 1  # and blocked each time
                assert env.targets()[k] == -1 and not (terminated or truncated)
                seen += 1
            if terminated or truncated:
                break
    assert seen > 0


def test_a_fleet_of_one_plays_the_single_envs_episodes():
    single, fleet = StopChoiceEnv(SMALL), FleetStopChoiceEnv(SMALL)
    assert fleet.observation_space == single.observation_space
    for seed in (4, 5):
        a_obs, a_rewards, a_infos, a_masks = random_episode(single, seed, rng_seed=seed)
        b_obs, b_rewards, b_infos, b_masks = random_episode(fleet, seed, rng_seed=seed)
        assert len(a_obs) == len(b_obs) and all(np.array_equal(x, y) for x, y in zip(a_obs, b_obs))
        assert all(np.array_equal(x, y) for x, y in zip(a_masks, b_masks))
        assert a_rewards == b_rewards
        for a, b in zip(a_infos, b_infos):
            assert {k: a[k] for k in ("kernel_steps", "reward_parts", "stop", "dwell", "masked")} == {
                k: b[k] for k in ("kernel_steps", "reward_parts", "stop", "dwell", "masked")}
        assert single.kernel_actions == [step["auv_0"] for step in fleet.kernel_actions]
        ours, theirs = a_infos[-1]["episode_metrics"], b_infos[-1]["episode_metrics"]
        assert {k: theirs[k] for k in ours} == dict(ours)


def test_the_same_seed_gives_the_same_episode():
    first, second = FleetStopChoiceEnv(SMALL, n_auvs=2), FleetStopChoiceEnv(SMALL, n_auvs=2)
    a_obs, a_rewards, a_infos, _ = random_episode(first, seed=5, rng_seed=1)
    b_obs, b_rewards, b_infos, _ = random_episode(second, seed=5, rng_seed=1)
    assert len(a_obs) == len(b_obs) and all(np.array_equal(x, y) for x, y in zip(a_obs, b_obs))
    assert a_rewards == b_rewards and first.kernel_actions == second.kernel_actions
    assert a_infos[-1]["episode_metrics"] == b_infos[-1]["episode_metrics"]
    _, c_rewards, _, _ = random_episode(second, seed=6, rng_seed=1)
    assert c_rewards != a_rewards


def test_check_env_passes():
    from gymnasium.utils.env_checker import check_env

    check_env(FleetStopChoiceEnv(SMALL, n_auvs=2, masked_action="hover"), skip_render_check=True)


class FirstAllowed:
    """A stand-in model: the first allowed action."""

    def predict(self, obs, deterministic=True, action_masks=None):
        return int(np.flatnonzero(action_masks)[0]), None


def test_the_adapter_plays_the_envs_episodes_on_several_layouts():
    env = FleetStopChoiceEnv(SMALL, n_auvs=2, layout_seeds=[2, 5])
    model = FirstAllowed()
    returns = []
    for i in range(4):
        obs, _ = env.reset(seed=100 + i)
        while True:
            action, _ = model.predict(obs, action_masks=env.action_masks())
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                returns.append(info["episode_metrics"]["return"])
                break
    result = evaluate_fleet(FleetStopChoicePolicy.from_env(model, env),
                            AuvFleetEnv(SMALL, n_auvs=2, layout_seeds=[2, 5]), episodes=4, seed=100)
    assert [r["return"] for r in result.records] == returns
    assert len({r["layout_seed"] for r in result.records}) == 2  # both layouts played


def test_an_auv_whose_battery_is_spent_is_asked_nothing_more():
    env = FleetStopChoiceEnv(SMALL, n_auvs=2, auv_batteries_j=(0.0005 * SMALL.battery_j, SMALL.battery_j))
    _, rewards, infos, _ = random_episode(env, seed=0)
    metrics = env.episode_metrics()
    gone = metrics["steps_each"][0]
    assert gone < 10 and metrics["steps_each"][1] == SMALL.episode_steps
    steps = np.cumsum([i["kernel_steps"] for i in infos])
    assert all(i["auv"] == 1 for i, t in zip(infos[1:], steps) if t >= gone)  # decisions after it left
    assert env.targets()[0] == -1
    assert math.fsum(rewards) == pytest.approx(metrics["return"], rel=1e-9, abs=1e-12)


def test_the_adapter_says_what_to_do_before_begin_episode(pair):
    policy = FleetStopChoicePolicy.from_env(FirstAllowed(), pair)
    with pytest.raises(RuntimeError, match="begin_episode"):
        policy.act(None)


def test_maskable_ppo_trains_and_its_adapter_replays_its_episodes_on_the_fleet_env(pair):
    from sb3_contrib import MaskablePPO

    from rl.deep import pin_torch

    pin_torch()
    env = pair  # masked_action="raise": a masked action would stop the training with an error
    model = MaskablePPO("MlpPolicy", env, n_steps=64, batch_size=64, n_epochs=2, seed=0, device="cpu")
    model.learn(256)

    returns = []
    for i in range(3):
        obs, _ = env.reset(seed=1_000 + i)
        while True:
            action, _ = model.predict(obs, deterministic=True, action_masks=env.action_masks())
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                returns.append(info["episode_metrics"]["return"])
                break
    policy = FleetStopChoicePolicy.from_env(model, env)
    result = evaluate_fleet(policy, AuvFleetEnv(SMALL, n_auvs=2), episodes=3, seed=1_000)
    assert [r["return"] for r in result.records] == returns
