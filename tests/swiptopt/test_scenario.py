import dataclasses

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from swiptopt import link
from swiptopt.scenario import PRESETS, Box, Scenario, ScenarioError, Sphere


def test_paper_defaults_match_the_spec():
    s = Scenario.preset("paper")
    assert s.grid_shape == (10, 10, 5)
    assert s.n_cells == 500
    assert s.resolved_start_cell == (5, 5, 0)
    assert s.step_duration_s == pytest.approx(10 / 1.5)
    assert s.bandwidth_hz == pytest.approx(4000.0)
    np.testing.assert_allclose(s.cell_centers_m[s.start_cell_index], [55.0, 55.0, 5.0])


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_presets_build_and_round_trip_through_toml(name, tmp_path):
    s = Scenario.preset(name)
    path = tmp_path / f"{name}.toml"
    s.to_toml(path)
    back = Scenario.from_toml(path)
    assert back == s
    np.testing.assert_array_equal(back.layout.positions_m, s.layout.positions_m)


def test_round_trip_with_overrides_and_optional_fields(tmp_path):
    s = Scenario.preset(
        "harbour",
        n_nodes=7,
        layout_seed=99,
        split_ratio=0.3,
        energy_ref_j=0.2,
        start_cell=(15, 15, 1),
        harvester="logistic",
    )
    s.to_toml(tmp_path / "s.toml")
    assert Scenario.from_toml(tmp_path / "s.toml") == s


