import copy
import dataclasses
import math
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import swiptopt
from swiptopt import acoustics, harvesting
from swiptopt import kernel as K
from swiptopt.env import AuvSwiptEnv
from swiptopt.link import auv_power, reward_references
from swiptopt.metrics import EPISODE_METRICS
from swiptopt.scenario import Box, Scenario

CASES = [
    ("paper", {}),
    ("harbour", {}),  # obstacles, seabed and a current
    ("tiny", {}),
    ("paper", {"channel": "rician", "harvester": "logistic", "n_nodes": 8}),
    ("harbour", {"idle_drain_w": 0.001, "energy_gate_j": 0.3, "n_nodes": 6}),
]
#: The node-to-AUV data link: packets paid from the nodes' storage.
UPLINK_CASES = [
    ("paper", {"link": "uplink"}),
    ("harbour", {"link": "uplink", "channel": "rician", "energy_gate_j": 0.2, "n_nodes": 6, "storage_capacity_j": 0.3}),
]
CASES += UPLINK_CASES


@pytest.mark.parametrize("observation", ["tabular", "vector"])
@pytest.mark.parametrize("preset, overrides", CASES)
def test_check_env_passes(preset, overrides, observation):
    env = gym.make(swiptopt.ENV_ID, preset=preset, observation=observation, render_mode="ansi", **overrides)
    check_env(env.unwrapped, skip_render_check=False)


def test_registered_and_made_with_overrides():
    env = gym.make(swiptopt.ENV_ID, preset="paper", n_nodes=7, layout_seed=4, observation="vector")
    assert env.unwrapped.scenario.n_nodes == 7
    assert env.observation_space.shape == (4 + 6 * 7,)
    scenario = Scenario.preset("tiny")
    assert gym.make(swiptopt.ENV_ID, scenario=scenario).unwrapped.scenario is scenario


def rollout(env, seed, actions):
    obs, _ = env.reset(seed=seed)
    trace = [obs]
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        trace.append((np.asarray(obs).tobytes(), r, term, trunc, info["reward_parts"], info.get("episode_metrics")))
        if term or trunc:
            obs, _ = env.reset()
            trace.append(obs)
    return trace


@pytest.mark.parametrize("preset, overrides", CASES)
def test_same_seed_and_actions_give_the_same_episodes(preset, overrides):
    actions = np.random.default_rng(11).integers(0, 7, 400)
    a = rollout(gym.make(swiptopt.ENV_ID, preset=preset, **overrides), 5, actions)
    b = rollout(gym.make(swiptopt.ENV_ID, preset=preset, **overrides), 5, actions)
    python = rollout(AuvSwiptEnv(preset=preset, backend="python", **overrides), 5, actions)
    assert repr(a) == repr(b)  # bit for bit: reprs of floats are exact
    assert repr(a) == repr(python)  # the compiled and the Python kernel agree exactly


def test_different_seeds_give_different_episodes():
    actions = np.random.default_rng(11).integers(0, 7, 300)
    a = rollout(gym.make(swiptopt.ENV_ID, preset="paper"), 5, actions)
    c = rollout(gym.make(swiptopt.ENV_ID, preset="paper"), 6, actions)
    assert repr(a) != repr(c)


