import numpy as np
import pytest

from rl import core


def test_td_update_q_learning_sarsa_and_terminal():
    q = np.array([[0.0, 0.0], [1.0, 3.0]])
    core.td_update(q, 0, 1, 2.0, 1, 0, False, False, 0.5, 0.9)  # target 2 + 0.9 * max(1, 3)
    assert q[0, 1] == pytest.approx(0.5 * (2.0 + 2.7))
    q = np.array([[0.0, 0.0], [1.0, 3.0]])
    core.td_update(q, 0, 1, 2.0, 1, 0, False, True, 0.5, 0.9)  # SARSA: Q[s', a'=0] = 1
    assert q[0, 1] == pytest.approx(0.5 * (2.0 + 0.9))
    q = np.array([[0.0, 4.0], [1.0, 3.0]])
    core.td_update(q, 0, 1, 2.0, 1, 0, True, False, 0.25, 0.9)  # terminal: target = r
    assert q[0, 1] == pytest.approx(4.0 + 0.25 * (2.0 - 4.0))


def test_greedy_and_epsilon_greedy_actions():
    q = np.array([[0.0, 5.0, 5.0, 1.0]])
    assert core.greedy_action(q, 0) == 1  # lowest index among ties
    rng = np.random.default_rng(0)
    picks = [core.epsilon_greedy_action(q, 0, 0.0, rng) for _ in range(2000)]
    assert set(picks) == {1, 2}  # ties broken at random, never a worse action
    assert abs(np.mean(np.array(picks) == 1) - 0.5) < 0.05
    rng = np.random.default_rng(1)
    explore = [core.epsilon_greedy_action(q, 0, 1.0, rng) for _ in range(4000)]
    np.testing.assert_allclose(np.bincount(explore, minlength=4) / 4000, 0.25, atol=0.03)
