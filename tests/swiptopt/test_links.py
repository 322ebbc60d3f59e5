"""The link technologies (docs/links.md): each one's functions against the published
formulas computed here independently, the acoustic link unchanged, an env per technology,
and bad settings refused in one line."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swiptopt import Scenario
from swiptopt import kernel as K
from swiptopt.errors import ConfigError
from swiptopt.link import link_budget, magnetic_constants, reward_references, service_range_m, transmit_power_w
from swiptopt.magnetic import skin_depth_m
from swiptopt.optical import WATER_ATTENUATION_PER_M
from swiptopt.scenario import TECHNOLOGY_FIELDS

DISTANCES_M = (1.0, 2.0, 5.0, 10.0, 20.0, 40.0)
# the elementary charge and Boltzmann's constant (SI 2019, exact), mu_0 (CODATA 2018)
Q_C, K_B, MU_0 = 1.602176634e-19, 1.380649e-23, 1.25663706212e-6


def optical_reference(s: Scenario, d: float) -> tuple[float, float]:
    """(SNR dB, available W) of the optical link from its published formulas: Beer-Lambert,
    the beam's geometric gain, the photodiode's shot and thermal noise, the PV panel."""
    c = {"pure_sea": 0.056, "clear_ocean": 0.151, "coastal": 0.398, "turbid_harbour": 2.17}[s.water_type]
    solid_angle = 2 * math.pi * (1 - math.cos(math.radians(s.cone_half_angle_deg)))
    received = s.optical_power_w * math.exp(-c * d) * min(1.0, s.receiver_aperture_m2 / (solid_angle * d * d))
    signal = s.responsivity_a_per_w * received
    background = s.responsivity_a_per_w * s.background_irradiance_w_m2 * s.receiver_aperture_m2
    b = s.optical_bandwidth_hz
    noise = 2 * Q_C * (signal + background + s.dark_current_a) * b + 4 * K_B * 290.0 * b / s.photodiode_load_ohm
    return 10 * math.log10(signal**2 / noise), s.pv_efficiency * received


def mi_reference(s: Scenario, d: float) -> tuple[float, float]:
    """(SNR dB, received W) of the MI link: coaxial coils' mutual inductance, the skin
    depth's attenuation, resonant circuits with a matched load, thermal noise k T B F."""
    omega = 2 * math.pi * s.mi_frequency_khz * 1e3
    delta = math.sqrt(2 / (omega * MU_0 * s.seawater_conductivity_s_per_m))
    a, n = s.coil_radius_m, s.coil_turns
    mutual = MU_0 * math.pi * n * n * a**4 / (2 * d**3)
    resistance = 2 * math.pi * a * n * s.coil_wire_ohm_per_m
    x = omega**2 * mutual**2 * math.exp(-2 * d / delta) / resistance**2
    received = s.mi_transmit_power_w * x / (4 + 2 * x)
    noise = K_B * 290.0 * s.mi_bandwidth_hz * 10 ** (s.mi_noise_figure_db / 10)
    return 10 * math.log10(received / noise), received


@pytest.mark.parametrize("water", sorted(WATER_ATTENUATION_PER_M))
def test_the_optical_link_is_its_published_formulas(water):
    s = Scenario.preset("paper-optical", water_type=water)
    budget = link_budget(s, np.array(DISTANCES_M), split_ratio=0.0)
    for i, d in enumerate(DISTANCES_M):
        snr, available = optical_reference(s, d)
        assert budget.snr_db[i] == pytest.approx(snr, rel=1e-9, abs=1e-9)
        assert budget.available_power_w[i] == pytest.approx(available, rel=1e-12)
    assert WATER_ATTENUATION_PER_M[water] == {"pure_sea": 0.056, "clear_ocean": 0.151, "coastal": 0.398,
                                              "turbid_harbour": 2.17}[water]


@pytest.mark.parametrize("frequency_khz", [1.0, 10.0, 50.0])
def test_the_mi_link_is_its_published_formulas(frequency_khz):
    s = Scenario.preset("paper-mi", mi_frequency_khz=frequency_khz)
    budget = link_budget(s, np.array(DISTANCES_M))
    for i, d in enumerate(DISTANCES_M):
        snr, received = mi_reference(s, d)
        assert budget.snr_db[i] == pytest.approx(snr, rel=1e-9)
        assert budget.available_power_w[i] == pytest.approx(received, rel=1e-12)
    # the skin depth of seawater at 10 kHz, 4 S/m: 2.516 m
    assert float(skin_depth_m(10.0, 4.0)) == pytest.approx(2.5165, abs=1e-4)
    assert magnetic_constants(s).skin_depth_m == pytest.approx(float(skin_depth_m(frequency_khz, 4.0)))


