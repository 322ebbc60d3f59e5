import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from swiptopt import acoustics as ac

# Reference values worked out by hand from the published formulas (paper eqs. 4-8).
THORP_REFERENCE = {1.0: 0.0690, 10.0: 1.1870, 24.0: 5.6912, 50.0: 17.4671, 100.0: 34.0687}
NOISE_REFERENCE = [
    # (f kHz, shipping, wind m/s), (N_t, N_s, N_w, N_th), total
    ((1.0, 0.5, 0.0), (17.0, 39.2298, 44.1549, -15.0), 45.3726),
    ((10.0, 0.5, 5.0), (-13.0, 5.9219, 46.0892, 5.0), 46.0899),
    ((100.0, 1.0, 10.0), (-43.0, -18.0078, 33.6477, 25.0), 34.2036),
    ((24.0, 0.0, 10.0), (-24.4063, -16.9597, 45.8257, 12.6042), 45.8278),
]


@pytest.mark.parametrize("freq, expected", THORP_REFERENCE.items())
def test_thorp_reference_values(freq, expected):
    assert ac.thorp_absorption_db_per_km(freq) == pytest.approx(expected, abs=1e-4)


def test_thorp_is_vectorised():
    out = ac.thorp_absorption_db_per_km(np.array(list(THORP_REFERENCE)))
    assert out.shape == (5,)
    np.testing.assert_allclose(out, list(THORP_REFERENCE.values()), atol=1e-4)


@pytest.mark.parametrize("args, parts, total", NOISE_REFERENCE)
def test_noise_reference_values(args, parts, total):
    f, s, w = args
    got = (
        ac.turbulence_noise_psd_db(f),
        ac.shipping_noise_psd_db(f, s),
        ac.wind_noise_psd_db(f, w),
        ac.thermal_noise_psd_db(f),
    )
    np.testing.assert_allclose(got, parts, atol=1e-4)
    assert ac.noise_psd_db(f, shipping=s, wind_mps=w) == pytest.approx(total, abs=1e-4)


def test_spec_example_noise():
    assert ac.noise_psd_db(24.0, shipping=0.0, wind_mps=10.0) == pytest.approx(45.83, abs=0.01)


def test_transmission_loss_reference():
    # 1.5 * 10 * log10(1000) + 1 km * 5.6912 dB/km
    assert ac.transmission_loss_db(1000.0, 24.0, 1.5) == pytest.approx(45.0 + 5.6912, abs=1e-4)
    # spherical spreading at 100 m, 10 kHz: 40 dB + 0.1 km * 1.1870
    assert ac.transmission_loss_db(100.0, 10.0, 2.0) == pytest.approx(40.1187, abs=1e-4)
    # below 1 m the distance is clamped: only the absorption over 1 m is left
    assert ac.transmission_loss_db(0.2, 24.0) == pytest.approx(ac.transmission_loss_db(1.0, 24.0))


def test_source_level_snr_and_capacity():
    assert ac.source_level_db(1000.0, 0.5) == pytest.approx(170.8 + 30.0 - 10 * math.log10(2), abs=1e-9)
    assert ac.source_level_db(1.0, 1.0, directivity_db=3.0) == pytest.approx(173.8)
    assert ac.snr_db(200.0, 50.0, 80.0, 2.0) == pytest.approx(72.0)
    assert ac.capacity_bps(4000.0, 0.0) == pytest.approx(4000.0)  # log2(1 + 1) = 1
    assert ac.capacity_bps(1000.0, 10 * math.log10(7.0)) == pytest.approx(3000.0)


def test_noise_level_flat_and_integrated():
    flat = ac.noise_level_db(24.0, 4000.0, 0.0, 10.0)
    assert flat == pytest.approx(45.8278 + 10 * math.log10(4000.0), abs=1e-4)
    # a narrow band: integrating a nearly constant PSD gives the flat value
    narrow = ac.noise_level_db(24.0, 10.0, 0.0, 10.0, integrate=True)
    assert narrow == pytest.approx(ac.noise_level_db(24.0, 10.0, 0.0, 10.0), abs=1e-5)
    # a wide band at low frequency: the PSD falls steeply, so the low edge dominates and
    # the integral exceeds the centre-frequency approximation
    wide = ac.noise_level_db(2.0, 3000.0, 0.5, 5.0, integrate=True)
    assert wide > ac.noise_level_db(2.0, 3000.0, 0.5, 5.0) + 0.1


