"""Underwater optical wireless communication (UWOC): a line-of-sight light beam to a
photodiode and a photovoltaic cell at the node.

Every function is a pure, vectorised numpy function over distances (any shape); logarithms
and exponentials go through :mod:`swiptopt.fpmath` (the C library's, element by element: the
same bits on every CPU). SI units unless the name says otherwise. :func:`swiptopt.link.link_budget`
calls :func:`link` for scenarios with ``technology = "optical"``.

The link (docs/links.md has every parameter with its source):

- Beer–Lambert attenuation along the path, exp(-c d), with the beam attenuation coefficient
  c of the water type near 530 nm (Petzold 1972, as tabulated by Mobley 1994 and used by
  Gabriel et al. 2013 and Zeng et al. 2017). Counting every scattered photon as lost is the
  conservative line-of-sight model (Zeng et al. 2017).
- Geometric loss of a beam of divergence half-angle theta spread uniformly over the solid
  angle 2 pi (1 - cos theta) onto a receiver aperture A at slant distance d:
  A / (2 pi (1 - cos theta) d^2), capped at 1 (Arnon 2010; Zeng et al. 2017). The node
  must lie inside the beam (the coverage cone); the receiver's effective aperture is taken
  as A for every direction inside the beam (a domed or lens receiver), so the link depends
  on the distance alone.
- Photodiode receiver noise: shot noise of the signal, background-light and dark currents,
  2 q (I_s + I_bg + I_d) B, and thermal noise of the load, 4 k T B / R_L; electrical SNR
  I_s^2 / sigma^2 with I_s = R P_r (Zeng et al. 2017; Giles & Bankman 2005).
- Harvesting: the node's photovoltaic cell turns the optical power on the aperture into
  electrical power at ``pv_efficiency`` (Wang et al. 2015, solar-panel SLIPT receivers).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from swiptopt import fpmath

#: Beam attenuation coefficients c = a + b of the water types near 530 nm, 1/m (Petzold
#: 1972; Mobley 1994; the values UWOC studies use, Gabriel et al. 2013, Zeng et al. 2017).
WATER_ATTENUATION_PER_M = {
    "pure_sea": 0.056,
    "clear_ocean": 0.151,
    "coastal": 0.398,
    "turbid_harbour": 2.17,
}
WATER_TYPES = tuple(WATER_ATTENUATION_PER_M)

#: Elementary charge, C (SI 2019, exact).
ELEMENTARY_CHARGE_C = 1.602176634e-19
#: Boltzmann constant, J/K (SI 2019, exact).
BOLTZMANN_J_PER_K = 1.380649e-23
#: Receiver noise temperature, K: the standard reference temperature T0 = 290 K (IEEE).
NOISE_TEMPERATURE_K = 290.0
#: Distances are clamped to at least this, m (the acoustic link's reference distance, so
#: every technology's budget starts at the same distance).
MIN_DISTANCE_M = 1.0


def beer_lambert_transmittance(distance_m: ArrayLike, attenuation_per_m: float) -> np.ndarray:
    """Share of the light left after ``distance_m`` of water, exp(-c d) (Beer–Lambert;
    Mobley 1994; Zeng et al. 2017). ``attenuation_per_m`` is c, 1/m."""
    return fpmath.exp(-(attenuation_per_m * np.asarray(distance_m, dtype=float)))


def beam_solid_angle_sr(half_angle_deg: float) -> float:
    """Solid angle of a cone of half-angle ``half_angle_deg``, 2 pi (1 - cos theta), sr."""
    return 2.0 * math.pi * (1.0 - math.cos(math.radians(half_angle_deg)))


def geometric_gain(distance_m: ArrayLike, aperture_m2: float, half_angle_deg: float) -> np.ndarray:
    """Share of a uniform beam of divergence half-angle ``half_angle_deg`` that falls on an
    aperture of ``aperture_m2`` at ``distance_m``: min(1, A / (Omega d^2)) with
    Omega = 2 pi (1 - cos theta) (Arnon 2010; Zeng et al. 2017)."""
    d = np.asarray(distance_m, dtype=float)
    return np.minimum(1.0, (aperture_m2 / beam_solid_angle_sr(half_angle_deg)) / (d * d))


def received_power_w(
    transmit_power_w: float, distance_m: ArrayLike, attenuation_per_m: float, aperture_m2: float,
    half_angle_deg: float,
) -> np.ndarray:
    """Optical power on the receiver aperture, P_r = P_t exp(-c d) G(d), W (Arnon 2010;
    Zeng et al. 2017); ``distance_m`` clamped to at least :data:`MIN_DISTANCE_M`."""
    d = np.maximum(np.asarray(distance_m, dtype=float), MIN_DISTANCE_M)
    return transmit_power_w * beer_lambert_transmittance(d, attenuation_per_m) * geometric_gain(
        d, aperture_m2, half_angle_deg
    )


def photocurrent_a(optical_power_w: ArrayLike, responsivity_a_per_w: float) -> np.ndarray:
    """Photodiode current I = R P, A."""
    return responsivity_a_per_w * np.asarray(optical_power_w, dtype=float)


def shot_noise_coefficient(bandwidth_hz: float) -> float:
    """2 q B, A^2 per A of current: shot noise variance = 2 q I B (Zeng et al. 2017)."""
    return 2.0 * ELEMENTARY_CHARGE_C * bandwidth_hz


def thermal_noise_variance_a2(
    bandwidth_hz: float, load_ohm: float, temperature_k: float = NOISE_TEMPERATURE_K
) -> float:
    """Thermal (Johnson) noise current variance of the load, 4 k T B / R_L, A^2 (Johnson 1928;
    Zeng et al. 2017)."""
    return 4.0 * BOLTZMANN_J_PER_K * temperature_k * bandwidth_hz / load_ohm


def noise_variance_a2(
    signal_a: ArrayLike, standing_current_a: float, bandwidth_hz: float, load_ohm: float,
    temperature_k: float = NOISE_TEMPERATURE_K,
) -> np.ndarray:
    """Receiver noise variance 2 q (I_s + I_bg + I_d) B + 4 k T B / R_L, A^2, with
    ``standing_current_a`` = I_bg + I_d (Zeng et al. 2017)."""
    shot = shot_noise_coefficient(bandwidth_hz)
    return shot * (np.asarray(signal_a, dtype=float) + standing_current_a) + thermal_noise_variance_a2(
        bandwidth_hz, load_ohm, temperature_k
    )


def snr_linear(signal_a: ArrayLike, noise_variance: ArrayLike) -> np.ndarray:
    """Electrical SNR of an intensity-modulated link, I_s^2 / sigma^2."""
    i = np.asarray(signal_a, dtype=float)
    return i * i / np.asarray(noise_variance, dtype=float)


@dataclass(frozen=True)
class OpticalConstants:
    """The constants of one optical link, computed once per scenario."""

    transmit_power_w: float
    """Optical power leaving the AUV's source, W."""
    attenuation_per_m: float
    """Beam attenuation coefficient c, 1/m."""
    aperture_per_sr_m2: float
    """A / Omega: receiver aperture over the beam's solid angle, m^2/sr."""
    responsivity_a_per_w: float
    shot_coefficient: float
    """2 q B, A^2/A."""
    standing_current_a: float
    """Background-light plus dark current, A."""
    thermal_variance_a2: float
    """4 k T B / R_L, A^2."""
    pv_efficiency: float
    """Photovoltaic conversion efficiency at the node."""