@pytest.mark.parametrize("preset, overrides", CASES)
def test_invariants_over_random_rollouts(preset, overrides):
    env = AuvSwiptEnv(preset=preset, **overrides)
    t = env.tables
    drains = env.scenario.idle_drain_w > 0
    rng = np.random.default_rng(3)
    for episode in range(6):
        env.reset(seed=episode)
        s = env.state
        free0 = t.capacity - t.energy0
        auv_prev = 0.0
        while True:
            cell = s.cell
            a = int(rng.integers(0, 7))
            _, r, term, trunc, info = env.step(a)
            parts = info["reward_parts"]
            assert r == pytest.approx(sum(parts.values()), abs=1e-12)
            assert np.all(s.data_left >= 0) and np.all(s.collected <= t.data0)
            np.testing.assert_allclose(s.collected + s.data_left, t.data0, rtol=1e-12)
            assert np.all(s.energy >= 0) and np.all(s.energy <= t.capacity * (1 + 1e-12))
            spent = s.acc[K.A_NODE_TX_J]
            if not drains:
                # energy is conserved: what the nodes hold is what they had, plus what they
                # harvested, minus what their uplink packets cost (0 on the downlink)
                assert s.energy.sum() == pytest.approx(t.energy0.sum() + s.delivered.sum() - spent, abs=1e-9)
                if spent == 0:
                    assert np.all(s.delivered <= free0 * (1 + 1e-12) + 1e-15)
            auv = s.acc[K.A_PROPULSION_J] + s.acc[K.A_HOTEL_J] + s.acc[K.A_PROJECTOR_J]
            assert auv > auv_prev
            auv_prev = auv
            # a blocked move leaves the AUV in place; an allowed one moves it by one cell
            moved = env.scenario.cell_of_index(s.cell) - env.scenario.cell_of_index(cell)
            if a != K.HOVER and t.next_cell[cell, a] != cell:
                np.testing.assert_array_equal(moved, K.ACTION_DELTAS[a])
            else:
                assert s.cell == cell
            assert not env.scenario.blocked_cells[s.cell]
            if term or trunc:
                m = info["episode_metrics"]
                assert set(EPISODE_METRICS) <= set(m)
                assert m["data_bits"] == pytest.approx(s.collected.sum())
                assert m["auv_energy_j"] == pytest.approx(
                    m["auv_propulsion_j"] + m["auv_hotel_j"] + m["auv_projector_j"]
                )
                break


def test_blocked_moves_cost_the_move_and_stay():
    scenario = Scenario.preset("tiny", obstacles=(Box(min_m=(20, 10, 0), max_m=(30, 20, 20)),))
    env = AuvSwiptEnv(scenario)
    env.reset(seed=0)
    start = env.state.cell
    move_j = auv_power(scenario).move_energy_j
    env.step(5)  # -z from the surface: out of the volume
    assert env.state.cell == start
    assert env.state.acc[K.A_PROPULSION_J] + env.state.acc[K.A_HOTEL_J] == pytest.approx(move_j)
    env.step(0)  # +x into the box
    assert env.state.cell == start
    env.step(2)  # +y is free
    assert env.state.cell != start


def _one_node_below(**overrides):
    # the AUV at the centre of cell (1, 1, 0) = (15, 15, 5) m; the node 10 m straight below
    return Scenario.preset(
        "tiny",
        n_nodes=1,
        node_positions_m=[(15.0, 15.0, 15.0)],
        start_cell=(1, 1, 0),
        **overrides,
    )


def test_worked_case_one_node_straight_below():
    scenario = _one_node_below(split_ratio=0.4, reward_weight=0.6)
    env = AuvSwiptEnv(scenario)
    env.reset(seed=0)
    e0 = env.state.energy[0]
    _, reward, _, _, info = env.step(K.HOVER)
    # the model functions for this geometry, by hand
    dt = 10.0 / 1.5
    sl = acoustics.source_level_db(1000.0, 0.5)
    tl = acoustics.transmission_loss_db(10.0, 24.0, 1.5)
    nl = acoustics.noise_level_db(24.0, 4000.0, 0.0, 10.0)
    snr_lin = acoustics.db_to_linear(acoustics.snr_db(sl, tl, nl))
    bits = min(1e5, dt * 4000.0 * math.log2(1 + 0.4 * snr_lin))
    p_av = harvesting.available_power_w(sl - tl, -170.0, 100.0)
    joules = min(1.0 - e0, dt * float(harvesting.harvested_power_w(p_av, 0.4, 0.5)))
    assert env.state.collected[0] == pytest.approx(bits, rel=1e-12)
    assert env.state.delivered[0] == pytest.approx(joules, rel=1e-12)
    refs = reward_references(scenario)
    hover_j = 15.0 * dt
    assert info["reward_parts"]["throughput"] == pytest.approx(0.6 * bits / refs.data_ref_bits)
    assert info["reward_parts"]["harvest"] == pytest.approx(0.4 * joules / refs.energy_ref_j)
    assert info["reward_parts"]["movement"] == pytest.approx(-0.02 * hover_j / refs.move_energy_ref_j)
    assert env.state.acc[K.A_PROJECTOR_J] == pytest.approx(1000.0 * dt)
    assert reward == pytest.approx(sum(info["reward_parts"].values()))


