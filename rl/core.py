"""The agents' rules as plain functions over arrays, shared by the agents and the trainer.

Written so that numba compiles them unchanged: the compiled trainer runs these very
functions, so both training backends learn the same Q-table from the same seed. Every
random choice uses only ``rng.random()``, in a fixed order.
"""

from __future__ import annotations


def random_action(rng, n_actions):  # type: ignore[no-untyped-def]
    """A uniform random action: one draw."""
    return int(rng.random() * n_actions)


def greedy_action(q, s):  # type: ignore[no-untyped-def]
    """argmax_a Q[s, a], the lowest index among ties (no randomness: for evaluation)."""
    best = 0
    for a in range(1, q.shape[1]):
        if q[s, a] > q[s, best]:
            best = a
    return best


def epsilon_greedy_action(q, s, epsilon, rng):  # type: ignore[no-untyped-def]
    """With probability epsilon a random action, else a greedy one with ties broken at random.

    Draws: one uniform for the exploration test; then one for the random action, or one to
    pick among tied maxima when there are several.
    """
    n = q.shape[1]
    if rng.random() < epsilon:
        return random_action(rng, n)
    best = q[s, 0]
    count = 1
    for a in range(1, n):
        v = q[s, a]
        if v > best:
            best = v
            count = 1
        elif v == best:
            count += 1
    if count == 1:
        return greedy_action(q, s)
    k = int(rng.random() * count)
    for a in range(n):
        if q[s, a] == best:
            if k == 0:
                return a
            k -= 1
    return n - 1  # not reached


def td_update(q, s, a, reward, s_next, a_next, terminated, sarsa, learning_rate, discount):  # type: ignore[no-untyped-def]
    """One temporal-difference update of Q[s, a] (paper eq. 21 and its on-policy twin).

    Q-learning bootstraps on max_a' Q[s', a'], SARSA on Q[s', a_next]; a terminal step
    (not a truncation) bootstraps on nothing.
    """
    if terminated:
        target = reward
    elif sarsa:
        target = reward + discount * q[s_next, a_next]
    else:
        best = q[s_next, 0]
        for b in range(1, q.shape[1]):
            if q[s_next, b] > best:
                best = q[s_next, b]
        target = reward + discount * best
    q[s, a] += learning_rate * (target - q[s, a])
