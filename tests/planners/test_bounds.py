"""planners.bounds: the upper bound on shared tables, and the exact optimum's size bound."""

from __future__ import annotations

import numpy as np
import pytest

from planners import bounds
from planners.bounds import exact_optimum, exact_state_bound, upper_bound
from swiptopt import kernel as K
from swiptopt.harvesting import harvest_from_input_w
from swiptopt.scenario import Scenario


@pytest.mark.parametrize(
    ("preset", "overrides"),
    [("paper", {"channel": "none", "n_nodes": 30}), ("tiny", {"harvester": "logistic"}), ("harbour", {})],
)
def test_upper_bound_on_shared_tables_is_the_bound_on_its_own(preset, overrides):
    scenario = Scenario.preset(preset, **overrides)
    tables = K.build_tables(scenario)
    assert upper_bound(scenario, tables) == upper_bound(scenario)


def test_upper_bound_per_step_energy_is_the_kernel_harvester_pair_by_pair():
    """The bound's per-cell joules (vectorised) against the scalar harvester of the kernel."""
    scenario = Scenario.preset("paper", channel="none", n_nodes=12, harvester="logistic", reward_weight=0.0)
    t = K.build_tables(scenario)
    p = t.params
    joules = np.array([
        p[K.P_DT] * harvest_from_input_w((1 - p[K.P_ALPHA]) * pav, True, p[K.P_ETA], p[K.P_LMAX], p[K.P_LA], p[K.P_LB])
        for pav in t.cov_pav
    ])
    per_cell = np.bincount(np.repeat(np.arange(t.n_cells), np.diff(t.cov_ptr)), weights=joules, minlength=t.n_cells)
    room = float((t.capacity - t.energy0)[np.unique(t.cov_node)].sum())
    expected = min(room, scenario.episode_steps * float(per_cell.max()))
    assert upper_bound(scenario, t).energy_delivered_j == pytest.approx(expected, rel=1e-15)


@pytest.mark.parametrize(
    "overrides",
    [
        {"episode_steps": 6},
        {"n_nodes": 6, "episode_steps": 7},
        {"episode_steps": 5, "idle_drain_w": 1e-3},  # order matters: only 7^t holds
        {"episode_steps": 5, "energy_gate_j": 0.3},
        {"episode_steps": 7, "reward_weight": 1.0, "layout_seed": 3},
    ],
)
def test_the_state_bound_holds_for_the_search(overrides):
    scenario = Scenario.preset("tiny", **overrides)
    bound = exact_state_bound(scenario)
    explored = exact_optimum(scenario, max_states=bound).states_explored
    assert explored <= bound
    assert bound <= 7 * sum(7**t for t in range(scenario.episode_steps))


def test_the_state_bound_sees_the_size_before_any_search():
    """The case that once searched for 55 s before giving up: its bound is far beyond the
    limit, so the benchmark skips it at once (see the runner test)."""
    scenario = Scenario.preset("tiny", episode_steps=30, n_nodes=8)
    assert exact_state_bound(scenario) > 1000 * bounds.EXACT_STATE_LIMIT
    assert exact_state_bound(Scenario.preset("tiny")) <= bounds.EXACT_STATE_LIMIT


def test_uplink_bound_holds_although_sending_frees_storage():
    """On the uplink a node's storage is refilled after it sends, so the energy delivered can
    exceed the free storage at the start; the bound counts that, and every walk stays under it."""
    from planners.policies import GreedyPlanner
    from planners.rate_greedy import RateGreedyPlanner
    from swiptopt import evaluate
    from swiptopt.env import AuvSwiptEnv

    scenario = Scenario.preset("paper", n_nodes=15, link="uplink", storage_capacity_j=0.2, channel="none")
    env = AuvSwiptEnv(scenario)
    bound = upper_bound(scenario, env.tables)
    t = env.tables
    room = float((t.capacity - t.energy0)[np.unique(t.cov_node)].sum())
    beyond_room = False
    for policy in (GreedyPlanner(), RateGreedyPlanner()):
        result = evaluate(policy, env, episodes=1, seed=0)
        for record in result.records:
            assert record["data_bits"] <= bound.data_bits * (1 + 1e-12)
            assert record["energy_delivered_j"] <= bound.energy_delivered_j * (1 + 1e-12)
            assert record["return"] <= bound.return_ + 1e-9
            beyond_room |= record["energy_delivered_j"] > room
    assert beyond_room  # the case the plain storage cap would get wrong
    assert bound.energy_delivered_j > room


def test_exact_optimum_steps_the_uplink_kernel_and_replays():
    from swiptopt.env import AuvSwiptEnv

    scenario = Scenario.preset("tiny", link="uplink", storage_capacity_j=0.05, episode_steps=5)
    best = exact_optimum(scenario)
    env = AuvSwiptEnv(scenario)
    env.reset(seed=0)
    total = 0.0
    for a in best.actions:
        _, r, *_ = env.step(a)
        total += r
    assert total == pytest.approx(best.return_, abs=1e-12)
    assert env.state.acc[K.A_NODE_TX_J] > 0  # the optimum did pay for packets