def test_worked_case_uplink_packets_paid_from_storage():
    # a node 10 m below, storage 1 J, half full: the AUV's signal first charges it (all of
    # it: no split on the uplink), then it sends whole 800-bit packets at its own SNR
    scenario = _one_node_below(link="uplink", initial_soc_min=0.5, initial_soc_max=0.5, split_ratio=0.7)
    env = AuvSwiptEnv(scenario)
    env.reset(seed=0)
    env.step(K.HOVER)
    dt = 10.0 / 1.5
    tl = acoustics.transmission_loss_db(10.0, 24.0, 1.5)
    nl = acoustics.noise_level_db(24.0, 4000.0, 0.0, 10.0)
    sl_auv = acoustics.source_level_db(1000.0, 0.5)
    sl_node = acoustics.source_level_db(1.6635, 0.5)
    assert sl_node == pytest.approx(170.0, abs=1e-3)  # Table I's 170 dB re 1 uPa @ 1 m
    p_av = harvesting.available_power_w(sl_auv - tl, -170.0, 100.0)
    joules = min(0.5, dt * float(harvesting.harvested_power_w(p_av, 0.0, 0.5)))  # alpha ignored
    rate = 4000.0 * math.log2(1 + acoustics.db_to_linear(acoustics.snr_db(sl_node, tl, nl)))
    airtime = 800.0 / rate
    cost = (1.6635 + 0.1) * airtime
    packets = min(math.floor(dt / airtime), math.floor((0.5 + joules) / cost), 125)
    assert 0 < packets < 125  # the storage, not the time on air, limits this step
    assert env.state.delivered[0] == pytest.approx(joules, rel=1e-12)
    assert env.state.collected[0] == packets * 800.0
    assert env.state.acc[K.A_NODE_TX_J] == pytest.approx(packets * cost, rel=1e-12)
    assert env.state.energy[0] == pytest.approx(0.5 + joules - packets * cost, rel=1e-9)
    assert env.state.energy[0] < cost  # it sent all it could pay for
    # an empty node under the gate sends nothing, whatever its SNR
    gated = AuvSwiptEnv(scenario.replace(energy_gate_j=0.9))
    gated.reset(seed=0)
    gated.step(K.HOVER)
    assert gated.state.collected[0] == 0.0 and gated.state.acc[K.A_NODE_TX_J] == 0.0
    # the downlink with the same split moves all the data in one step
    down = AuvSwiptEnv(scenario.replace(link="downlink_split"))
    down.reset(seed=0)
    down.step(K.HOVER)
    assert down.state.collected[0] == 1e5 and down.state.acc[K.A_NODE_TX_J] == 0.0


def test_energy_efficiency_readings_side_by_side():
    env = AuvSwiptEnv(Scenario.preset("paper", n_nodes=30, channel="none"))
    env.reset(seed=0)
    covered_steps, covered_nodes = 0, 0
    for a in [4, 4, 6, 0, 0, 2, 2, 6, 1, 1, 1, 3, 3, 5, 5, 6]:
        _, _, term, trunc, info = env.step(a)
        n = len(env.tables.covered(env.state.cell))
        covered_steps += n > 0
        covered_nodes += n
    m = env.episode_metrics()
    p = auv_power(env.scenario)
    motion = m["auv_propulsion_j"] + m["auv_hotel_j"]
    assert 0 < covered_steps < 16 and covered_nodes > covered_steps  # the readings differ here
    projector_j = p.projector_energy_j
    assert m["energy_efficiency_bit_per_j"] == pytest.approx(m["data_bits"] / (motion + projector_j * covered_steps))
    assert m["energy_efficiency_always_on_bit_per_j"] == pytest.approx(m["data_bits"] / (motion + projector_j * 16))
    assert m["energy_efficiency_per_node_bit_per_j"] == pytest.approx(
        m["data_bits"] / (motion + projector_j * covered_nodes)
    )
    assert m["mobility_efficiency_bit_per_j"] == pytest.approx(m["data_bits"] / motion)


