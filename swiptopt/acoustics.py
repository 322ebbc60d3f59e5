"""The underwater acoustic channel: absorption, spreading, ambient noise, SNR and rate.

Every function is a pure, vectorised numpy function: scalars and arrays are accepted and
broadcast against each other; a scalar in gives a numpy scalar (0-d) out. Logarithms and
powers of ten go through :mod:`swiptopt.fpmath` (the C library's functions), so every
quantity has the same bits on every CPU and in the kernel. Frequencies are
in kHz because the empirical formulas were fitted in kHz; everything else is SI unless the
name says otherwise (``_db``, ``_khz``, ``_km``).

Sources: Thorp (1967) for absorption; Stojanovic (2007), "On the relationship between
capacity and distance in an underwater acoustic communication channel", for the spreading
law, the four-part noise model and the AN product; Urick, *Principles of Underwater Sound*,
for the source level of a projector. Paper equations refer to Omeke et al.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from swiptopt import fpmath

#: Range in which Thorp's absorption formula is used here, kHz.
THORP_VALID_KHZ = (0.1, 1000.0)

#: 10 log10 of the acoustic intensity of 1 W radiated omnidirectionally, measured at 1 m,
#: in dB re 1 uPa (Urick): SL = 170.8 + 10 log10(P_acoustic).
SOURCE_LEVEL_PER_WATT_DB = 170.8


def _positive(name: str, value: ArrayLike) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if np.any(~(arr > 0)):
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return arr


def thorp_absorption_db_per_km(freq_khz: ArrayLike) -> np.ndarray:
    """Thorp's absorption coefficient a(f) in dB/km (paper eq. 4; Thorp 1967).

    ``freq_khz``: any shape, > 0. Example: a(24 kHz) = 5.6912 dB/km.
    """
    f2 = _positive("freq_khz", freq_khz) ** 2
    return 0.11 * f2 / (1.0 + f2) + 44.0 * f2 / (4100.0 + f2) + 2.75e-4 * f2 + 0.003


def transmission_loss_db(
    distance_m: ArrayLike, freq_khz: ArrayLike, spreading_k: ArrayLike = 1.5
) -> np.ndarray:
    """Transmission loss TL = k 10 log10(r) + (r / 1000) a(f), dB (paper eq. 3; Stojanovic 2007).

    ``distance_m`` is clamped to at least 1 m (the reference distance of the source level);
    ``spreading_k`` is 1 for cylindrical, 2 for spherical spreading, 1.5 the practical value.
    """
    r = np.maximum(np.asarray(distance_m, dtype=float), 1.0)
    k = np.asarray(spreading_k, dtype=float)
    return k * 10.0 * fpmath.log10(r) + (r / 1000.0) * thorp_absorption_db_per_km(freq_khz)


def turbulence_noise_psd_db(freq_khz: ArrayLike) -> np.ndarray:
    """Turbulence noise N_t = 17 - 30 log10 f, dB re 1 uPa^2/Hz (paper eq. 5; Stojanovic 2007)."""
    return 17.0 - 30.0 * fpmath.log10(_positive("freq_khz", freq_khz))


def shipping_noise_psd_db(freq_khz: ArrayLike, shipping: ArrayLike) -> np.ndarray:
    """Shipping noise N_s = 30 + 20 s + 26 log10 f - 60 log10(f + 0.03) (paper eq. 6).

    ``shipping`` is the shipping activity factor s in [0, 1].
    """
    f = _positive("freq_khz", freq_khz)
    s = np.asarray(shipping, dtype=float)
    return 30.0 + 20.0 * s + 26.0 * fpmath.log10(f) - 60.0 * fpmath.log10(f + 0.03)


def wind_noise_psd_db(freq_khz: ArrayLike, wind_mps: ArrayLike) -> np.ndarray:
    """Wind-driven surface noise N_w = 50 + 7.5 sqrt(w) + 20 log10 f - 40 log10(f + 0.4) (paper eq. 7)."""
    f = _positive("freq_khz", freq_khz)
    w = np.asarray(wind_mps, dtype=float)
    return 50.0 + 7.5 * np.sqrt(w) + 20.0 * fpmath.log10(f) - 40.0 * fpmath.log10(f + 0.4)


def thermal_noise_psd_db(freq_khz: ArrayLike) -> np.ndarray:
    """Thermal noise N_th = -15 + 20 log10 f, dB re 1 uPa^2/Hz (paper eq. 8)."""
    return -15.0 + 20.0 * fpmath.log10(_positive("freq_khz", freq_khz))


def noise_psd_db(
    freq_khz: ArrayLike, shipping: ArrayLike = 0.0, wind_mps: ArrayLike = 0.0
) -> np.ndarray:
    """Total ambient noise PSD, the power sum of paper eqs. 5-8, dB re 1 uPa^2/Hz.

    Example: N(24 kHz, s = 0, w = 10 m/s) = 45.83 dB.
    """
    parts = (
        turbulence_noise_psd_db(freq_khz),
        shipping_noise_psd_db(freq_khz, shipping),
        wind_noise_psd_db(freq_khz, wind_mps),
        thermal_noise_psd_db(freq_khz),
    )
    return 10.0 * fpmath.log10(sum(fpmath.pow10(p / 10.0) for p in parts))


def noise_level_db(
    freq_khz: ArrayLike,
    bandwidth_hz: ArrayLike,
    shipping: ArrayLike = 0.0,
    wind_mps: ArrayLike = 0.0,
    *,
    integrate: bool = False,
    band_khz: tuple[ArrayLike, ArrayLike] | None = None,
    n_points: int = 201,
) -> np.ndarray:
    """Noise level in the receiver band, dB re 1 uPa (the N_0(f) B of paper eqs. 13-14).

    By default the flat-band approximation ``NL = N(fc) + 10 log10(B)``, the paper's noise
    power ``N_0(f) B``. With ``integrate=True`` the PSD is integrated (trapezoid rule,
    ``n_points`` samples) over the band ``band_khz = (f_min, f_max)``, which matters when
    the band is wide compared with ``fc`` or the carrier is off the band's centre; without
    ``band_khz`` the band is taken as ``[fc - B/2, fc + B/2]``.
    """
    fc = _positive("freq_khz", freq_khz)
    bw = _positive("bandwidth_hz", bandwidth_hz)
    if not integrate:
        return noise_psd_db(fc, shipping, wind_mps) + 10.0 * fpmath.log10(bw)
    if band_khz is None:
        low, high = fc - bw / 2000.0, fc + bw / 2000.0
    else:
        low, high = (np.asarray(edge, dtype=float) for edge in band_khz)
    low, high, s, w = np.broadcast_arrays(low, high, np.asarray(shipping, float), np.asarray(wind_mps, float))
    if np.any(low <= 0) or np.any(high <= low):
        raise ValueError(f"the band must satisfy 0 < f_min < f_max, got [{low}, {high}] kHz")
    u = np.linspace(0.0, 1.0, n_points)
    f = low[..., None] + (high - low)[..., None] * u  # (..., n_points), kHz
    psd_lin = fpmath.pow10(noise_psd_db(f, s[..., None], w[..., None]) / 10.0)
    power = np.trapezoid(psd_lin, f * 1000.0, axis=-1)  # uPa^2
    return 10.0 * fpmath.log10(power)


def source_level_db(
    electrical_power_w: ArrayLike, efficiency: ArrayLike, directivity_db: ArrayLike = 0.0
) -> np.ndarray:
    """Source level of the projector, SL = 170.8 + 10 log10(P eta) + DI, dB re 1 uPa @ 1 m.

    ``efficiency`` is the electro-acoustic efficiency eta_ea in (0, 1]; ``directivity_db``
    the transmit directivity index (paper eq. 2; Urick).
    """
    p = _positive("electrical_power_w", electrical_power_w)
    eta = _positive("efficiency", efficiency)
    return (
        SOURCE_LEVEL_PER_WATT_DB
        + 10.0 * fpmath.log10(p)
        + 10.0 * fpmath.log10(eta)
        + np.asarray(directivity_db, dtype=float)
    )


def snr_db(
    source_level_db: ArrayLike,
    transmission_loss_db: ArrayLike,
    noise_level_db: ArrayLike,
    directivity_rx_db: ArrayLike = 0.0,
) -> np.ndarray:
    """Passive sonar equation: SNR = SL - TL - NL + DI_rx, dB (paper eq. 1).

    The paper adds the directivity index twice; here the projector's is in SL and the
    receiver's is ``directivity_rx_db``.
    """
    return (
        np.asarray(source_level_db, float)
        - np.asarray(transmission_loss_db, float)
        - np.asarray(noise_level_db, float)
        + np.asarray(directivity_rx_db, float)
    )


def db_to_linear(value_db: ArrayLike) -> np.ndarray:
    """Power ratio from decibels."""
    return fpmath.pow10(np.asarray(value_db, dtype=float) / 10.0)


def capacity_bps(bandwidth_hz: ArrayLike, snr_db: ArrayLike) -> np.ndarray:
    """Shannon rate R = B log2(1 + SNR_lin), bit/s (paper eq. 15)."""
    return shannon_rate_bps(np.asarray(bandwidth_hz, dtype=float), db_to_linear(snr_db))


def shannon_rate_bps(bandwidth_hz: ArrayLike, snr_linear: ArrayLike) -> np.ndarray:
    """B log2(1 + SNR) on a linear SNR, bit/s (arrays; :func:`link_rate_bps` is one link)."""
    return np.asarray(bandwidth_hz, dtype=float) * fpmath.log2(1.0 + np.asarray(snr_linear, dtype=float))


def link_rate_bps(bandwidth_hz, snr_linear):  # type: ignore[no-untyped-def]
    """:func:`shannon_rate_bps` of one link (floats), with the same C library ``log2``; the
    kernel calls it, in Python or compiled by numba."""
    return bandwidth_hz * math.log2(1.0 + snr_linear)


def an_product_db(
    distance_m: ArrayLike,
    freq_khz: ArrayLike,
    spreading_k: ArrayLike = 1.5,
    shipping: ArrayLike = 0.0,
    wind_mps: ArrayLike = 0.0,
) -> np.ndarray:
    """Stojanovic's AN product in dB: TL(r, f) + N(f). The narrowband SNR is SL - AN."""
    return transmission_loss_db(distance_m, freq_khz, spreading_k) + noise_psd_db(
        freq_khz, shipping, wind_mps
    )