def constants(
    *, transmit_power_w: float, attenuation_per_m: float, aperture_m2: float, half_angle_deg: float,
    responsivity_a_per_w: float, dark_current_a: float, background_irradiance_w_m2: float, bandwidth_hz: float,
    load_ohm: float, pv_efficiency: float,
) -> OpticalConstants:
    """The link's constants from its physical parameters (background current R E_bg A)."""
    background_a = float(photocurrent_a(background_irradiance_w_m2 * aperture_m2, responsivity_a_per_w))
    return OpticalConstants(
        transmit_power_w=float(transmit_power_w),
        attenuation_per_m=float(attenuation_per_m),
        aperture_per_sr_m2=aperture_m2 / beam_solid_angle_sr(half_angle_deg),
        responsivity_a_per_w=float(responsivity_a_per_w),
        shot_coefficient=shot_noise_coefficient(bandwidth_hz),
        standing_current_a=background_a + dark_current_a,
        thermal_variance_a2=thermal_noise_variance_a2(bandwidth_hz, load_ohm),
        pv_efficiency=float(pv_efficiency),
    )


@dataclass(frozen=True, eq=False)
class OpticalLink:
    """The mean optical link at given distances; arrays have the shape of the distances."""

    received_power_w: np.ndarray
    """Optical power on the aperture, W."""
    snr_db: np.ndarray
    """Electrical SNR with all the light on the photodiode, dB."""
    available_power_w: np.ndarray
    """Electrical power of the photovoltaic cell with all the light on it, W."""


def link(distance_m: ArrayLike, k: OpticalConstants) -> OpticalLink:
    """Received power, SNR and harvestable power at ``distance_m`` (clamped to 1 m)."""
    d = np.maximum(np.asarray(distance_m, dtype=float), MIN_DISTANCE_M)
    transmittance = fpmath.exp(-(k.attenuation_per_m * d))
    gain = np.minimum(1.0, k.aperture_per_sr_m2 / (d * d))
    p_r = k.transmit_power_w * transmittance * gain
    signal = k.responsivity_a_per_w * p_r
    variance = k.shot_coefficient * (signal + k.standing_current_a) + k.thermal_variance_a2
    snr = signal * signal / variance
    return OpticalLink(p_r, 10.0 * fpmath.log10(snr), k.pv_efficiency * p_r)
