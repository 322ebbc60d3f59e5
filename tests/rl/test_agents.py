import numpy as np
import pytest

import swiptopt
from rl import QLearningAgent, RandomAgent, SarsaAgent, TabularConfig, make_agent, train
from swiptopt.env import AuvSwiptEnv


def test_paper_defaults():
    c = TabularConfig()
    assert (c.learning_rate, c.discount, c.epsilon_start, c.epsilon_decay, c.epsilon_min) == (0.75, 0.99, 1.0, 0.999, 0.001)
    assert c.replay_size == 0


@pytest.mark.parametrize("bad", [0.0, -0.1, 1.5, float("nan"), True])
def test_learning_rate_out_of_range_names_the_argument(bad):
    with pytest.raises(swiptopt.ConfigError, match="learning_rate") as info:
        QLearningAgent(10, learning_rate=bad)
    assert info.value.field == "learning_rate"


def test_other_bad_settings():
    with pytest.raises(swiptopt.ConfigError, match="discount"):
        TabularConfig(discount=1.2)
    with pytest.raises(swiptopt.ConfigError, match="unknown agent setting 'lr'"):
        SarsaAgent(10, lr=0.5)
    with pytest.raises(swiptopt.ConfigError, match="unknown algorithm 'dqn'"):
        make_agent("dqn", 10)
    with pytest.raises(swiptopt.ConfigError, match="n_states"):
        QLearningAgent(0)


def test_epsilon_schedule_follows_the_paper():
    env = AuvSwiptEnv(preset="tiny")
    agent = QLearningAgent(env.observation_space.n, seed=0, epsilon_decay=0.5, epsilon_min=0.1)
    log = train(agent, env, 6, seed=0)
    np.testing.assert_allclose(log["epsilon"], [1.0, 0.5, 0.25, 0.125, 0.1, 0.1])
    assert agent.epsilon_ == 0.1


def test_save_load_round_trip(tmp_path):
    env = AuvSwiptEnv(preset="paper", n_nodes=10)
    agent = SarsaAgent(env.observation_space.n, seed=3, learning_rate=0.5)
    train(agent, env, 300, seed=1, backend="compiled")
    before = swiptopt.evaluate(agent, env, episodes=5, seed=50)
    path = tmp_path / "sarsa.npz"
    agent.save(path)
    loaded = SarsaAgent.load(path)
    np.testing.assert_array_equal(loaded.q_table_, agent.q_table_)
    assert loaded.config == agent.config and loaded.epsilon_ == agent.epsilon_
    assert loaded.rng_.random() == agent.rng_.random()  # generator state restored
    after = swiptopt.evaluate(loaded, env, episodes=5, seed=50)
    assert after.records == before.records
    with np.load(path, allow_pickle=False) as data:  # plain arrays, no pickle
        assert set(data.files) >= {"q_table", "config", "epsilon", "rng_state"}
    with pytest.raises(swiptopt.ConfigError, match="sarsa"):
        QLearningAgent.load(path)


def test_random_agent_uses_its_own_generator():
    a, b = RandomAgent(seed=4), RandomAgent(seed=4)
    assert [a.predict(0) for _ in range(50)] == [b.predict(0) for _ in range(50)]
    assert len({a.predict(0) for _ in range(200)}) == 7
