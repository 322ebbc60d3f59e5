"""The link budget of one scenario: the model functions combined for given distances.

This module is where the scenario's parameters meet the physics of ``acoustics``,
``harvesting`` and ``auv``; the simulator kernel, the coverage analysis, the planners and
``swiptopt scenario show`` all read their numbers from here, so there is one combination of
the equations, not one per caller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from swiptopt import acoustics, auv, harvesting, magnetic, optical
from swiptopt.scenario import Scenario

#: Distance of the on-axis reference link that defines the energy reward reference, m.
REFERENCE_DISTANCE_M = 10.0


@dataclass(frozen=True, eq=False)
class LinkBudget:
    """The AUV-to-node link at given distances; arrays have the shape of ``distance_m``."""

    distance_m: np.ndarray
    source_level_db: float
    """Projector source level, dB re 1 uPa @ 1 m."""
    noise_level_db: float
    """Noise level in the band, dB re 1 uPa."""
    transmission_loss_db: np.ndarray
    received_level_db: np.ndarray
    """RL = SL - TL, dB re 1 uPa."""
    snr_db: np.ndarray
    """Link SNR before power splitting, dB; coverage compares it with the threshold."""
    in_service: np.ndarray
    """Whether the SNR reaches ``snr_threshold_db`` (bool)."""
    rate_bps: np.ndarray
    """Information rate with the split alpha * SNR; zero where out of service."""
    available_power_w: np.ndarray
    """Electrical power available at the node's transducer, W."""
    harvested_power_w: np.ndarray
    """Harvested DC power, W; zero where out of service. With ``link = "downlink_split"`` the
    split (1 - alpha) goes to the harvester, with ``"uplink"`` all of the received power."""
    uplink_snr_db: np.ndarray
    """SNR of the node's own transmission at the AUV, dB (paper eq. 13): the node's source
    level through the same channel and noise, received with the AUV transducer's directivity."""
    uplink_rate_bps: np.ndarray
    """Rate of the node's transmission, B log2(1 + SNR_up), bit/s; zero below the threshold."""


def source_level_db(scenario: Scenario) -> float:
    """Projector source level of the scenario, dB re 1 uPa @ 1 m (paper eq. 2)."""
    return float(
        acoustics.source_level_db(
            scenario.electrical_power_w, scenario.electroacoustic_efficiency, scenario.directivity_tx_db
        )
    )


def node_source_level_db(scenario: Scenario) -> float:
    """Source level of a node's transmitter (uplink), dB re 1 uPa @ 1 m (paper eq. 2 with
    the node's power, efficiency and its transducer's directivity)."""
    return float(
        acoustics.source_level_db(
            scenario.node_transmit_power_w, scenario.node_electroacoustic_efficiency, scenario.directivity_rx_db
        )
    )


def uplink_snr_offset_db(scenario: Scenario) -> float:
    """SNR of the node's transmission at the AUV minus the AUV's at the node, dB.

    Both directions cross the same transmission loss and the same band noise (paper eqs. 3,
    13), and each transducer has one directivity for sending and receiving, so the
    difference is a constant: 10 log10(P_i eta_i / (P_elec eta_ea)). The kernel scales each
    pair's mean SNR by it, so the two directions share one table and one fading draw
    (reciprocity).
    """
    downlink = source_level_db(scenario) + scenario.directivity_rx_db
    uplink = node_source_level_db(scenario) + scenario.directivity_tx_db
    return uplink - downlink


def noise_level_db(scenario: Scenario) -> float:
    """Noise level over the scenario's band, dB re 1 uPa (paper eqs. 5-8 over the band B)."""
    return float(
        acoustics.noise_level_db(
            scenario.frequency_khz,
            scenario.bandwidth_hz,
            scenario.shipping,
            scenario.wind_mps,
            integrate=scenario.noise_integrated,
            band_khz=(scenario.band_min_khz, scenario.band_max_khz),
        )
    )


def harvested_power_w(
    scenario: Scenario, available_power_w: ArrayLike, split_ratio: ArrayLike | None = None
) -> np.ndarray:
    """The scenario's harvester applied to ``available_power_w`` (split default:
    :func:`harvest_split`)."""
    return harvesting.harvested_power_w(
        available_power_w,
        harvest_split(scenario) if split_ratio is None else split_ratio,
        scenario.harvest_efficiency,
        scenario.harvester,  # type: ignore[arg-type]
        logistic_max_w=scenario.logistic_max_w,
        logistic_a_per_w=scenario.logistic_a_per_w,
        logistic_b_w=scenario.logistic_b_w,
    )