def test_mi_power_falls_as_the_sixth_power_of_distance_in_fresh_water():
    """With a negligible conductivity (no skin-depth loss) and weak coupling, doubling the
    distance divides the received power by 2^6."""
    s = Scenario.preset("paper-mi", seawater_conductivity_s_per_m=1e-15)
    p = link_budget(s, np.array([8.0, 16.0])).available_power_w
    assert p[0] / p[1] == pytest.approx(64.0, rel=1e-6)


def test_the_acoustic_scenario_is_as_before():
    """The technology fields stay out of an acoustic scenario's dict (its hashes and keys
    are those of before), and the acoustic link's numbers are not the others'."""
    paper = Scenario.preset("paper")
    assert not TECHNOLOGY_FIELDS & set(paper.to_dict())
    assert Scenario.from_dict(Scenario.preset("paper-optical").to_dict()) == Scenario.preset("paper-optical")
    assert transmit_power_w(paper) == paper.electrical_power_w == 1000.0
    assert transmit_power_w(Scenario.preset("paper-optical")) == pytest.approx(1.0 / 0.3)
    # every technology's reward shares the acoustic reference, so returns compare across them
    assert reward_references(Scenario.preset("paper-mi")) == reward_references(paper)


def test_the_service_range_orders_the_water_types():
    ranges = [service_range_m(Scenario.preset("paper-optical", water_type=w))
              for w in ("pure_sea", "clear_ocean", "coastal", "turbid_harbour")]
    assert ranges == sorted(ranges, reverse=True) and ranges[-1] < 5.0 < ranges[1]


def test_magnetic_induction_reaches_every_direction():
    """A node above the AUV, out of any downward cone, is covered by MI (no beam), not by
    the optical link."""
    nodes = ((55.0, 55.0, 15.0), (55.0, 55.0, 35.0))  # 10 m above and 10 m below the start
    common = dict(n_nodes=2, node_positions_m=nodes, start_cell=(5, 5, 2), channel="none",
                  failure_prob_min=0.0, failure_prob_max=0.0)
    start = Scenario.preset("paper", **common).resolved_start_cell
    for preset, covered in (("paper-mi", {0, 1}), ("paper-optical", {1})):
        tables = K.build_tables(Scenario.preset(preset, **common))
        cell = int(Scenario.preset(preset, **common).cell_index(start))
        assert set(tables.covered(cell).tolist()) == covered, preset


@pytest.mark.parametrize("preset", ["paper-optical", "paper-mi"])
def test_an_env_per_technology_passes_both_checkers(preset):
    from gymnasium.utils.env_checker import check_env

    from swiptopt.env import AuvSwiptEnv

    for observation in ("tabular", "vector"):
        env = AuvSwiptEnv(Scenario.preset(preset, n_nodes=8), observation=observation)
        check_env(env, skip_render_check=True)
        if observation == "vector":
            sb3 = pytest.importorskip("stable_baselines3.common.env_checker")
            sb3.check_env(env, warn=False)


def test_a_technology_sweep_runs_and_every_technology_collects_data():
    from swiptopt.benchmark.experiment import Experiment
    from swiptopt.benchmark.runner import run_task

    experiment = Experiment(name="links", scenario={"preset": "paper", "n_nodes": 10},
                            sweep={"technology": ["acoustic", "optical", "magnetic_induction"]},
                            algorithms={"rate_greedy": {}}, layouts=1, episodes=1)
    results = {t.point["technology"]: run_task(t.to_dict()) for t in experiment.tasks()}
    assert set(results) == {"acoustic", "optical", "magnetic_induction"}
    data = {k: r["records"][0]["data_bits"] for k, r in results.items()}
    assert all(v > 0 for v in data.values()), data
    energy = {k: r["records"][0]["energy_delivered_j"] for k, r in results.items()}
    assert energy["acoustic"] > 100 * max(energy["optical"], energy["magnetic_induction"])  # the trade-off


@pytest.mark.parametrize(("overrides", "field", "words"), [
    ({"technology": "sonar"}, "technology", "'acoustic', 'optical', 'magnetic_induction'"),
    ({"technology": "optical", "water_type": "murky"}, "water_type", "'clear_ocean'"),
    ({"technology": "optical", "link": "uplink"}, "link", "acoustic link only"),
    ({"technology": "magnetic_induction", "coil_turns": 0}, "coil_turns", "coil_turns"),
    ({"technology": "optical", "pv_efficiency": 1.5}, "pv_efficiency", "pv_efficiency"),
])
def test_bad_technology_settings_are_one_line_naming_the_field(overrides, field, words):
    with pytest.raises(ConfigError) as info:
        Scenario.preset("paper", **overrides)
    assert info.value.field == field and words in str(info.value) and "\n" not in str(info.value)


def test_the_continuous_world_refuses_other_technologies():
    from swiptopt.continuous import build_world

    with pytest.raises(ConfigError, match="grid world only") as info:
        build_world(Scenario.preset("harbour", technology="optical"))
    assert info.value.field == "technology"
