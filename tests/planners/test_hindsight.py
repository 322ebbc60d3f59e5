"""planners.hindsight: the time-indexed program of one draw table is the best walk the kernel
allows with those draws, and the bound over tables is deterministic for a seed and budget."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from planners.adaptive import TINY_FADING
from planners.hindsight import (
    Draws,
    HindsightBudget,
    hindsight_bound,
    hindsight_walk,
    replay,
    step_amounts,
)
from swiptopt import Scenario
from swiptopt import kernel as K
from swiptopt.errors import ConfigError


@pytest.mark.parametrize("overrides", [
    TINY_FADING,  # Rayleigh, failures, Gamma = 1, every node coverable: walks may stop early
    {"channel": "shadowing", "failure_prob_max": 0.3},  # Gamma = 0.5: data and charge, a node never covered
])
def test_one_table_is_solved_to_the_best_kernel_walk(overrides):
    """Three steps: every one of the 7^3 action sequences replayed through the kernel with the
    table's draws; the program's optimum is the best of them, and its walk replays to it."""
    scenario = Scenario.preset("tiny", **{**overrides, "episode_steps": 3})
    tables = K.build_tables(scenario)
    for seed in range(3):
        draws = Draws.sample(tables, seed)
        walk = hindsight_walk(scenario, draws, tables=tables)
        brute = max(replay(tables, list(seq), draws) for seq in itertools.product(range(K.N_ACTIONS), repeat=3))
        assert walk.optimal and walk.bound == pytest.approx(brute, abs=1e-9)
        assert replay(tables, walk.actions, draws) == pytest.approx(walk.best, abs=1e-9)


def test_the_amounts_are_the_kernels_first_step_uncapped():
    """Each pair's amount with a table's draws is what the kernel delivers in a first step
    from its cell, before the node's cap (checked where the cap does not bind)."""
    scenario = Scenario.preset("tiny", channel="rician", rician_k=2.0, failure_prob_max=0.3, data_bits=1e9,
                               storage_capacity_j=1e3)
    tables = K.build_tables(scenario)
    draws = Draws.sample(tables, 11)
    bits, joules = step_amounts(tables, draws)
    covering = np.flatnonzero(np.diff(tables.cov_ptr))
    for cell in covering:
        state = K.new_state(tables)
        state.where[K.W_CELL] = cell
        nodes = tables.covered(cell)
        state.where[K.W_UPTR] = state.where[K.W_ZPTR] = 0
        K.step(K.HOVER, draws.uniforms[0, nodes].copy(), draws.normals[0, nodes, :2].ravel().copy(),
               K.step_args(tables, state))
        pairs = np.arange(tables.cov_ptr[cell], tables.cov_ptr[cell + 1])
        assert np.array_equal(state.collected[nodes], bits[0, pairs])
        assert np.array_equal(state.delivered[nodes], joules[0, pairs])


def test_the_bound_is_deterministic_for_a_seed_and_budget_and_sample_k_is_fixed():
    scenario = Scenario.preset("tiny", **TINY_FADING)
    budget = HindsightBudget(samples=6, seed=4)
    first, again = hindsight_bound(scenario, budget=budget), hindsight_bound(scenario, budget=budget)
    assert first.status == "ok" and first.proven == 6
    assert [s.bound for s in first.samples] == [s.bound for s in again.samples]
    assert (first.mean, first.ci95) == (again.mean, again.ci95)
    # sample k does not depend on how many are drawn; another seed draws other tables
    more = hindsight_bound(scenario, budget=HindsightBudget(samples=8, seed=4))
    assert [s.bound for s in more.samples[:6]] == [s.bound for s in first.samples]
    other = hindsight_bound(scenario, budget=HindsightBudget(samples=6, seed=5))
    assert [s.bound for s in other.samples] != [s.bound for s in first.samples]
    assert first.upper_limit == pytest.approx(first.mean + first.ci95) and first.policy_bound().holds_for == "adaptive"


def test_the_linear_relaxation_per_table_is_a_weaker_bound():
    scenario = Scenario.preset("tiny", **TINY_FADING)
    exact = hindsight_bound(scenario, budget=HindsightBudget(samples=4))
    relaxed = hindsight_bound(scenario, budget=HindsightBudget(samples=4, max_nodes=0))
    assert all(r.bound >= e.bound - 1e-9 for r, e in zip(relaxed.samples, exact.samples))
    assert relaxed.best_mean is None and relaxed.proven == 0


def test_unsupported_scenarios_are_a_status_and_bad_budgets_an_error():
    result = hindsight_bound(Scenario.preset("tiny", link="uplink"), budget=HindsightBudget(samples=2))
    assert result.status == "unsupported" and "uplink" in result.message and result.mean is None
    for bad, field in (
        ({"samples": 1}, "samples"), ({"max_nodes": -1}, "max_nodes"), ({"time_limit_s": 0}, "time_limit_s")
    ):
        with pytest.raises(ConfigError) as error:
            HindsightBudget(**bad)
        assert error.value.field == field
