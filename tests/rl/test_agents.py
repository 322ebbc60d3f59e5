import numpy as np
import pytest

import swiptopt
from rl import QLearningAgent, RandomAgent, SarsaAgent, TabularConfig, make_agent, train
from swiptopt.env import AuvSwiptEnv


def test_paper_defaults():
    c = TabularConfig()
    learning = (c.learning_rate, c.discount, c.epsilon_start, c.epsilon_decay, c.epsilon_min)
    assert learning == (0.75, 0.99, 1.0, 0.999, 0.001)
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


def saved_agent(tmp_path):
    agent = QLearningAgent(12, seed=1, learning_rate=0.5)
    agent.q_table_[:] = np.arange(12 * 7).reshape(12, 7)
    path = tmp_path / "agent.npz"
    agent.save(path)
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    return path, arrays


def resave(tmp_path, arrays, **changes):
    path = tmp_path / "bad.npz"
    values = {**arrays, **changes}
    np.savez(path, **{k: v for k, v in values.items() if v is not None})
    return path


@pytest.mark.parametrize(
    "change, words",
    [
        ({"epsilon": None}, ["lacks the array 'epsilon'"]),
        ({"q_table": np.zeros((12, 7, 2))}, ["q_table must be a 2-D float array", "3-D"]),
        ({"q_table": np.zeros((12, 7), dtype=np.int64)}, ["q_table must be a 2-D float array", "int64"]),
        ({"q_table": np.zeros((0, 7))}, ["q_table must be a 2-D float array"]),
        ({"q_table": np.full((12, 7), np.nan)}, ["not finite"]),
        ({"epsilon": np.array([0.5, 0.5])}, ["epsilon must be a single float", "(2,)"]),
        ({"epsilon": np.array(3.0)}, ["epsilon = 3.0 must lie in [0, 1]"]),
        ({"seed": np.array("three")}, ["seed must be a single integer"]),
        ({"algorithm": np.array(7)}, ["algorithm must be a single str"]),
        ({"config": np.array('{"learning_rate": 0.5, "colour": "red"}')}, ["unknown agent setting 'colour'"]),
        ({"config": np.array('{"learning_rate": 7}')}, ["learning_rate = 7"]),
        ({"config": np.array("{not json")}, ["config is not valid JSON"]),
        ({"config": np.array("[1, 2]")}, ["config must be a JSON object"]),
        ({"rng_state": np.array('{"bit_generator": "MT19937"}')}, ["rng_state is not a state of PCG64"]),
    ],
)
def test_load_refuses_a_malformed_agent_file_in_one_line(tmp_path, change, words):
    _, arrays = saved_agent(tmp_path)
    path = resave(tmp_path, arrays, **change)
    with pytest.raises(swiptopt.ConfigError) as info:
        QLearningAgent.load(path)
    message = str(info.value)
    assert message.startswith(str(path)) and "\n" not in message
    for word in words:
        assert word in message


def test_load_refuses_files_that_are_not_agent_archives(tmp_path):
    path, _ = saved_agent(tmp_path)
    good = path.read_bytes()
    cases = {
        "absent.npz": None,
        "text.npz": b"q_table = 3\n",
        "truncated.npz": good[: len(good) // 2],
        "zeroed.npz": good[: len(good) // 2] + bytes(len(good) - len(good) // 2),
        "empty.npz": b"",
    }
    for name, content in cases.items():
        bad = tmp_path / name
        if content is not None:
            bad.write_bytes(content)
        with pytest.raises(swiptopt.ConfigError) as info:
            QLearningAgent.load(bad)
        assert str(bad) in str(info.value) and "\n" not in str(info.value), name
    single = tmp_path / "single.npy"
    np.save(single, np.zeros((12, 7)))
    with pytest.raises(swiptopt.ConfigError, match="single array, not an .npz archive"):
        QLearningAgent.load(single)
    _, arrays = saved_agent(tmp_path)
    with pytest.raises(swiptopt.ConfigError, match="Object arrays cannot be loaded when allow_pickle=False"):
        QLearningAgent.load(resave(tmp_path, arrays, q_table=np.array([{"a": 1}], dtype=object)))
    with pytest.raises(swiptopt.ConfigError, match="no such agent file"):
        QLearningAgent.load(tmp_path / "absent.npz")
    with pytest.raises(swiptopt.ConfigError, match="cannot read"):
        QLearningAgent.load(tmp_path)
    # the well-formed file still loads, exactly
    loaded = QLearningAgent.load(path)
    np.testing.assert_array_equal(loaded.q_table_, np.arange(12 * 7).reshape(12, 7))
    assert loaded.config.learning_rate == 0.5
