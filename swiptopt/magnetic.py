"""Magnetic induction (MI): two resonant coupled coils in conducting seawater.

Every function is a pure, vectorised numpy function over distances (any shape); the
exponential and the logarithm go through :mod:`swiptopt.fpmath` (the C library's, element
by element: the same bits on every CPU). SI units unless the name says otherwise.
:func:`swiptopt.link.link_budget` calls :func:`link` for scenarios with
``technology = "magnetic_induction"``.

The link (docs/links.md has every parameter with its source):

- Mutual inductance of two coaxial loops in the near field (d >> coil radius),
  M = mu pi N_t N_r a_t^2 a_r^2 / (2 d^3) (Sun & Akyildiz 2010; Domingo 2012), so the power
  falls as d^-6; orientation loss is not modelled (coaxial alignment, which tri-directional
  coils approach in any orientation: Akyildiz, Wang & Sun 2015). The field is omnidirectional:
  a node is reachable in any direction within range.
- Coil resistance R = 2 pi a N R_0 for a wire of R_0 ohm per metre (Sun & Akyildiz 2010).
- Seawater's conductivity sigma attenuates the field as exp(-d / delta), the power as
  exp(-2 d / delta), with the skin depth delta = sqrt(2 / (omega mu sigma)) (Domingo 2012).
- Both coils resonant, the receiver's load matched to its coil (R_L = R_r): the share of the
  transmitter's power that reaches the load is x / (4 + 2 x), x = omega^2 M^2 e^{-2d/delta} /
  (R_t R_r): the circuit model's exact ratio, with the load's reflected impedance in the
  transmitter's loop; for weak coupling it is the familiar omega^2 M^2 / (4 R_t R_r) and it
  never exceeds 1/2 (the transformer circuit model of Sun & Akyildiz 2010; derived in
  docs/links.md). The same received power
  carries the data and, by resonant inductive power transfer, charges the node.
- Noise: thermal noise k T B of the matched receiver times its noise figure F.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from swiptopt import fpmath
from swiptopt.optical import BOLTZMANN_J_PER_K, MIN_DISTANCE_M, NOISE_TEMPERATURE_K

#: Magnetic constant mu_0, H/m (CODATA 2018).
MU_0_H_PER_M = 1.25663706212e-6


def angular_frequency_rad_s(freq_khz: ArrayLike) -> np.ndarray:
    """omega = 2 pi f, rad/s, for ``freq_khz`` in kHz."""
    return 2.0 * math.pi * (np.asarray(freq_khz, dtype=float) * 1000.0)


def skin_depth_m(
    freq_khz: ArrayLike, conductivity_s_per_m: ArrayLike, relative_permeability: float = 1.0
) -> np.ndarray:
    """Skin depth delta = sqrt(2 / (omega mu sigma)), m (Domingo 2012). Example: 2.516 m at
    10 kHz in seawater of 4 S/m."""
    omega = angular_frequency_rad_s(freq_khz)
    mu = MU_0_H_PER_M * relative_permeability
    return np.sqrt(2.0 / (omega * mu * np.asarray(conductivity_s_per_m, dtype=float)))


def mutual_inductance_h(
    distance_m: ArrayLike, radius_tx_m: float, radius_rx_m: float, turns_tx: float, turns_rx: float,
    relative_permeability: float = 1.0,
) -> np.ndarray:
    """Near-field mutual inductance of two coaxial coils, mu pi N_t N_r a_t^2 a_r^2 / (2 d^3),
    H (Sun & Akyildiz 2010; Domingo 2012); valid for ``distance_m`` much larger than the radii."""
    d = np.asarray(distance_m, dtype=float)
    return mutual_inductance_coefficient(radius_tx_m, radius_rx_m, turns_tx, turns_rx, relative_permeability) / (
        d * d * d
    )


def mutual_inductance_coefficient(
    radius_tx_m: float, radius_rx_m: float, turns_tx: float, turns_rx: float, relative_permeability: float = 1.0
) -> float:
    """mu pi N_t N_r a_t^2 a_r^2 / 2, H m^3: the mutual inductance times d^3."""
    mu = MU_0_H_PER_M * relative_permeability
    return mu * math.pi * turns_tx * turns_rx * (radius_tx_m * radius_tx_m) * (radius_rx_m * radius_rx_m) / 2.0


def coil_resistance_ohm(radius_m: ArrayLike, turns: ArrayLike, wire_ohm_per_m: ArrayLike) -> np.ndarray:
    """Resistance of a coil's wire, 2 pi a N R_0, ohm (Sun & Akyildiz 2010)."""
    return 2.0 * math.pi * np.asarray(radius_m, dtype=float) * np.asarray(turns, dtype=float) * np.asarray(
        wire_ohm_per_m, dtype=float
    )