def _noise_power_by_quadrature(f_min_khz, f_max_khz, shipping, wind_mps):
    # an independent reference: Gauss-Legendre over the band, in uPa^2
    nodes, weights = np.polynomial.legendre.leggauss(64)
    f = 0.5 * (f_max_khz - f_min_khz) * nodes + 0.5 * (f_max_khz + f_min_khz)
    psd = 10.0 ** (ac.noise_psd_db(f, shipping, wind_mps) / 10.0)
    return 10 * math.log10(0.5 * (f_max_khz - f_min_khz) * 1000.0 * float(weights @ psd))


def test_integrated_noise_covers_the_band_edges_not_the_centre():
    # the model integrates over [f_min, f_max]; with the carrier off the band's centre that
    # is not [fc - B/2, fc + B/2]
    band = (3.0, 9.0)
    integrated = ac.noise_level_db(4.0, 6000.0, 0.5, 5.0, integrate=True, band_khz=band)
    assert integrated == pytest.approx(_noise_power_by_quadrature(*band, 0.5, 5.0), abs=1e-3)
    centred = ac.noise_level_db(4.0, 6000.0, 0.5, 5.0, integrate=True)  # [1, 7] kHz: noisier
    assert abs(integrated - centred) > 1.0


def test_scenario_noise_integrates_over_its_band():
    from swiptopt import Scenario
    from swiptopt.link import noise_level_db

    s = Scenario.preset("paper", noise_integrated=True, frequency_khz=23.0)  # band 22-26 kHz
    assert noise_level_db(s) == pytest.approx(_noise_power_by_quadrature(22.0, 26.0, 0.0, 10.0), abs=1e-3)


@pytest.mark.parametrize("bad", [0.0, -1.0, np.nan])
def test_non_positive_frequency_rejected(bad):
    with pytest.raises(ValueError, match="freq_khz"):
        ac.thorp_absorption_db_per_km(bad)


distances = st.floats(1.0, 1e5, allow_nan=False)
freqs = st.floats(0.1, 1000.0, allow_nan=False)


@given(d1=distances, d2=distances, f=freqs, k=st.floats(1.0, 2.0))
def test_loss_grows_with_distance(d1, d2, f, k):
    lo, hi = sorted((d1, d2))
    assert ac.transmission_loss_db(hi, f, k) >= ac.transmission_loss_db(lo, f, k)
    if hi > lo * (1 + 1e-9):
        assert ac.transmission_loss_db(hi, f, k) > ac.transmission_loss_db(lo, f, k)


@given(f1=freqs, f2=freqs)
def test_absorption_grows_with_frequency(f1, f2):
    lo, hi = sorted((f1, f2))
    if hi > lo * (1 + 1e-9):
        assert ac.thorp_absorption_db_per_km(hi) > ac.thorp_absorption_db_per_km(lo)


@given(d=st.floats(10.0, 1e5), k1=st.floats(1.0, 2.0), k2=st.floats(1.0, 2.0))
def test_optimal_frequency_independent_of_spreading(d, k1, k2):
    f1 = ac.optimal_frequency_khz(d, spreading_k=k1, wind_mps=5.0)
    f2 = ac.optimal_frequency_khz(d, spreading_k=k2, wind_mps=5.0)
    assert f1 == pytest.approx(f2, rel=1e-5)


@given(d1=st.floats(10.0, 1e5), d2=st.floats(10.0, 1e5))
def test_optimal_frequency_falls_with_distance(d1, d2):
    lo, hi = sorted((d1, d2))
    assert ac.optimal_frequency_khz(hi) <= ac.optimal_frequency_khz(lo) * (1 + 1e-6)


def test_optimal_frequency_is_the_minimum_of_the_an_product():
    d = np.array([50.0, 1000.0, 10_000.0, 100_000.0])
    f_opt = ac.optimal_frequency_khz(d, shipping=0.5, wind_mps=0.0)
    assert f_opt.shape == d.shape
    dense = np.geomspace(0.1, 1000.0, 200_001)
    for di, fi in zip(d, f_opt):
        brute = dense[np.argmin(ac.an_product_db(di, dense, 1.5, 0.5, 0.0))]
        assert fi == pytest.approx(brute, rel=1e-3)
    # strictly decreasing over four decades of distance
    assert np.all(np.diff(f_opt) < 0)
