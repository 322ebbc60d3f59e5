import gymnasium as gym
import numpy as np
import pytest

import swiptopt
from rl import QLearningAgent, RandomAgent, SarsaAgent, TabularConfig, paper_protocol, train
from swiptopt import Scenario
from swiptopt.env import AuvSwiptEnv

SCENARIOS = [
    ("paper", {"n_nodes": 25}),
    ("harbour", {"channel": "rician", "harvester": "logistic"}),
    ("tiny", {}),
    ("paper", {"n_nodes": 12, "link": "uplink", "energy_gate_j": 0.1}),
]


def run(cls, backend, preset, overrides, episodes=150, seed=9):
    env = gym.make(swiptopt.ENV_ID, preset=preset, **overrides)
    agent = cls(seed=seed) if cls is RandomAgent else cls(env.observation_space.n, seed=seed)
    log = train(agent, env, episodes, seed=seed + 1, backend=backend)
    return agent, log


@pytest.mark.parametrize("preset, overrides", SCENARIOS)
@pytest.mark.parametrize("cls", [QLearningAgent, SarsaAgent, RandomAgent])
def test_backends_agree_bit_for_bit(cls, preset, overrides):
    a_py, log_py = run(cls, "python", preset, overrides)
    a_co, log_co = run(cls, "compiled", preset, overrides)
    np.testing.assert_array_equal(log_py.values, log_co.values)
    if cls is not RandomAgent:
        np.testing.assert_array_equal(a_py.q_table_, a_co.q_table_)
        assert a_py.epsilon_ == a_co.epsilon_
        assert np.any(a_py.q_table_ != 0)
    assert a_py.rng_.random() == a_co.rng_.random()  # the same number of draws was taken


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_same_seed_same_table_and_log_run_to_run(backend):
    a, log_a = run(QLearningAgent, backend, "paper", {}, episodes=200)
    b, log_b = run(QLearningAgent, backend, "paper", {}, episodes=200)
    np.testing.assert_array_equal(a.q_table_, b.q_table_)
    np.testing.assert_array_equal(log_a.values, log_b.values)
    c, _ = run(QLearningAgent, backend, "paper", {}, episodes=200, seed=10)
    assert not np.array_equal(a.q_table_, c.q_table_)


def test_bad_training_arguments():
    env = AuvSwiptEnv(preset="tiny")
    agent = QLearningAgent(env.observation_space.n, seed=0)
    with pytest.raises(swiptopt.ConfigError, match="backend"):
        train(agent, env, 5, backend="gpu")
    with pytest.raises(swiptopt.ConfigError, match="episodes"):
        train(agent, env, -1)
    vector = AuvSwiptEnv(preset="tiny", observation="vector")
    with pytest.raises(swiptopt.ConfigError, match="tabular"):
        train(agent, vector, 5, backend="compiled")
    replay = QLearningAgent(env.observation_space.n, seed=0, replay_size=100)
    with pytest.raises(swiptopt.ConfigError, match="replay"):
        train(replay, env, 5, backend="compiled")


def test_replay_option_learns_deterministically():
    env = AuvSwiptEnv(preset="paper", n_nodes=10)
    cfg = TabularConfig(replay_size=1000, replay_batch=4)
    a = QLearningAgent(env.observation_space.n, config=cfg, seed=2)
    b = QLearningAgent(env.observation_space.n, config=cfg, seed=2)
    plain = QLearningAgent(env.observation_space.n, seed=2)
    train(a, env, 40, seed=3)
    train(b, env, 40, seed=3)
    train(plain, env, 40, seed=3)
    np.testing.assert_array_equal(a.q_table_, b.q_table_)
    assert not np.array_equal(a.q_table_, plain.q_table_)


def test_agents_learn_on_unseen_layouts():
    """Paper preset, 25 nodes, paper's defaults, layouts and seeds not used while building
    the toolkit: the greedy policies beat the random trajectory on data, on bits per joule
    of AUV motion (the paper's efficiency) and on return, pooled over 8 layouts.
    (`swiptopt run rl-vs-random` measures the same over 40 layouts, with intervals.)"""
    metrics = ("data_bits", "mobility_efficiency_bit_per_j", "return")
    totals = {alg: np.zeros(len(metrics)) for alg in ("random", "q_learning", "sarsa")}
    for layout in range(21, 29):
        scenario = Scenario.preset("paper", n_nodes=25, layout_seed=layout)
        for alg in totals:
            result = paper_protocol(scenario, alg, train_episodes=20_000, eval_episodes=10, seed=layout)
            totals[alg] += [result.evaluation.summary[m].mean for m in metrics]
    q, sarsa, rand = totals["q_learning"] / totals["random"], totals["sarsa"] / totals["random"], totals["random"]
    assert np.all(rand > 0)
    assert q[0] > 1.3 and q[1] > 1.3 and q[2] > 2.0, q  # measured 1.9, 1.9, 3.1
    assert sarsa[0] > 1.1 and sarsa[1] > 1.1 and sarsa[2] > 1.5, sarsa  # measured 1.4, 1.5, 2.3


def test_training_episodes_beyond_the_limit_are_refused_before_the_log_is_allocated(monkeypatch):
    from rl.training import LOG_COLUMNS
    from swiptopt.limits import LOG_BYTES_PER_EPISODE

    assert LOG_BYTES_PER_EPISODE == 8 * len(LOG_COLUMNS)  # the message's size is the log's
    env = AuvSwiptEnv(preset="tiny")
    agent = QLearningAgent(env.observation_space.n, seed=0)
    with pytest.raises(swiptopt.ConfigError) as info:
        train(agent, env, 10**9, seed=0)
    assert info.value.field == "episodes"
    for words in ("1,000,000,000", "10,000,000", "SWIPTOPT_MAX_TRAINING_EPISODES", "59.6 GiB"):
        assert words in str(info.value)
    monkeypatch.setenv("SWIPTOPT_MAX_TRAINING_EPISODES", "20")
    with pytest.raises(swiptopt.ConfigError, match="21, over the limit of 20"):
        train(agent, env, 21, seed=0, backend="compiled")
    assert len(train(agent, env, 20, seed=0, backend="compiled")) == 20