def test_hovering_over_served_nodes_earns_exactly_the_movement_penalty():
    scenario = _one_node_below(initial_soc_min=1.0, initial_soc_max=1.0, episode_steps=20, data_bits=1e4)
    env = AuvSwiptEnv(scenario)
    env.reset(seed=0)
    _, r1, term, _, _ = env.step(K.HOVER)
    assert r1 > 0 and term  # one step collects the data; storage was full: all served
    # keep a second, far node unserved so the episode goes on, and hover over the first
    scenario = _one_node_below(initial_soc_min=1.0, initial_soc_max=1.0, data_bits=1e4).replace(
        n_nodes=2, node_positions_m=((15.0, 15.0, 15.0), (29.0, 29.0, 6.0))
    )
    env = AuvSwiptEnv(scenario)
    env.reset(seed=0)
    env.step(K.HOVER)
    expected = -0.02 * 15.0 * (10 / 1.5) / reward_references(scenario).move_energy_ref_j
    for _ in range(5):
        _, r, term, _, info = env.step(K.HOVER)
        assert not term
        assert r == expected
        assert info["reward_parts"]["throughput"] == 0.0 and info["reward_parts"]["harvest"] == 0.0


def test_rician_fading_preserves_the_mean_harvest():
    # a linear harvester and large storage: the mean energy per step over many fades equals
    # the mean-channel value, because E|h|^2 = 1 for the normalised Rician channel
    scenario = _one_node_below(
        channel="rician", rician_k=2.0, storage_capacity_j=1e6, episode_steps=4000, data_bits=1e12, battery_j=1e9
    )
    env = AuvSwiptEnv(scenario)
    env.reset(seed=1)
    for _ in range(4000):
        env.step(K.HOVER)
    mean = env.state.delivered[0] / 4000
    deterministic = AuvSwiptEnv(scenario.replace(channel="none"))
    deterministic.reset(seed=1)
    deterministic.step(K.HOVER)
    per_step = deterministic.state.delivered[0]
    # std of |h|^2 for K = 2 is sqrt(1 + 2K)/(K + 1) = 0.745; 4000 samples: 1.2 % standard error
    assert mean == pytest.approx(per_step, rel=0.05)
    assert mean != per_step


def test_episode_end_metrics_and_target_steps():
    # free storage 0.8 J, half of it 0.4 J; about 78 mJ per step at 10 m: six steps needed
    env = AuvSwiptEnv(_one_node_below(episode_steps=3, initial_soc_min=0.2, initial_soc_max=0.2))
    env.reset(seed=0)
    for _ in range(3):
        _, _, term, trunc, info = env.step(K.HOVER)
    assert trunc and not term
    m = info["episode_metrics"]
    assert m["steps_to_data_target"] == 1  # all data in the first step
    assert m["steps_to_energy_target"] is None  # half the free storage takes more steps
    assert m["length"] == 3 and m["mission_time_s"] == pytest.approx(20.0)
    assert m["energy_efficiency_bit_per_j"] == pytest.approx(m["data_bits"] / m["auv_energy_j"])
    assert m["nodes_served"] == 0
    with pytest.raises(RuntimeError, match="reset"):
        env.step(K.HOVER)


def test_renders():
    env = AuvSwiptEnv(preset="harbour", render_mode="rgb_array")
    env.reset(seed=0)
    for a in (0, 2, 4, 6):
        env.step(a)
    image = env.render()
    assert image.ndim == 3 and image.shape[2] == 3 and image.dtype == np.uint8
    assert image.std() > 0
    text = AuvSwiptEnv(preset="tiny", render_mode="ansi")
    text.reset(seed=0)
    text.step(6)
    assert "t=1/8" in text.render()


def test_bad_arguments():
    with pytest.raises(ValueError, match="observation"):
        AuvSwiptEnv(observation="pixels")
    with pytest.raises(swiptopt.ScenarioError, match="n_nodes"):
        AuvSwiptEnv(n_nodes=-1)
    env = AuvSwiptEnv(preset="tiny")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(7)