def optimal_frequency_khz(
    distance_m: ArrayLike,
    spreading_k: float = 1.5,
    shipping: float = 0.0,
    wind_mps: float = 0.0,
    *,
    freq_range_khz: tuple[float, float] = THORP_VALID_KHZ,
    grid_points: int = 2000,
    tol_khz: float = 1e-9,
) -> np.ndarray:
    """Frequency maximising 1 / (A(l, f) N(f)) at distance l, kHz (Stojanovic 2007).

    Minimises the AN product over ``freq_range_khz``: a log-spaced grid brackets the
    minimum, then golden-section search refines it inside the bracket. The spreading term
    does not depend on f, so the optimum does not depend on ``spreading_k``; it falls with
    distance because absorption grows with both. ``distance_m``: any shape; the result has
    the same shape.
    """
    d = np.atleast_1d(_positive("distance_m", distance_m))
    flat = d.reshape(-1, 1)
    grid = np.geomspace(*freq_range_khz, grid_points)

    def cost(f: np.ndarray) -> np.ndarray:
        return an_product_db(flat, f, spreading_k, shipping, wind_mps)

    values = cost(np.broadcast_to(grid, (flat.shape[0], grid_points)))
    best = np.argmin(values, axis=1)
    lo = grid[np.maximum(best - 1, 0)]
    hi = grid[np.minimum(best + 1, grid_points - 1)]
    inv_phi = (np.sqrt(5.0) - 1.0) / 2.0
    while np.any(hi - lo > tol_khz * np.maximum(1.0, hi)):
        a = hi - inv_phi * (hi - lo)
        b = lo + inv_phi * (hi - lo)
        left_better = cost(a[:, None])[:, 0] < cost(b[:, None])[:, 0]
        hi = np.where(left_better, b, hi)
        lo = np.where(left_better, lo, a)
    return ((lo + hi) / 2.0).reshape(np.shape(distance_m))
