"""planners.adaptive: the exact optimal adaptive policy, against hand-computed cases, the
deterministic exact optimum, the simulator and every bound (docs/optimum.md)."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from planners.adaptive import (
    TINY_FADING,
    AdaptivePolicy,
    adaptive_optimum,
    gain_survival,
    open_loop_value,
)
from planners.bounds import ADAPTIVE, OPEN_LOOP, exact_optimum
from planners.hindsight import Draws, hindsight_walk, replay
from planners.optimal import MilpBudget, policy_bounds, solve_optimum
from planners.service import _gain_distribution
from swiptopt import Scenario, evaluate
from swiptopt import kernel as K
from swiptopt.env import AuvSwiptEnv
from swiptopt.errors import ConfigError

EXACT = MilpBudget(max_nodes=10_000, rel_gap=0.0)


def two_cells(*, covers_a: bool, fail: float, steps: int, stay_cost: float, move_cost: float):
    """Cells A (the start) and B, one node, Gamma = 1 and a data reference of the node's
    data, so that the node's data is worth 1; every stay costs ``stay_cost`` and every move
    (or blocked move) ``move_cost``. The node's link fails with probability ``fail``; when it
    works, a step ending in B carries all of its data and one ending in A (if ``covers_a``)
    half of it (alpha SNR = 3 there, 31 in B: log2 4 = 2 and log2 32 = 5 times dt B)."""
    scenario = Scenario(length_m=20.0, width_m=10.0, depth_m=10.0, cell_size_m=10.0, n_nodes=1,
                        node_positions_m=((10.0, 5.0, 5.0),), start_cell=(0, 0, 0), channel="none",
                        failure_prob_min=fail, failure_prob_max=fail, episode_steps=steps, reward_weight=1.0,
                        snr_threshold_db=0.0, initial_soc_min=1.0, initial_soc_max=1.0)
    t = K.build_tables(scenario)
    data = 4.0 * t.params[K.P_DT] * t.params[K.P_BW]
    params = t.params.copy()
    params[[K.P_GAMMA, K.P_DATA_REF, K.P_LAMBDA, K.P_MOVE_REF, K.P_HOTEL_J, K.P_DRAW_UNIFORMS]] = [
        1.0, data, 1.0, 1.0, 0.0, 1.0]
    propulsion = np.full((2, K.N_ACTIONS), move_cost)
    propulsion[:, K.HOVER] = stay_cost
    snr = [6.0, 62.0] if covers_a else [62.0]
    tables = dataclasses.replace(
        t, cov_ptr=np.array([0, 1, 2] if covers_a else [0, 0, 1]), cov_node=np.zeros(len(snr), dtype=np.int64),
        cov_snr=np.array(snr), cov_pav=np.full(len(snr), 1e-3), data0=np.array([data]),
        energy0=t.capacity.copy(), fail_prob=np.array([fail]), params=params, propulsion_j=propulsion,
        draws_uniforms=True,
    )
    return scenario, tables


def best_open_loop(scenario, tables):
    steps = int(tables.params[K.P_STEPS])
    return max(
        open_loop_value(scenario, list(seq), tables=tables)
        for seq in itertools.product(range(K.N_ACTIONS), repeat=steps)
    )


def perfect_information(scenario, tables, fail):
    """The exact perfect-information value: every failure pattern, each solved by the
    time-indexed program and checked against every action sequence replayed by the kernel."""
    steps = int(tables.params[K.P_STEPS])
    total = 0.0
    for works in itertools.product((True, False), repeat=steps):
        draws = Draws(np.array([[0.9 if w else 0.1] for w in works]), np.zeros((steps, 1, 1)))
        walk = hindsight_walk(scenario, draws, budget=None, tables=tables)
        brute = max(replay(tables, list(seq), draws) for seq in itertools.product(range(K.N_ACTIONS), repeat=steps))
        assert walk.optimal and walk.bound == pytest.approx(brute, abs=1e-9)
        assert replay(tables, walk.actions, draws) == pytest.approx(walk.best, abs=1e-12)
        total += np.prod([1 - fail if w else fail for w in works]) * walk.bound
    return total


def test_adapting_to_the_draws_beats_every_open_loop_walk_and_the_milp_bound():
    """A half-serving A and a fully serving B a move away (move 0.4, stay 0.1, failure 0.2,
    two steps). Adaptive: hover in A (0.8 x 0.5 - 0.1); if the link worked, hover again (0.4
    more at 0.8), else move to B (1 at 0.8, for 0.4): 0.3 + 0.8 x 0.3 + 0.2 x 0.4 = 0.62.
    Open loop: (A, A) 0.8 - 0.2 = 0.6, (B, B) 0.8 + 0.2 x 0.8 - 0.4 - 0.2 x 0.1 = 0.54,
    (B, A) 0.8 - 0.4 + 0.2 x (0.4 - 0.4) = 0.4, (A, B) 0.38. The MILP's walks: (A, A) 0.6,
    (A, B) and (B, B) 0.5, so its proven bound 0.6 is below what the adaptive policy earns;
    the LP (the mixture 0.6 (A, A) + 0.3 (A, B) + 0.1 (B, B) of walks) and perfect
    information are above it, at 0.68."""
    scenario, tables = two_cells(covers_a=True, fail=0.2, steps=2, stay_cost=0.1, move_cost=0.4)
    walks = ((K.HOVER, K.HOVER), (0, K.HOVER), (0, 1), (K.HOVER, 0))  # (A, A), (B, B), (B, A), (A, B)
    assert [open_loop_value(scenario, list(w), tables=tables) for w in walks] == pytest.approx([0.6, 0.54, 0.4, 0.38])
    optimum = adaptive_optimum(scenario, tables=tables)
    assert optimum.value == pytest.approx(0.62, abs=1e-12)
    assert optimum.policy[(0, next(k for (t, k) in optimum.policy if t == 0))] == K.HOVER
    assert best_open_loop(scenario, tables) == pytest.approx(0.60, abs=1e-12)
    result = solve_optimum(scenario, budget=EXACT, tables=tables)
    assert result.bound == pytest.approx(0.60, abs=1e-9) and result.bound < optimum.value - 0.01
    assert result.lp_bound == pytest.approx(0.68, abs=1e-9)
    assert perfect_information(scenario, tables, 0.2) == pytest.approx(0.68, abs=1e-12)
    # the bounds the table may use: the LP for every policy, the MILP's for none (the
    # node can be served, so a walk can end early)
    assert [(b.name, b.holds_for) for b in policy_bounds(result)] == [("lp (expected)", ADAPTIVE)]


def test_an_open_loop_walk_that_ends_early_beats_the_milp_bound():
    """Only B covers the node; every step costs 0.3; the link works with probability 0.4 and
    then carries everything; three steps. Going to B and staying earns 0.4 - 0.3 a step
    until the node is served and the episode ends: (1 + 0.6 + 0.36) x 0.1 = 0.196, open loop
    and optimal. The MILP's model pays every step unless the expected service is complete:
    its best walk (three steps in B) is worth 1 - 0.9 = 0.1. The LP (2.5 expected steps in B,
    fractional stopping) is 0.25, and perfect information is the adaptive value itself."""
    scenario, tables = two_cells(covers_a=False, fail=0.6, steps=3, stay_cost=0.3, move_cost=0.3)
    optimum = adaptive_optimum(scenario, tables=tables)
    assert optimum.value == pytest.approx(0.196, abs=1e-12)
    assert open_loop_value(scenario, [0, K.HOVER, K.HOVER], tables=tables) == pytest.approx(0.196, abs=1e-12)
    assert best_open_loop(scenario, tables) == pytest.approx(0.196, abs=1e-12)
    result = solve_optimum(scenario, budget=EXACT, tables=tables)
    assert result.bound == pytest.approx(0.1, abs=1e-9)
    assert result.lp_bound == pytest.approx(0.25, abs=1e-9)
    assert perfect_information(scenario, tables, 0.6) == pytest.approx(0.196, abs=1e-12)
    assert all(b.holds_for == ADAPTIVE for b in policy_bounds(result))


def test_the_milp_bound_holds_for_open_loop_plans_when_no_walk_can_end_early():
    """Layout 0 of tiny leaves a node that no cell covers: no episode ends early, and the
    MILP's bound then bounds the exact value of its own plan (and of any open-loop plan);
    at 99 dB the bound is strictly below the LP's, so the table may use it."""
    scenario = Scenario.preset("tiny", **{**TINY_FADING, "layout_seed": 0, "snr_threshold_db": 99.0})
    result = solve_optimum(scenario, budget=EXACT)
    bounds = {b.name: b for b in policy_bounds(result)}
    assert bounds["milp (expected)"].holds_for == OPEN_LOOP and bounds["lp (expected)"].holds_for == ADAPTIVE
    plan = open_loop_value(scenario, result.actions)
    assert plan <= result.objective + 1e-12 <= result.bound + 1e-9 <= result.lp_bound + 2e-9