def reference_vector_observation(env):
    """The vector observation (docs/design.md, 'A step, the reward and the end of an episode
    (Section III)') written out directly from the scenario (the test's own)."""
    s, t, sc = env.state, env.tables, env.scenario
    extent = sc.extent_m
    here = sc.cell_centers_m[s.cell] / extent
    covered = np.zeros(t.n_nodes)
    covered[t.covered(s.cell)] = 1.0
    per_node = np.column_stack(
        [sc.layout.positions_m / extent - here, s.data_left / t.data0, s.energy / t.capacity, covered]
    )
    return np.concatenate([here, [1.0 - s.t / sc.episode_steps], per_node.ravel()]).astype(np.float32)


@pytest.mark.parametrize("preset, overrides", CASES[:3] + UPLINK_CASES)
def test_vector_observation_is_the_same_compiled_python_and_written_out(preset, overrides):
    actions = np.random.default_rng(7).integers(0, 7, 120)
    envs = [AuvSwiptEnv(preset=preset, observation="vector", backend=b, **overrides) for b in ("compiled", "python")]
    observations = [[e.reset(seed=3)[0]] for e in envs]
    for a in actions:
        for env, seen in zip(envs, observations):
            obs, _, term, trunc, _ = env.step(a)
            np.testing.assert_array_equal(obs, reference_vector_observation(env))
            seen.append(obs)
            if term or trunc:
                seen.append(env.reset()[0])
    for first, second in zip(*observations):
        assert first.dtype == np.float32 and first.tobytes() == second.tobytes()
    # every step hands out its own array: keeping one does not see the next
    assert not any(np.shares_memory(a, b) for a, b in zip(observations[0], observations[0][1:]))


def test_served_mask_is_is_served_for_every_node():
    rng = np.random.default_rng(0)
    n = 4000
    capacity = rng.uniform(0.5, 2.0, n)
    data_left = np.where(rng.random(n) < 0.5, 0.0, rng.uniform(-1.0, 1e5, n))
    data_left[:4] = [-0.0, np.nan, 1e-300, -1e-300]
    energy = capacity * rng.choice([0.0, 1.0 - 1e-12, 1.0 - 2e-12, 1.0, 1.5, np.nan], n)
    for gamma in (0.0, 0.5, 1.0):
        expected = [bool(K.is_served(data_left, energy, capacity, gamma, i)) for i in range(n)]
        assert K.served_mask(data_left, energy, capacity, gamma).tolist() == expected


# ----------------------------------------------------------------- v1: wrappers, spec, layouts


@pytest.mark.parametrize("observation", ["tabular", "vector"])
@pytest.mark.parametrize("layout_seeds", [None, range(0, 40)])
def test_both_env_checkers_pass(observation, layout_seeds):
    sb3_check_env = pytest.importorskip("stable_baselines3.common.env_checker").check_env
    env = gym.make(swiptopt.ENV_ID, preset="paper", n_nodes=8, observation=observation, layout_seeds=layout_seeds)
    check_env(env.unwrapped)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # SB3's checker only warns: any warning fails the test
        sb3_check_env(env.unwrapped, warn=True)


def test_spec_tells_the_episode_length():
    assert gym.make(swiptopt.ENV_ID, preset="tiny").spec.max_episode_steps == 8
    assert gym.make(swiptopt.ENV_ID, preset="paper", episode_steps=70).spec.max_episode_steps == 70
    limited = gym.make(swiptopt.ENV_ID, preset="paper", max_episode_steps=20)
    assert limited.spec.max_episode_steps == 20
    limited.reset(seed=0)
    for t in range(1, 21):
        _, _, term, trunc, info = limited.step(K.HOVER)
        assert trunc == (t == 20) and not term
    # the TimeLimit ended it, not the env: the metrics are the unwrapped env's
    assert "episode_metrics" not in info
    assert limited.unwrapped.episode_metrics()["length"] == 20
    # no TimeLimit of our own: the env truncates itself
    wrappers = []
    env = gym.make(swiptopt.ENV_ID, preset="tiny")
    while env is not env.unwrapped:
        wrappers.append(type(env).__name__)
        env = env.env
    assert "TimeLimit" not in wrappers


