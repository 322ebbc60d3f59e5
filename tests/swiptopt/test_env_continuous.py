"""The continuous world: its step, its environment, and its agreement with the grid."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import swiptopt
from swiptopt import continuous as C
from swiptopt import kernel as K
from swiptopt.env import AuvSwiptEnv
from swiptopt.env_continuous import AuvSwiptContinuousEnv
from swiptopt.errors import ConfigError
from swiptopt.scenario import Box, Scenario, Sphere


def _grid_walk(scenario: Scenario, seed: int) -> tuple[list[float], list[float], dict, dict]:
    """Run a random walk of free grid moves (and hovers) on both envs, step for step."""
    grid, cont = AuvSwiptEnv(scenario), AuvSwiptContinuousEnv(scenario)
    grid.reset(seed=seed)
    cont.reset(seed=seed)
    rng = np.random.default_rng(seed)
    rewards_g, rewards_c = [], []
    while True:
        free = [a for a in range(K.N_ACTIONS) if a == K.HOVER or grid.tables.moved[grid.state.cell, a]]
        a = int(rng.choice(free))
        _, rg, tg, ug, info_g = grid.step(a)
        _, rc, tc, uc, info_c = cont.step(K.ACTION_DELTAS[a].astype(np.float32))
        rewards_g.append(rg)
        rewards_c.append(rc)
        np.testing.assert_array_equal(cont.position, scenario.cell_centers_m[grid.state.cell])
        assert (tg, ug) == (tc, uc)
        if tg or ug:
            return rewards_g, rewards_c, dict(info_g["episode_metrics"]), dict(info_c["episode_metrics"])


@pytest.mark.parametrize("channel", ["none", "shadowing", "rician"])
def test_grid_moves_score_exactly_what_the_grid_scores(channel: str) -> None:
    # no obstacles, no current, the grid's cell centres: every reward and metric, bit for bit
    scenario = Scenario.preset("paper", channel=channel, n_nodes=40, layout_seed=2)
    rewards_g, rewards_c, metrics_g, metrics_c = _grid_walk(scenario, seed=5)
    assert rewards_g == rewards_c
    assert metrics_g["data_bits"] > 0 and metrics_g["energy_delivered_j"] > 0  # the walk served nodes
    assert metrics_g.keys() == metrics_c.keys()
    for key, value in metrics_g.items():
        assert value == metrics_c[key] or (value != value and metrics_c[key] != metrics_c[key]), key


def test_coverage_from_cell_centres_is_the_grid_tables() -> None:
    scenario = Scenario.preset("harbour", layout_seed=1, n_nodes=30)
    tables, world = K.build_tables(scenario), C.build_world(scenario)
    checked = 0
    for cell in np.flatnonzero(~scenario.blocked_cells):
        nodes, snr, pav = C.coverage_at(world, scenario.cell_centers_m[cell])
        start, stop = tables.cov_ptr[cell], tables.cov_ptr[cell + 1]
        np.testing.assert_array_equal(nodes, tables.cov_node[start:stop])
        np.testing.assert_array_equal(snr, tables.cov_snr[start:stop])
        np.testing.assert_array_equal(pav, tables.cov_pav[start:stop])
        checked += stop - start
    assert checked > 50


def test_propulsion_against_the_current_is_the_grid_table() -> None:
    # the harbour's current varies with depth: every axis move and hover from every free cell
    scenario = Scenario.preset("harbour", station_keeping_power_w=7.0)
    tables, world = K.build_tables(scenario), C.build_world(scenario)
    free = np.flatnonzero(~scenario.blocked_cells)
    for a in range(K.N_ACTIONS):
        velocity = K.ACTION_DELTAS[a] * scenario.speed_mps
        got = [C.propulsion_energy_j(world, scenario.cell_centers_m[c], velocity) for c in free]
        np.testing.assert_array_equal(got, tables.propulsion_j[free, a])
    # a diagonal against the current costs more than the same speed with it
    here = np.array([100.0, 100.0, 5.0])
    against = C.propulsion_energy_j(world, here, -scenario.speed_mps * np.array([0.6, 0.8, 0.0]))
    along = C.propulsion_energy_j(world, here, scenario.speed_mps * np.array([0.6, 0.8, 0.0]))
    assert against > along > 0


def _world_with(*obstacles: object, **fields: object) -> C.World:
    return C.build_world(Scenario(length_m=100.0, width_m=100.0, depth_m=50.0, obstacles=obstacles, **fields))


def test_first_contact_is_exact_for_boundary_boxes_and_spheres() -> None:
    open_water = _world_with()
    p = np.array([50.0, 50.0, 5.0])
    assert C.travel_fraction(open_water, p, p + [0, 0, -10.0]) == pytest.approx(0.5)  # the surface
    assert C.travel_fraction(open_water, p, p + [60.0, 0, 0]) == pytest.approx(50 / 60)  # the wall at x = 100
    assert C.travel_fraction(open_water, p, p + [10.0, 10.0, 10.0]) == 1.0
    box = _world_with(Box(min_m=(60.0, 40.0, 0.0), max_m=(70.0, 60.0, 20.0)))
    assert C.travel_fraction(box, p, p + [20.0, 0, 0]) == pytest.approx(0.5)
    assert C.travel_fraction(box, p, p + [20.0, 0, 20.0]) == pytest.approx(0.5)  # enters its side at x = 60
    below = np.array([50.0, 50.0, 25.0])
    assert C.travel_fraction(box, below, below + [30.0, 0, 0]) == 1.0  # passes under it
    sphere = _world_with(Sphere(center_m=(50.0, 50.0, 30.0), radius_m=5.0))
    assert C.travel_fraction(sphere, p, p + [0, 0, 40.0]) == pytest.approx(20 / 40)
    assert C.travel_fraction(sphere, p, p + [10.0, 0, 0]) == 1.0


def test_seabed_contact() -> None:
    # a seabed rising from 50 m deep at x = 0 to 30 m at x = 100 (20 m height there)
    world = _world_with(seabed_height_m=((0.0, 0.0), (20.0, 20.0)))
    p = np.array([50.0, 50.0, 35.0])  # seabed at 40 m here
    t = C.travel_fraction(world, p, p + [0, 0, 10.0])
    assert t == pytest.approx(0.5, abs=1e-9)
    # moving towards the rising seabed at constant depth: it reaches 35 m deep at x = 75
    t = C.travel_fraction(world, p, p + [40.0, 0, 0])
    assert t == pytest.approx(25 / 40, abs=1e-9)


def _segments_blocked(scenario: Scenario, path: np.ndarray, samples: int = 101) -> int:
    t = np.linspace(0.0, 1.0, samples)[None, :, None]
    points = path[:-1, None, :] + t * (path[1:, None, :] - path[:-1, None, :])
    return int(np.count_nonzero(scenario.is_blocked(points)))


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_paths_never_enter_an_obstacle(backend: str) -> None:
    env = AuvSwiptContinuousEnv(preset="harbour", backend=backend)
    rng = np.random.default_rng(0)
    blocked = 0
    for episode in range(3 if backend == "python" else 12):
        env.reset(seed=episode, options={"layout_seed": episode % 3})
        # a persistent heading for a while, then another: long runs into walls and the seabed
        heading = rng.uniform(-1, 1, 3)
        while True:
            if rng.random() < 0.1:
                heading = rng.uniform(-1, 1, 3)
            _, _, terminated, truncated, info = env.step(heading.astype(np.float32))
            blocked += info["blocked"]
            if terminated or truncated:
                break
        path = env.path
        assert _segments_blocked(env.scenario, path) == 0
        assert np.all((path >= 0) & (path <= env.scenario.extent_m))
    assert blocked > 20  # the test did run into things


def test_python_and_compiled_steps_agree_bit_for_bit() -> None:
    runs = []
    for backend in ("python", "compiled"):
        env = AuvSwiptContinuousEnv(preset="harbour", backend=backend, layout_seed=4)
        obs, _ = env.reset(seed=11)
        rng = np.random.default_rng(3)
        observations, rewards = [obs], []
        while True:
            obs, reward, terminated, truncated, info = env.step(rng.uniform(-1.2, 1.2, 3).astype(np.float32))
            observations.append(obs)
            rewards.append(reward)
            if terminated or truncated:
                break
        runs.append((np.array(observations), rewards, env.path, dict(info["episode_metrics"])))
    (o1, r1, p1, m1), (o2, r2, p2, m2) = runs
    np.testing.assert_array_equal(o1, o2)
    np.testing.assert_array_equal(p1, p2)
    assert r1 == r2
    assert m1.keys() == m2.keys() and all(m1[k] == m2[k] or m1[k] != m1[k] for k in m1)


def test_a_move_reaches_at_most_one_step_and_hover_stays() -> None:
    env = AuvSwiptContinuousEnv(preset="harbour")
    env.reset(seed=0)
    start = env.position
    env.step(np.array([1.0, 1.0, 1.0], dtype=np.float32))  # norm sqrt(3): scaled to one step
    assert np.linalg.norm(env.position - start) == pytest.approx(env.scenario.cell_size_m)
    here = env.position
    _, _, _, _, info = env.step(np.zeros(3, dtype=np.float32))
    np.testing.assert_array_equal(env.position, here)
    assert info["reward_parts"]["movement"] < 0  # hovering still costs hotel and station keeping
    np.testing.assert_allclose(C.velocity_of(np.array([2.0, 0.0, 0.0]), 1.5), [1.5, 0, 0])
    action = C.action_towards(here, here + [3.0, 4.0, 0.0], env.scenario.cell_size_m)
    np.testing.assert_allclose(action, [0.3, 0.4, 0.0], rtol=1e-6)


def test_the_env_passes_both_checkers() -> None:
    from gymnasium.utils.env_checker import check_env

    check_env(AuvSwiptContinuousEnv(preset="harbour", n_nodes=5), skip_render_check=True)
    sb3 = pytest.importorskip("stable_baselines3.common.env_checker")
    sb3.check_env(AuvSwiptContinuousEnv(preset="harbour", n_nodes=5), warn=True)


def test_make_layouts_and_reset_options() -> None:
    env = gym.make(swiptopt.CONTINUOUS_ENV_ID, preset="harbour", layout_seeds=[3, 7])
    assert env.spec.max_episode_steps == Scenario.preset("harbour").episode_steps
    seen = {env.reset(seed=s)[1]["layout_seed"] for s in range(12)}
    assert seen == {3, 7}
    _, info = env.reset(options={"layout_seed": 9})
    assert info["layout_seed"] == 9
    np.testing.assert_array_equal(
        env.unwrapped.world.nodes_m, Scenario.preset("harbour", layout_seed=9).layout.positions_m
    )
    with pytest.raises(ConfigError, match="unknown reset option"):
        env.reset(options={"layout": 1})
    with pytest.raises(ValueError, match=r"\(3,\) real numbers"):
        env.step(np.zeros(2, dtype=np.float32))


def test_same_seed_same_episode_and_render() -> None:
    def run() -> tuple[np.ndarray, float]:
        env = AuvSwiptContinuousEnv(preset="harbour", render_mode="rgb_array")
        env.reset(seed=2)
        rng = np.random.default_rng(2)
        total = 0.0
        for _ in range(15):
            total += env.step(rng.uniform(-1, 1, 3).astype(np.float32))[1]
        image = env.render()
        assert image.ndim == 3 and image.shape[2] == 3
        return env.path, total

    (p1, t1), (p2, t2) = run(), run()
    np.testing.assert_array_equal(p1, p2)
    assert t1 == t2


def test_coverable_nodes() -> None:
    # a node under a box roof cannot be covered; one in open water can
    scenario = Scenario(
        length_m=100.0, width_m=100.0, depth_m=50.0, n_nodes=2,
        node_positions_m=((20.0, 20.0, 40.0), (80.0, 80.0, 40.0)),
        obstacles=(Box(min_m=(0.0, 0.0, 0.0), max_m=(40.0, 40.0, 39.0)),),
    )
    np.testing.assert_array_equal(C.coverable_nodes(scenario), [False, True])


def test_actions_that_are_not_three_real_numbers_are_refused_in_one_short_line() -> None:
    """A complex action was truncated to its real part; a huge one gave a 5 MB message."""
    env = AuvSwiptContinuousEnv(preset="tiny")
    env.reset(seed=0)
    for bad in ([0.5 + 1j, 0.0, 0.0], np.zeros(10**6), "up", [[1, 2], [3]], np.zeros(2)):
        with pytest.raises(ValueError, match=r"actions must be \(3,\) real numbers") as info:
            env.step(bad)
        assert len(str(info.value)) < 200 and "\n" not in str(info.value)
    _, _, _, _, info = env.step(np.array([[1.0, 0.0, 0.0]]))  # any array of three reals is one action
    assert not info["blocked"]