@pytest.mark.parametrize("layout", [1, 5])
def test_the_dp_is_the_exact_optimum_on_deterministic_tiny(layout):
    scenario = Scenario.preset("tiny", layout_seed=layout, episode_steps=6)
    assert adaptive_optimum(scenario).value == pytest.approx(exact_optimum(scenario).return_, abs=1e-9)


@pytest.fixture(scope="module")
def fading():
    scenario = Scenario.preset("tiny", **TINY_FADING)
    return scenario, adaptive_optimum(scenario)


def test_the_tiny_fading_value_is_what_its_policy_earns_in_the_simulator(fading):
    scenario, optimum = fading
    assert optimum.regime == "all-or-nothing fading" and not optimum.tracks_charge
    assert optimum.value == pytest.approx(2.4320447, abs=1e-7)  # a reference: the regression pin
    summary = evaluate(AdaptivePolicy(), AuvSwiptEnv(scenario), episodes=3000, seed=7).summary["return"]
    assert abs(summary.mean - optimum.value) <= summary.ci95


def test_open_loop_value_is_what_a_plan_earns_in_the_simulator(fading):
    from planners.optimal import MilpPlanner

    scenario, _ = fading
    planner = MilpPlanner(budget=EXACT)
    summary = evaluate(planner, AuvSwiptEnv(scenario), episodes=3000, seed=3).summary["return"]
    assert abs(summary.mean - open_loop_value(scenario, planner.result_.actions)) <= summary.ci95