def test_metrics_key_survives_the_standard_wrappers():
    from gymnasium.wrappers import FlattenObservation, RecordEpisodeStatistics

    env = RecordEpisodeStatistics(FlattenObservation(gym.make(swiptopt.ENV_ID, preset="tiny")))
    env.reset(seed=0)
    while True:
        _, _, term, trunc, info = env.step(K.HOVER)
        if term or trunc:
            break
    assert info["episode"]["l"] == info["episode_metrics"]["length"] == 8
    assert info["episode"]["r"] == pytest.approx(info["episode_metrics"]["return"])
    m = info["episode_metrics"]
    assert dict(m) == m and set(EPISODE_METRICS) <= set(m)
    assert pickle.loads(pickle.dumps(m)) == m and copy.deepcopy(m) == m
    with pytest.raises(TypeError):
        m["return"] = 0.0  # read-only


def test_gymnasium_vector_env_keeps_metrics_whole():
    # two sub-envs end at once with different kinds of values (a step count and None):
    # stacking them per metric would fail; the mapping stays one object per sub-env
    envs = gym.vector.SyncVectorEnv(
        [lambda: AuvSwiptEnv(preset="tiny"), lambda: AuvSwiptEnv(preset="tiny", data_bits=1e12)]
    )
    envs.reset(seed=0)
    for _ in range(8):
        _, _, term, trunc, infos = envs.step(np.full(2, K.HOVER))
    assert np.all(term | trunc) and infos["_episode_metrics"].all()
    values = [infos["episode_metrics"][k]["steps_to_data_target"] for k in range(2)]
    assert values == [1, None]


def _trace(env, seed, options, actions):
    obs, info = env.reset(seed=seed, options=options)
    trace = [np.asarray(obs).tobytes(), info]
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        trace.append((np.asarray(obs).tobytes(), r, term, trunc, info.get("episode_metrics")))
        if term or trunc:
            break
    return repr(trace)


@pytest.mark.parametrize("observation", ["tabular", "vector"])
def test_a_layout_chosen_at_reset_is_that_layout(observation):
    actions = np.random.default_rng(2).integers(0, 7, 60)
    env = AuvSwiptEnv(preset="paper", n_nodes=12, observation=observation)
    space = env.observation_space
    for k in (5, 9, 0, 5):
        fixed = AuvSwiptEnv(preset="paper", n_nodes=12, observation=observation, layout_seed=k)
        assert _trace(env, 3, {"layout_seed": k}, actions) == _trace(fixed, 3, None, actions)
        assert env.scenario == fixed.scenario and env.observation_space == space
        rebuilt = K.build_tables(fixed.scenario)
        for f in dataclasses.fields(K.Tables):
            np.testing.assert_array_equal(getattr(env.tables, f.name), getattr(rebuilt, f.name), err_msg=f.name)
    # without options an episode runs on the scenario's own layout again
    fresh = AuvSwiptEnv(preset="paper", n_nodes=12, observation=observation)
    assert _trace(env, 3, None, actions) == _trace(fresh, 3, None, actions)


def test_layouts_drawn_per_episode():
    env = AuvSwiptEnv(preset="paper", n_nodes=6, layout_seeds=[11, 12, 13, 14])
    drawn = [env.reset(seed=s)[1]["layout_seed"] for s in range(40)]
    assert set(drawn) == {11, 12, 13, 14}
    assert drawn == [env.reset(seed=s)[1]["layout_seed"] for s in range(40)]  # seeded: reproducible
    assert env.reset(seed=0, options={"layout_seed": 99})[1]["layout_seed"] == 99  # an option wins
    unseeded = {env.reset()[1]["layout_seed"] for _ in range(40)}
    assert unseeded == {11, 12, 13, 14}
    positions = {
        env.reset(options={"layout_seed": k})[1]["layout_seed"]: env.scenario.layout.positions_m.copy()
        for k in (11, 12)
    }
    assert not np.allclose(positions[11], positions[12])
    huge = AuvSwiptEnv(preset="tiny", layout_seeds=range(10**12, 2 * 10**12, 7))  # never materialised
    seed = huge.reset(seed=0)[1]["layout_seed"]
    assert 10**12 <= seed < 2 * 10**12 and (seed - 10**12) % 7 == 0


