"""Fleets (swiptopt.fleet, swiptopt.env_fleet): a fleet of one is the single AUV bit for bit,
PettingZoo's API tests pass, AUVs never share a cell unless allowed, and the fleet's rules
(both transfers to a doubly covered node, an AUV leaving when its battery is spent)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("pettingzoo")
from pettingzoo.test import parallel_api_test, parallel_seed_test  # noqa: E402

from swiptopt import ConfigError, Scenario  # noqa: E402
from swiptopt import fleet as F  # noqa: E402
from swiptopt.env import AuvSwiptEnv  # noqa: E402
from swiptopt.env_fleet import AuvFleetEnv  # noqa: E402
from swiptopt.jit import numba_available  # noqa: E402

BACKENDS = ["python"] + (["compiled"] if numba_available() else [])
#: Fading and link failures on: every draw of the buffers matters.
NOISY = {"channel": "rician", "failure_prob_max": 0.3}


def _same(a, b) -> bool:
    return a == b or (isinstance(a, float) and math.isnan(a) and math.isnan(b))


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("observation", ["vector", "tabular"])
def test_a_fleet_of_one_is_the_single_auv_bit_for_bit(backend, observation):
    single = AuvSwiptEnv(observation=observation, backend=backend, **NOISY)
    fleet = AuvFleetEnv(observation=observation, backend=backend, **NOISY)
    rng = np.random.default_rng(5)
    ends = 0
    for episode in range(3):
        seed = episode if episode < 2 else None  # the third goes on with the draws left
        o1, _ = single.reset(seed=seed)
        o2, _ = fleet.reset(seed=seed)
        assert np.array_equal(o1, o2["auv_0"])
        while True:
            a = int(rng.integers(7))
            o1, r1, te1, tr1, i1 = single.step(a)
            o2, r2, te2, tr2, i2 = fleet.step({"auv_0": a})
            assert np.array_equal(o1, o2["auv_0"])
            assert (r1, te1, tr1) == (r2["auv_0"], te2["auv_0"], tr2["auv_0"])
            assert i1["reward_parts"] == i2["auv_0"]["reward_parts"]
            if te1 or tr1:
                m1, m2 = i1["episode_metrics"], i2["auv_0"]["episode_metrics"]
                assert all(_same(m1[k], m2[k]) for k in m1), [k for k in m1 if not _same(m1[k], m2[k])]
                assert m2["return_each"] == [m1["return"]] and m2["n_auvs"] == 1
                ends += 1
                break
        assert fleet.agents == []
    assert ends == 3


def test_a_fleet_of_one_keeps_the_scenario_as_it_was():
    paper = Scenario.preset("paper")
    assert not {"n_auvs", "share_cells", "auv_start_cells", "auv_batteries_j"} & set(paper.to_dict())
    assert Scenario.preset("paper", n_auvs=1).to_dict() == paper.to_dict()
    assert Scenario.preset("paper", n_auvs=2).to_dict()["n_auvs"] == 2


@pytest.mark.parametrize("observation", ["vector", "tabular"])
def test_pettingzoo_api_tests_pass(observation):
    parallel_api_test(AuvFleetEnv(n_auvs=3, observation=observation, episode_steps=30), num_cycles=60)
    # batteries that run out: AUVs leave the fleet one by one
    parallel_api_test(AuvFleetEnv(n_auvs=2, observation=observation, battery_j=3000.0), num_cycles=60)
    parallel_seed_test(lambda: AuvFleetEnv(n_auvs=2, observation=observation, episode_steps=20))


def test_an_auv_whose_battery_is_spent_leaves_and_the_others_go_on():
    # AUV 1 has a battery for a few steps; AUV 0 for the whole episode
    env = AuvFleetEnv(n_auvs=2, auv_batteries_j=[3.6e6, 1500.0], channel="none")
    env.reset(seed=0)
    left_at = None
    for t in range(1, env.scenario.episode_steps + 1):
        live = list(env.agents)
        _, rewards, terminations, truncations, infos = env.step({a: 6 for a in live})
        if "auv_1" in live and terminations["auv_1"]:
            left_at = t
            assert not terminations["auv_0"] and env.agents == ["auv_0"]
            assert "episode_metrics" in infos["auv_1"]
        if "auv_1" not in live:
            assert set(rewards) == {"auv_0"}
        if not env.agents:
            break
    m = env.episode_metrics()
    assert left_at is not None and m["steps_each"] == [env.fleet_state.t, left_at]
    assert m["auv_energy_j_each"][1] >= 1500.0 > m["auv_energy_j_each"][1] - 1000.0
    assert truncations["auv_0"] and env.fleet_state.t == env.scenario.episode_steps


def _walk(env, seed, steps, rng):
    env.reset(seed=seed)
    cells = [env.fleet_state.cells.copy()]
    for _ in range(steps):
        if not env.agents:
            break
        env.step({a: int(rng.integers(7)) for a in env.agents})
        cells.append(env.fleet_state.cells.copy())
    return np.array(cells)


def test_auvs_never_share_a_cell_unless_the_scenario_allows_it():
    # four AUVs on a 3 x 3 x 2 grid, moving at random: they meet often
    small = dict(length_m=30.0, width_m=30.0, depth_m=20.0, n_nodes=3, episode_steps=400, n_auvs=4)
    env = AuvFleetEnv(**small, auv_start_cells=[[0, 0, 0], [2, 2, 0], [0, 2, 1], [2, 0, 1]])
    cells = _walk(env, 0, 400, np.random.default_rng(0))
    assert len(cells) > 100
    assert all(len(set(row)) == 4 for row in cells.tolist())
    moved = (cells[1:] != cells[:-1]).any(axis=0)
    assert moved.all()
    shared = AuvFleetEnv(**small, share_cells=True, auv_start_cells=[[1, 1, 0]] * 4)
    cells = _walk(shared, 0, 400, np.random.default_rng(0))
    assert any(len(set(row)) < 4 for row in cells[1:].tolist())


def test_a_node_covered_by_two_auvs_gets_both_transfers():
    # tiny: no fading, no failures; two AUVs in one cell hovering over the same nodes
    base = dict(channel="none", failure_prob_max=0.0, failure_prob_min=0.0, idle_drain_w=0.0)
    one = AuvSwiptEnv(preset="tiny", **base)
    one.reset(seed=0)
    start = one.scenario.resolved_start_cell
    _, _, _, _, info1 = one.step(6)
    two = AuvFleetEnv(preset="tiny", **base, n_auvs=2, share_cells=True, auv_start_cells=[start, start])
    two.reset(seed=0)
    _, rewards, _, _, info2 = two.step({"auv_0": 6, "auv_1": 6})
    first = info1["reward_parts"]["harvest"]
    assert first > 0
    # both transfers arrive (uncapped in the first step): each AUV's harvest part is the single AUV's
    assert info2["auv_0"]["reward_parts"]["harvest"] == pytest.approx(first, rel=1e-12)
    assert info2["auv_1"]["reward_parts"]["harvest"] == pytest.approx(first, rel=1e-12)
    assert two.fleet_state.parts[1] == pytest.approx(2 * first, rel=1e-12)


@pytest.mark.skipif(not numba_available(), reason="numba not installed")
def test_the_compiled_fleet_step_is_the_python_one():
    scenario = Scenario.preset("paper", n_auvs=3, **NOISY)
    runs = []
    for backend in ("python", "compiled"):
        env = AuvFleetEnv(scenario, backend=backend)
        rng = np.random.default_rng(1)
        obs, _ = env.reset(seed=3)
        trace = [np.concatenate(list(obs.values()))]
        while env.agents:
            obs, rewards, *_ = env.step({a: int(rng.integers(7)) for a in env.agents})
            trace.append(np.concatenate([*obs.values(), np.array(list(rewards.values()))]))
        runs.append((trace, env.episode_metrics()))
    (a, ma), (b, mb) = runs
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))
    assert dict(ma) == dict(mb)


def test_the_same_seed_gives_the_same_fleet_episode_and_its_totals_add_up():
    def run(seed):
        env = AuvFleetEnv(n_auvs=3, **NOISY)
        rng = np.random.default_rng(7)
        env.reset(seed=seed)
        total = 0.0
        while env.agents:
            _, rewards, *_ = env.step({a: int(rng.integers(7)) for a in env.agents})
            total += sum(rewards.values())
        return dict(env.episode_metrics()), total

    (m1, total), (m2, _) = run(4), run(4)
    assert m1 == m2
    assert run(5)[0] != m1
    # the AUVs' own returns add up to the fleet's, their energies to its energy
    assert sum(m1["return_each"]) == pytest.approx(m1["return"], rel=1e-12)
    assert total == pytest.approx(m1["return"], rel=1e-12)
    assert sum(m1["auv_energy_j_each"]) == pytest.approx(m1["auv_energy_j"], rel=1e-12)
    assert sum(m1["data_bits_each"]) == pytest.approx(m1["data_bits"], rel=1e-12)
    assert 0 < m1["makespan_s"] <= m1["mission_time_s"]


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"n_auvs": 0}, "n_auvs"),
        ({"n_auvs": 17}, "n_auvs"),
        ({"n_auvs": 2, "auv_start_cells": [[0, 0, 0]]}, "auv_start_cells"),
        ({"n_auvs": 2, "auv_start_cells": [[0, 0, 0], [0, 0, 0]]}, "auv_start_cells"),
        ({"n_auvs": 2, "auv_start_cells": [[0, 0, 0], [0, 0, 99]]}, "auv_start_cells"),
        ({"n_auvs": 2, "start_cell": [0, 0, 0]}, "start_cell"),
        ({"n_auvs": 2, "auv_batteries_j": [1.0, -1.0]}, "auv_batteries_j"),
        ({"auv_start_cells": [[0, 0, 0]], "start_cell": [0, 0, 0]}, "auv_start_cells"),
    ],
)
def test_a_bad_fleet_names_its_field(changes, field):
    with pytest.raises(ConfigError) as err:
        Scenario.preset("paper", **changes)
    assert err.value.field == field and "\n" not in str(err.value)


def test_the_single_auv_envs_refuse_a_fleet():
    with pytest.raises(ConfigError, match="n_auvs = 2: this environment runs one AUV"):
        AuvSwiptEnv(n_auvs=2)


def test_default_start_cells_spread_along_the_surface():
    s = Scenario.preset("paper", n_auvs=4)
    assert s.fleet_start_cells == ((1, 5, 0), (3, 5, 0), (6, 5, 0), (8, 5, 0))
    assert Scenario.preset("paper").fleet_start_cells == (Scenario.preset("paper").resolved_start_cell,)
    assert F.fleet_tables(s).start_cells.tolist() == [s.cell_index(c) for c in s.fleet_start_cells]


def test_a_layout_chosen_at_reset_is_the_fleet_of_that_layout():
    many = AuvFleetEnv(n_auvs=2, layout_seeds=range(5), **NOISY)
    rng = np.random.default_rng(2)
    for layout in (3, 1, 3):
        got, infos = many.reset(seed=layout, options={"layout_seed": layout})
        alone = AuvFleetEnv(n_auvs=2, layout_seed=layout, **NOISY)
        want, _ = alone.reset(seed=layout)
        assert infos["auv_0"]["layout_seed"] == layout
        assert all(np.array_equal(got[a], want[a]) for a in want)
        actions = {a: int(rng.integers(7)) for a in want}
        got, *_ = many.step(actions)
        want, *_ = alone.step(actions)
        assert all(np.array_equal(got[a], want[a]) for a in want)