def test_toml_may_start_from_a_preset(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(
        'preset = "tiny"\nn_nodes = 2\n\n[[obstacles]]\nkind = "sphere"\ncenter_m = [5, 5, 15]\nradius_m = 2\n'
    )
    s = Scenario.from_toml(path)
    assert (s.name, s.n_nodes, s.grid_shape) == ("tiny", 2, (3, 3, 2))
    assert s.obstacles == (Sphere(center_m=(5.0, 5.0, 15.0), radius_m=2.0),)


@pytest.mark.parametrize(
    "overrides, field, words",
    [
        ({"n_nodes": -3}, "n_nodes", ["-3", "[1, 10000]"]),
        ({"split_ratio": 1.5}, "split_ratio", ["1.5", "[0, 1]"]),
        ({"frequency_khz": -24.0}, "frequency_khz", ["-24", "[0.1, 1000]"]),
        ({"n_nodes": 2.5}, "n_nodes", ["2.5", "integer"]),
        ({"channel": "foggy"}, "channel", ["foggy", "shadowing"]),
        ({"length_m": 105.0}, "length_m", ["105", "cell_size_m"]),
        ({"frequency_khz": 30.0}, "frequency_khz", ["30", "band"]),
        ({"initial_soc_min": 0.9}, "initial_soc_min", ["0.9", "initial_soc_max"]),
        ({"start_cell": (10, 0, 0)}, "start_cell", ["(10, 0, 0)", "outside"]),
        ({"reward_weight": True}, "reward_weight", ["True", "number"]),
        ({"energy_ref_j": 0.0}, "energy_ref_j", ["0.0", "(0,"]),
    ],
)
def test_bad_values_name_the_field_value_and_range(overrides, field, words):
    with pytest.raises(ScenarioError) as info:
        Scenario.preset("paper", **overrides)
    assert info.value.field == field
    message = str(info.value)
    assert field in message
    for word in words:
        assert word in message


def test_unknown_keys_are_errors(tmp_path):
    with pytest.raises(ScenarioError, match="unknown scenario key 'n_node'"):
        Scenario.preset("paper", n_node=3)
    path = tmp_path / "s.toml"
    path.write_text("n_nodes = 3\nsplit_factor = 0.5\n")
    with pytest.raises(ScenarioError, match="split_factor") as info:
        Scenario.from_toml(path)
    assert str(path) in str(info.value)
    path.write_text('[[obstacles]]\nkind = "box"\nmin_m = [0, 0, 0]\nmax_m = [1, 1, 1]\ncolour = "red"\n')
    with pytest.raises(ScenarioError, match="colour"):
        Scenario.from_toml(path)


def test_malformed_and_missing_files(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("n_nodes = [\n")
    with pytest.raises(ScenarioError, match="malformed TOML"):
        Scenario.from_toml(path)
    with pytest.raises(ScenarioError, match="cannot read"):
        Scenario.from_toml(tmp_path / "absent.toml")
    with pytest.raises(ScenarioError, match="unknown preset"):
        Scenario.preset("ocean")


def test_start_cell_inside_an_obstacle_is_rejected():
    with pytest.raises(ScenarioError, match="start_cell") as info:
        Scenario.preset("paper", obstacles=(Box(min_m=(50, 50, 0), max_m=(60, 60, 10)),))
    assert info.value.field == "start_cell"


def test_scenario_is_frozen_and_replace_validates():
    s = Scenario.preset("paper")
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.n_nodes = 3  # type: ignore[misc]
    assert s.replace(n_nodes=3).n_nodes == 3
    with pytest.raises(ScenarioError, match="n_nodes"):
        s.replace(n_nodes=0)


@given(alpha=st.floats(allow_nan=False, allow_infinity=False))
def test_split_ratio_validation_property(alpha):
    if 0.0 <= alpha <= 1.0:
        assert Scenario(split_ratio=alpha).split_ratio == alpha
    else:
        with pytest.raises(ScenarioError, match="split_ratio"):
            Scenario(split_ratio=alpha)


@given(n=st.integers(-1000, 20_000))
def test_node_count_validation_property(n):
    if 1 <= n <= 10_000:
        assert Scenario(n_nodes=n).n_nodes == n
    else:
        with pytest.raises(ScenarioError, match="n_nodes"):
            Scenario(n_nodes=n)


def test_layout_is_drawn_from_the_layout_seed():
    a = Scenario.preset("paper", layout_seed=3).layout
    b = Scenario.preset("paper", layout_seed=3).layout
    c = Scenario.preset("paper", layout_seed=4).layout
    np.testing.assert_array_equal(a.positions_m, b.positions_m)
    np.testing.assert_array_equal(a.initial_energy_j, b.initial_energy_j)
    assert not np.allclose(a.positions_m, c.positions_m)
    assert a.positions_m.shape == (25, 3)
    assert np.all((a.positions_m >= 0) & (a.positions_m <= [100, 100, 50]))
    soc = a.initial_energy_j / a.capacity_j
    assert np.all((soc >= 0.2) & (soc <= 0.8))
    assert np.all((a.failure_prob >= 0.05) & (a.failure_prob <= 0.25))
    # changing the node count keeps the charge stream independent of the position stream
    d = Scenario.preset("paper", layout_seed=3, obstacles=(Sphere((20, 20, 30), 5.0),)).layout
    np.testing.assert_array_equal(a.initial_energy_j, d.initial_energy_j)


def test_harbour_nodes_and_start_avoid_obstacles_and_seabed():
    s = Scenario.preset("harbour")
    assert not np.any(s.is_blocked(s.layout.positions_m))
    assert not s.blocked_cells[s.start_cell_index]
    # the seabed rises towards x = 0: 12 m above the bottom there, flat at the far side
    assert s.seabed_depth_m(0.0, 50.0) == pytest.approx(28.0)
    assert s.seabed_depth_m(200.0, 50.0) == pytest.approx(40.0)
    assert s.seabed_depth_m(50.0, 10.0) == pytest.approx(40.0 - 8.0)
    assert s.blocked_cells.sum() > 0


def test_explicit_positions_and_current_field():
    s = Scenario.preset("tiny", n_nodes=2, node_positions_m=[(5, 5, 15), (25, 25, 5)],
                        current_mps=(0.2, 0, 0), current_bottom_mps=(0.0, 0, 0))
    np.testing.assert_array_equal(s.layout.positions_m, [[5, 5, 15], [25, 25, 5]])
    np.testing.assert_allclose(s.current_at_mps([0.0, 10.0, 20.0])[:, 0], [0.2, 0.1, 0.0])
    with pytest.raises(ScenarioError, match="node_positions_m"):
        Scenario.preset("tiny", n_nodes=3, node_positions_m=[(5, 5, 15)])


def test_reward_references_and_link_budget():
    s = Scenario.preset("paper")
    refs = link.reward_references(s)
    assert refs.data_ref_bits == 1e5
    assert refs.move_energy_ref_j == pytest.approx(44.05875 * 10 / 1.5)
    # E_ref: RL at 10 m = SL - TL; P_av = V^2 / 4R; whole signal harvested at eta 0.5; one step
    sl = 170.8 + 10 * np.log10(1000 * 0.5)
    tl = 15.0 + 0.01 * 5.691226
    p_av = 10 ** ((sl - tl - 170.0) / 10) / 400.0
    assert refs.energy_ref_j == pytest.approx(0.5 * p_av * 10 / 1.5, rel=1e-6)
    # independent of the split ratio, overridable
    assert link.reward_references(s.replace(split_ratio=0.9)).energy_ref_j == refs.energy_ref_j
    assert link.reward_references(s.replace(energy_ref_j=2.0)).energy_ref_j == 2.0
    budget = link.link_budget(s, [10.0, 50.0])
    assert np.all(np.diff(budget.snr_db) < 0) and np.all(np.diff(budget.harvested_power_w) < 0)
    assert budget.harvested_power_w[0] == pytest.approx(0.5 * 0.5 * p_av, rel=1e-6)


def test_service_range_follows_the_snr_threshold():
    s = Scenario.preset("paper")
    assert link.service_range_m(s) == 100.0  # the cone's range limit binds
    tight = s.replace(snr_threshold_db=95.0)
    r = link.service_range_m(tight)
    assert 10.0 < r < 100.0
    assert link.link_budget(tight, r).snr_db == pytest.approx(95.0, abs=1e-6)


# ------------------------------------------------------------------ labels, keys, files, sizes


def test_a_preset_may_carry_a_label_of_its_own(tmp_path):
    s = Scenario.preset("tiny", name="my tiny")
    assert (s.name, s.grid_shape) == ("my tiny", Scenario.preset("tiny").grid_shape)
    assert Scenario.preset("tiny").name == "tiny"
    path = tmp_path / "s.toml"
    path.write_text('preset = "harbour"\nname = "quay"\n')
    assert Scenario.from_toml(path).name == "quay"
    assert Scenario.from_dict({"name": "plain", "n_nodes": 3}).name == "plain"
    with pytest.raises(ScenarioError, match="name = 3 must be a string"):
        Scenario.preset("tiny", name=3)


@pytest.mark.parametrize("values", [{3: 1}, {3: 1, "n_nodes": 3}, {None: 1, 2.5: 2}, {("a",): 1, "preset": "tiny"}])
def test_non_string_keys_are_scenario_errors(values):
    with pytest.raises(ScenarioError, match="not a string") as info:
        Scenario.from_dict(values)
    assert info.value.field == "scenario"


def test_a_numpy_height_map_is_accepted():
    heights = np.array([[12.0, 12.0, 12.0], [4.0, 4.0, 4.0], [0.0, 0.0, 0.0]])
    s = Scenario.preset("harbour", seabed_height_m=heights)
    assert s == Scenario.preset("harbour")  # the same map as the preset's nested tuples
    assert Scenario.preset("paper", node_positions_m=np.full((25, 3), 5.0)).layout.positions_m.shape == (25, 3)
    with pytest.raises(ScenarioError, match="2-D list"):
        Scenario.preset("paper", seabed_height_m=np.zeros(0))


def test_a_file_that_is_not_utf8_is_one_error(tmp_path):
    path = tmp_path / "s.toml"
    path.write_bytes(b'preset = "tiny"\nname = "\xff\xfe"\n')
    with pytest.raises(ScenarioError) as info:
        Scenario.from_toml(path)
    assert str(path) in str(info.value) and "not a UTF-8 text file (byte 0xff at offset 24)" in str(info.value)
    path.write_text("a = " + "[" * 10_000 + "]" * 10_000 + "\n")
    with pytest.raises(ScenarioError, match="nested too deeply"):
        Scenario.from_toml(path)


@pytest.mark.parametrize(
    "overrides, field, words",
    [
        ({"cell_size_m": 0.01}, "cell_size_m", ["cell_size_m = 0.01", "10,000 x 10,000 x 5,000", "500,000,000,000",
                                                "1,000,000", "SWIPTOPT_MAX_CELLS"]),
        ({"length_m": 100_000.0, "width_m": 100_000.0}, "cell_size_m", ["10,000 x 10,000 x 5", "500,000,000"]),
        ({"cell_size_m": 1.0, "n_nodes": 1000}, "n_nodes", ["500,000 x n_nodes = 1,000", "500,000,000", "50,000,000",
                                                          "SWIPTOPT_MAX_CELL_NODE_PAIRS"]),
    ],
)
def test_sizes_that_cannot_fit_fail_before_anything_is_allocated(monkeypatch, overrides, field, words):
    def no_allocation(*args, **kwargs):
        raise AssertionError("cells were allocated before the size check")

    monkeypatch.setattr(Scenario, "is_blocked", no_allocation)
    with pytest.raises(ScenarioError) as info:
        Scenario.preset("paper", **overrides)
    assert info.value.field == field
    for word in words:
        assert word in str(info.value)


def test_size_limits_allow_a_laptop_sized_scenario_and_are_overridable(monkeypatch):
    fine = Scenario.preset("paper", cell_size_m=2.5, n_nodes=1000)
    assert fine.n_cells * fine.n_nodes == 32_000_000
    monkeypatch.setenv("SWIPTOPT_MAX_CELL_NODE_PAIRS", "1_000_000")
    with pytest.raises(ScenarioError,
                       match=r"32,000,000, over the limit of 1,000,000 \(set SWIPTOPT_MAX_CELL_NODE_PAIRS"):
        Scenario.preset("paper", cell_size_m=2.5, n_nodes=1000)
    monkeypatch.setenv("SWIPTOPT_MAX_CELLS", "600_000")
    monkeypatch.setenv("SWIPTOPT_MAX_CELL_NODE_PAIRS", "600_000")
    assert Scenario.preset("paper", cell_size_m=1.0, n_nodes=1).n_cells == 500_000