def link_budget(
    scenario: Scenario, distance_m: ArrayLike, split_ratio: ArrayLike | None = None
) -> LinkBudget:
    """Every quantity of the mean (unfaded) link at ``distance_m`` (any shape).

    The formulas are listed in docs/design.md, 'The acoustic link (Section II-B)' and 'SWIPT at the node
    (Section II-C)'.

    ``split_ratio`` defaults to the scenario's for ``link = "downlink_split"`` and to 0 (all
    received power to the harvester) for ``"uplink"``.
    """
    if split_ratio is None:
        split_ratio = harvest_split(scenario)
    alpha = split_ratio
    d = np.asarray(distance_m, dtype=float)
    if scenario.technology != "acoustic":
        return _light_or_field_budget(scenario, d, alpha)
    sl = source_level_db(scenario)
    nl = noise_level_db(scenario)
    tl = acoustics.transmission_loss_db(d, scenario.frequency_khz, scenario.spreading_k)
    rl = sl - tl
    snr = acoustics.snr_db(sl, tl, nl, scenario.directivity_rx_db)
    ok = snr >= scenario.snr_threshold_db
    info_snr = harvesting.information_snr_linear(acoustics.db_to_linear(snr), alpha)
    rate = np.where(ok, acoustics.shannon_rate_bps(scenario.bandwidth_hz, info_snr), 0.0)
    p_av = harvesting.available_power_w(rl, scenario.sensitivity_db, scenario.load_ohm, scenario.n_elements)
    p_h = np.where(ok, harvested_power_w(scenario, p_av, alpha), 0.0)
    snr_up = snr + uplink_snr_offset_db(scenario)
    rate_up = np.where(
        snr_up >= scenario.snr_threshold_db,
        acoustics.shannon_rate_bps(scenario.bandwidth_hz, acoustics.db_to_linear(snr_up)),
        0.0,
    )
    return LinkBudget(d, sl, nl, tl, rl, snr, ok, rate, p_av, p_h, snr_up, rate_up)


def optical_constants(scenario: Scenario) -> optical.OpticalConstants:
    """The optical link's constants of the scenario (docs/links.md): its source, the water
    type's attenuation, a beam as wide as the coverage cone, the node's receiver."""
    return optical.constants(
        transmit_power_w=scenario.optical_power_w,
        attenuation_per_m=optical.WATER_ATTENUATION_PER_M[scenario.water_type],
        aperture_m2=scenario.receiver_aperture_m2,
        half_angle_deg=scenario.cone_half_angle_deg,
        responsivity_a_per_w=scenario.responsivity_a_per_w,
        dark_current_a=scenario.dark_current_a,
        background_irradiance_w_m2=scenario.background_irradiance_w_m2,
        bandwidth_hz=scenario.optical_bandwidth_hz,
        load_ohm=scenario.photodiode_load_ohm,
        pv_efficiency=scenario.pv_efficiency,
    )


def magnetic_constants(scenario: Scenario) -> magnetic.MagneticConstants:
    """The MI link's constants of the scenario (docs/links.md): equal coils on the AUV and
    the nodes, resonant at ``mi_frequency_khz``, in water of the given conductivity."""
    return magnetic.constants(
        transmit_power_w=scenario.mi_transmit_power_w,
        freq_khz=scenario.mi_frequency_khz,
        conductivity_s_per_m=scenario.seawater_conductivity_s_per_m,
        radius_tx_m=scenario.coil_radius_m,
        radius_rx_m=scenario.coil_radius_m,
        turns_tx=scenario.coil_turns,
        turns_rx=scenario.coil_turns,
        wire_ohm_per_m=scenario.coil_wire_ohm_per_m,
        bandwidth_hz=scenario.mi_bandwidth_hz,
        noise_figure_db=scenario.mi_noise_figure_db,
    )


def _light_or_field_budget(scenario: Scenario, d: np.ndarray, alpha: ArrayLike) -> LinkBudget:
    """:func:`link_budget` of the optical or the MI link: the same quantities from the
    technology's SNR and available power (the acoustic levels are NaN; no uplink)."""
    if scenario.technology == "optical":
        light = optical.link(d, optical_constants(scenario))
        snr, p_av = light.snr_db, light.available_power_w
    else:
        field_ = magnetic.link(d, magnetic_constants(scenario))
        snr, p_av = field_.snr_db, field_.received_power_w
    ok = snr >= scenario.snr_threshold_db
    info_snr = harvesting.information_snr_linear(acoustics.db_to_linear(snr), alpha)
    rate = np.where(ok, acoustics.shannon_rate_bps(scenario.bandwidth_hz, info_snr), 0.0)
    p_h = np.where(ok, harvested_power_w(scenario, p_av, alpha), 0.0)
    nan = np.full(d.shape, np.nan)
    return LinkBudget(d, math.nan, math.nan, nan, nan, snr, ok, rate, np.asarray(p_av, dtype=float), p_h,
                      np.full(d.shape, -np.inf), np.zeros(d.shape))


def transmit_power_w(scenario: Scenario) -> float:
    """The electrical power the AUV's transmitter draws while it serves a node, W: the
    acoustic projector's ``electrical_power_w``, the optical source's light over its
    wall-plug efficiency, or the MI driver's power."""
    if scenario.technology == "optical":
        return scenario.optical_power_w / scenario.optical_wallplug_efficiency
    if scenario.technology == "magnetic_induction":
        return float(scenario.mi_transmit_power_w)
    return float(scenario.electrical_power_w)


