import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from swiptopt import harvesting as hv


def test_induced_voltage_and_available_power_reference():
    # RL + rho = 0 dB re 1 V: 1 V rms; into a matched 100 ohm load: 1 / 400 W
    assert hv.induced_voltage_v(170.0, -170.0) == pytest.approx(1.0)
    assert hv.induced_voltage_v(190.0, -170.0) == pytest.approx(10.0)
    assert hv.available_power_w(170.0, -170.0, 100.0) == pytest.approx(2.5e-3)
    assert hv.available_power_w(170.0, -170.0, 100.0, n_elements=4) == pytest.approx(1e-2)


def test_linear_harvester_reference():
    assert hv.harvested_power_w(0.04, 0.25, 0.5) == pytest.approx(0.5 * 0.75 * 0.04)
    assert hv.harvested_power_w(0.04, 1.0, 0.5) == 0.0
    assert hv.harvested_power_w(0.04, 0.0, 1.0) == pytest.approx(0.04)


def test_logistic_harvester_shape():
    m, a, b = 0.024, 150.0, 0.014
    omega = 1.0 / (1.0 + np.exp(a * b))
    assert hv.logistic_harvest_w(0.0) == pytest.approx(0.0, abs=1e-15)
    assert hv.logistic_harvest_w(b) == pytest.approx(m * (0.5 - omega) / (1 - omega))
    assert hv.logistic_harvest_w(10.0) == pytest.approx(m, rel=1e-9)  # saturates at M
    p = np.linspace(0, 0.2, 50)
    assert np.all(np.diff(hv.logistic_harvest_w(p)) > 0)
    # the model harvests from (1 - alpha) P_av
    assert hv.harvested_power_w(0.05, 0.6, model="logistic") == pytest.approx(hv.logistic_harvest_w(0.02))


def test_information_snr_is_split():
    assert hv.information_snr_linear(1000.0, 0.3) == pytest.approx(300.0)


def test_bad_split_and_model_rejected():
    with pytest.raises(ValueError, match="split_ratio"):
        hv.harvested_power_w(0.1, 1.5)
    with pytest.raises(ValueError, match="model"):
        hv.harvested_power_w(0.1, 0.5, model="quadratic")  # type: ignore[arg-type]


power = st.floats(0.0, 10.0, allow_nan=False)
split = st.floats(0.0, 1.0)


@given(p_av=power, alpha=split, eta=split, model=st.sampled_from(["linear", "logistic"]),
       m=st.floats(1e-4, 5.0), a=st.floats(1.0, 1e4), b=st.floats(0.0, 1.0))
def test_harvested_never_exceeds_available(p_av, alpha, eta, model, m, a, b):
    out = hv.harvested_power_w(p_av, alpha, eta, model, logistic_max_w=m, logistic_a_per_w=a, logistic_b_w=b)
    assert 0.0 <= out <= p_av * (1 + 1e-12)
    assert out <= (1 - alpha) * p_av * (1 + 1e-12) + 1e-300


@given(p_av=power, model=st.sampled_from(["linear", "logistic"]))
def test_nothing_harvested_at_split_one(p_av, model):
    assert hv.harvested_power_w(p_av, 1.0, 0.5, model) == 0.0


@pytest.mark.parametrize("logistic", [False, True])
def test_vectorised_harvester_matches_the_scalar_kernel_function(logistic):
    """The array harvester (scenario tables, bounds, the link budget) and the scalar one
    (the simulator kernel, compiled or not) give the same watts on random inputs, edge
    values included, bit for bit: both call the C library's exp (swiptopt.fpmath), on
    every CPU."""
    rng = np.random.default_rng(12 + logistic)
    n = 20_000
    p_in = np.concatenate([10.0 ** rng.uniform(-15, 1, n), [0.0, -0.0, 1e-300, 0.014, 5.0]])
    eta = rng.uniform(0.0, 1.0, p_in.size)
    m = rng.uniform(1e-4, 5.0, p_in.size)
    a = 10.0 ** rng.uniform(0, 4, p_in.size)
    b = rng.uniform(0.0, 1.0, p_in.size)
    vector = hv.harvest_from_input_array_w(p_in, logistic, eta, m, a, b)
    scalar = np.array([hv.harvest_from_input_w(*args) for args in zip(p_in, [logistic] * p_in.size, eta, m, a, b)])
    assert vector.shape == scalar.shape and vector.dtype == np.float64
    np.testing.assert_array_equal(vector, scalar)
    assert np.all((vector >= 0.0) & (vector <= p_in + 0.0))
    # one row broadcast against scalars, as the tables call it
    row = hv.harvest_from_input_array_w(p_in[:100], logistic, 0.5, 0.024, 150.0, 0.014)
    np.testing.assert_array_equal(
        row, [hv.harvest_from_input_w(p, logistic, 0.5, 0.024, 150.0, 0.014) for p in p_in[:100]]
    )