def test_an_unused_layout_path_rebuilds_nothing():
    env = AuvSwiptEnv(preset="paper", n_nodes=6)
    env.reset(seed=0)
    tables, scenario = env.tables, env.scenario
    env.reset(seed=1)
    env.reset(options={"layout_seed": scenario.layout_seed})
    assert env.tables is tables and env.scenario is scenario


def test_bad_reset_options_and_layout_seeds():
    env = AuvSwiptEnv(preset="tiny")
    with pytest.raises(swiptopt.ConfigError, match=r"unknown reset option 'layout'.*\['layout_seed'\]"):
        env.reset(options={"layout": 3})
    for bad in (-1, 2.5, "3", True, 2**63):
        with pytest.raises(swiptopt.ConfigError, match="layout_seed"):
            env.reset(options={"layout_seed": bad})
    for bad in ([], "0123", [1, -2], {"a": 1}, 5, range(-3, 2)):
        with pytest.raises(swiptopt.ConfigError, match="layout_seeds"):
            AuvSwiptEnv(preset="tiny", layout_seeds=bad)
    assert env.reset(options={})[1]["layout_seed"] == 0


def test_recent_layouts_stay_built():
    from swiptopt.env import LAYOUT_CACHE_SIZE

    env = AuvSwiptEnv(preset="tiny", layout_seeds=range(3))
    built = {}
    for s in range(30):
        _, info = env.reset(seed=s)
        assert env.tables is built.setdefault(info["layout_seed"], env.tables)  # built once each
    first = env.reset(options={"layout_seed": 100})[0] is not None and env.tables
    for k in range(101, 101 + LAYOUT_CACHE_SIZE):
        env.reset(options={"layout_seed": k})
    recent = env.tables
    env.reset(options={"layout_seed": 100})  # dropped: built again, the same
    assert env.tables is not first
    np.testing.assert_array_equal(env.tables.cov_node, first.cov_node)
    env.reset(options={"layout_seed": 100 + LAYOUT_CACHE_SIZE})
    assert env.tables is recent


def test_grid_actions_are_integers_never_truncated_or_parsed():
    """2.7 is not move 2 and "3" is not move 3 (no truncation, no parsing); a huge array gets a
    short message."""
    env = AuvSwiptEnv(preset="tiny")
    env.reset(seed=0)
    for bad in (2.7, "3", 1j, True, float("nan"), -1, K.N_ACTIONS, np.zeros(10**6), [1, 2]):
        with pytest.raises(ValueError, match=r"action must be an integer in \[0, 6\]") as info:
            env.step(bad)
        assert len(str(info.value)) < 200
    for good in (3, np.int64(2), 4.0, np.array([1])):
        env.step(good)


def test_the_named_parameters_are_the_vector_by_name():
    """Callers read the kernel's scalars by name (K.Params); each name must sit at its P_* index."""
    tables = K.build_tables(Scenario.preset("paper", n_nodes=6, channel="rician", link="uplink"))
    named = tables.named
    assert len(K.Params._fields) == K.N_PARAMS
    pairs = {"P_DT": "dt_s", "P_ALPHA": "split_ratio", "P_SNR_TH": "snr_threshold", "P_GAMMA": "reward_weight",
             "P_LAMBDA": "movement_weight", "P_MOVE_REF": "move_ref_j", "P_STEPS": "steps",
             "P_NORMAL_ROWS": "normal_rows", "P_LINK": "link", "P_PACKET_BITS": "packet_bits"}
    for index, name in pairs.items():
        assert K.Params._fields[getattr(K, index)] == name
        assert getattr(named, name) == tables.params[getattr(K, index)]
    assert named.link == K.LINK_CODES["uplink"] and named.normal_rows == 2.0
    changed = K.replace_params(tables.params, drain_j=0.5)
    assert changed[K.P_DRAIN_J] == 0.5 and tables.params[K.P_DRAIN_J] != 0.5  # a copy