def harvest_split(scenario: Scenario) -> float:
    """The share of the AUV's signal a node sends to information decoding: the scenario's
    alpha on the power-split downlink; 0 on the uplink, where the node decodes nothing and
    harvests all it receives."""
    return scenario.split_ratio if scenario.link == "downlink_split" else 0.0


@dataclass(frozen=True)
class UplinkPacket:
    """What one uplink packet costs a node on a link of a given rate (docs/design.md, 'SWIPT at
    the node (Section II-C)')."""

    airtime_s: np.ndarray
    """Time on air, packet_bits / rate, s."""
    energy_j: np.ndarray
    """Energy from the node's storage, (P_i + P_C) x time on air, J."""


def uplink_packet(scenario: Scenario, rate_bps: ArrayLike) -> UplinkPacket:
    """Time on air and energy of one packet at ``rate_bps`` (> 0)."""
    airtime = scenario.packet_bits / np.asarray(rate_bps, dtype=float)
    return UplinkPacket(airtime, (scenario.node_transmit_power_w + scenario.node_circuit_power_w) * airtime)


def service_range_m(scenario: Scenario) -> float:
    """Largest slant distance at which a node is covered: the cone range or the SNR limit.

    SNR falls monotonically with distance, so the threshold distance is found by bisection.
    """
    limit = scenario.cone_range_m
    if link_budget(scenario, limit).in_service:
        return float(limit)
    lo, hi = 0.0, limit  # in service at lo (distances clamp to 1 m), not at hi
    if not link_budget(scenario, 1.0).in_service:
        return 0.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if link_budget(scenario, mid).in_service:
            lo = mid
        else:
            hi = mid
    return lo


@dataclass(frozen=True)
class AuvPower:
    """The AUV's power draw and per-step energies in still water (paper eqs. 16-18)."""

    propulsion_w: float
    hotel_w: float
    projector_w: float
    move_energy_j: float
    """Energy of one move of one cell (propulsion + hotel)."""
    hover_energy_j: float
    """Energy of one hover step (hotel + station keeping)."""
    projector_energy_j: float
    """Energy of the projector over one step."""


def auv_power(scenario: Scenario) -> AuvPower:
    """Still-water power and step energies of the scenario's AUV."""
    p_prop = float(
        auv.propulsion_power_w(
            scenario.speed_mps,
            scenario.drag_coefficient,
            scenario.frontal_area_m2,
            scenario.water_density_kg_m3,
            scenario.propulsion_efficiency,
        )
    )
    dt = scenario.step_duration_s
    transmit_w = transmit_power_w(scenario)
    return AuvPower(
        propulsion_w=p_prop,
        hotel_w=scenario.hotel_power_w,
        projector_w=transmit_w,
        move_energy_j=float(
            auv.move_energy_j(scenario.cell_size_m, scenario.speed_mps, p_prop, scenario.hotel_power_w)
        ),
        hover_energy_j=float(auv.hover_energy_j(dt, scenario.hotel_power_w, scenario.station_keeping_power_w)),
        projector_energy_j=transmit_w * dt,
    )


@dataclass(frozen=True)
class RewardReferences:
    """The normalisers of the reward (paper eq. 23):
    r = G bits/D_ref + (1-G) J/E_ref - l E_auv/E_move_ref."""

    data_ref_bits: float
    energy_ref_j: float
    move_energy_ref_j: float


def reward_references(scenario: Scenario) -> RewardReferences:
    """The scenario's reward references, derived unless overridden.

    ``energy_ref_j`` is what one node harvests in one step on the cone axis at
    :data:`REFERENCE_DISTANCE_M` with the whole signal sent to the harvester (alpha = 0):
    independent of ``split_ratio``, so rewards stay comparable across a split-ratio sweep.
    Every link technology takes the acoustic link's reference, so that rewards stay
    comparable across technologies too (an optical or MI node harvests orders of magnitude
    less, and its reward says so).
    """
    if scenario.technology != "acoustic":  # the references do not depend on the link but through E_ref
        return reward_references(scenario.replace(technology="acoustic"))
    data_ref = scenario.data_ref_bits if scenario.data_ref_bits is not None else scenario.data_bits
    if scenario.energy_ref_j is not None:
        energy_ref = scenario.energy_ref_j
    else:
        p_av = link_budget(scenario, REFERENCE_DISTANCE_M).available_power_w
        energy_ref = float(harvested_power_w(scenario, p_av, 0.0)) * scenario.step_duration_s
        if not energy_ref > 0:
            raise ValueError(
                "the derived energy_ref_j is 0 (the harvester yields nothing at 10 m): set energy_ref_j"
            )
    move_ref = (
        scenario.move_energy_ref_j if scenario.move_energy_ref_j is not None else auv_power(scenario).move_energy_j
    )
    return RewardReferences(float(data_ref), float(energy_ref), float(move_ref))