def seawater_field_attenuation(distance_m: ArrayLike, skin_depth: ArrayLike) -> np.ndarray:
    """Power attenuation of the field by the conducting water, exp(-2 d / delta) (Domingo 2012)."""
    return fpmath.exp(-(2.0 * np.asarray(distance_m, dtype=float) / np.asarray(skin_depth, dtype=float)))


def power_transfer_ratio(coupling: ArrayLike) -> np.ndarray:
    """Share of the transmitter's power delivered to the matched load of the receive coil,
    x / (4 + 2 x) for x = omega^2 M^2 / (R_t R_r) (resonant circuits; Sun & Akyildiz 2010's
    transformer model, docs/links.md)."""
    x = np.asarray(coupling, dtype=float)
    return x / (4.0 + 2.0 * x)


def thermal_noise_w(bandwidth_hz: float, noise_figure_db: float, temperature_k: float = NOISE_TEMPERATURE_K) -> float:
    """Receiver noise power k T B F, W (Johnson 1928; Friis 1944 for the noise figure)."""
    return BOLTZMANN_J_PER_K * temperature_k * bandwidth_hz * math.pow(10.0, noise_figure_db / 10.0)


@dataclass(frozen=True)
class MagneticConstants:
    """The constants of one MI link, computed once per scenario."""

    transmit_power_w: float
    """Power the AUV's driver delivers to its coil circuit, W."""
    omega_squared: float
    """omega^2, rad^2/s^2."""
    inductance_coefficient: float
    """Mutual inductance times d^3, H m^3."""
    resistance_product_ohm2: float
    """R_t R_r, ohm^2."""
    skin_depth_m: float
    noise_w: float
    """Receiver noise power k T B F, W."""



def constants(
    *, transmit_power_w: float, freq_khz: float, conductivity_s_per_m: float, radius_tx_m: float, radius_rx_m: float,
    turns_tx: float, turns_rx: float, wire_ohm_per_m: float, bandwidth_hz: float, noise_figure_db: float,
) -> MagneticConstants:
    """The link's constants from its physical parameters."""
    omega = float(angular_frequency_rad_s(freq_khz))
    resistance = float(coil_resistance_ohm(radius_tx_m, turns_tx, wire_ohm_per_m)) * float(
        coil_resistance_ohm(radius_rx_m, turns_rx, wire_ohm_per_m)
    )
    return MagneticConstants(
        transmit_power_w=float(transmit_power_w),
        omega_squared=omega * omega,
        inductance_coefficient=mutual_inductance_coefficient(radius_tx_m, radius_rx_m, turns_tx, turns_rx),
        resistance_product_ohm2=resistance,
        skin_depth_m=float(skin_depth_m(freq_khz, conductivity_s_per_m)),
        noise_w=thermal_noise_w(bandwidth_hz, noise_figure_db),
    )


@dataclass(frozen=True, eq=False)
class MagneticLink:
    """The mean MI link at given distances; arrays have the shape of the distances."""

    received_power_w: np.ndarray
    """Power into the receive coil's matched load, W (for data and for charging)."""
    snr_db: np.ndarray
    """SNR with all the received power on the decoder, dB."""


def link(distance_m: ArrayLike, k: MagneticConstants) -> MagneticLink:
    """Received power and SNR at ``distance_m`` (clamped to 1 m)."""
    d = np.maximum(np.asarray(distance_m, dtype=float), MIN_DISTANCE_M)
    m = k.inductance_coefficient / (d * d * d)
    coupling = k.omega_squared * (m * m) * fpmath.exp(-(2.0 * d / k.skin_depth_m)) / k.resistance_product_ohm2
    p_r = k.transmit_power_w * (coupling / (4.0 + 2.0 * coupling))
    return MagneticLink(p_r, 10.0 * fpmath.log10(p_r / k.noise_w))