def test_gain_survival_is_one_minus_the_step_models_cdf():
    base = Scenario.preset("tiny")
    x = np.array([0.0, 0.05, 0.3, 1.0, 2.5, 7.0])
    for channel, overrides in ((1, {"channel": "shadowing", "shadowing_sigma_db": 4.0}),
                               (2, {"channel": "rician", "rician_k": 0.0}),
                               (2, {"channel": "rician", "rician_k": 6.0})):
        tables = K.build_tables(base.replace(**overrides))
        _, cdf = _gain_distribution(channel, tables.params[K.P_SIGMA_DB], tables.params[K.P_RICIAN_K])
        assert gain_survival(tables, x) == pytest.approx(1.0 - cdf(x), abs=1e-12)
    assert list(gain_survival(K.build_tables(base), np.array([0.5, 1.0, 1.5]))) == [1.0, 1.0, 0.0]


@pytest.mark.parametrize(("overrides", "field"), [
    ({"reward_weight": 0.5}, "reward_weight"),  # fading makes the charge continuous, and it counts
    ({"data_bits": 1e7}, "data_bits"),  # a working link may leave data behind
    ({"energy_gate_j": 0.1}, "energy_gate_j"),
])
def test_instances_outside_both_regimes_are_refused_naming_the_field(overrides, field):
    with pytest.raises(ConfigError) as error:
        adaptive_optimum(Scenario.preset("tiny", **{**TINY_FADING, **overrides}))
    assert error.value.field == field


def test_the_step_limit_is_an_error_naming_it():
    with pytest.raises(ConfigError) as error:
        adaptive_optimum(Scenario.preset("tiny", **TINY_FADING), max_kernel_steps=100)
    assert error.value.field == "max_kernel_steps"
