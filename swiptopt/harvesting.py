"""SWIPT at the sensor node: induced voltage, available power, power splitting, harvesting.

Paper eqs. 10-12; docs/design.md, 'SWIPT at the node (Section II-C)'. The paper writes the SNR
where the received level belongs in the induced-voltage formula; the derivation it cites
(Bereketli & Bilgen 2012) uses the received level RL = SL - TL, and so do we.

Power splitting: a fraction ``split_ratio`` (alpha) of the received signal goes to the
information decoder, the rest (1 - alpha) to the harvester. Noise is not split, so the
decoder sees alpha times the SNR.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from swiptopt import fpmath

HarvesterModel = Literal["linear", "logistic"]

#: Logistic harvester defaults (Boshkovska et al. 2015, fitted to a measured harvesting
#: circuit): saturation power M in W, steepness a in 1/W, turning point b in W. They are a
#: documented stand-in; an acoustic harvester should be fitted to its own measurements.
LOGISTIC_MAX_W = 0.024
LOGISTIC_A_PER_W = 150.0
LOGISTIC_B_W = 0.014


def _split(split_ratio: ArrayLike) -> np.ndarray:
    alpha = np.asarray(split_ratio, dtype=float)
    if np.any((alpha < 0) | (alpha > 1)) or np.any(np.isnan(alpha)):
        raise ValueError(f"split_ratio must lie in [0, 1], got {split_ratio!r}")
    return alpha


def induced_voltage_v(received_level_db: ArrayLike, sensitivity_db: ArrayLike) -> np.ndarray:
    """RMS open-circuit voltage of the node's hydrophone, V = 10^((RL + rho) / 20) (paper eq. 10).

    ``received_level_db`` in dB re 1 uPa; ``sensitivity_db`` (rho) in dB re 1 V/uPa.
    """
    return fpmath.pow10((np.asarray(received_level_db, float) + np.asarray(sensitivity_db, float)) / 20.0)


def available_power_w(
    received_level_db: ArrayLike,
    sensitivity_db: ArrayLike,
    load_ohm: ArrayLike,
    n_elements: ArrayLike = 1,
) -> np.ndarray:
    """Electrical power available to a matched load, P_av = n V^2 / (4 R_p), W (paper eq. 11)."""
    load = np.asarray(load_ohm, dtype=float)
    if np.any(~(load > 0)):
        raise ValueError(f"load_ohm must be > 0, got {load_ohm!r}")
    v = induced_voltage_v(received_level_db, sensitivity_db)
    return np.asarray(n_elements, dtype=float) * v**2 / (4.0 * load)


def information_snr_linear(snr_linear: ArrayLike, split_ratio: ArrayLike) -> np.ndarray:
    """SNR at the information decoder after splitting: alpha * SNR (noise is not split)."""
    return _split(split_ratio) * np.asarray(snr_linear, dtype=float)


def logistic_harvest_w(
    input_power_w: ArrayLike,
    max_w: float = LOGISTIC_MAX_W,
    a_per_w: float = LOGISTIC_A_PER_W,
    b_w: float = LOGISTIC_B_W,
) -> np.ndarray:
    """Boshkovska et al. (2015) non-linear harvester, zero at zero input, saturating at M.

    P_h = (M / (1 + exp(-a (P_in - b))) - M Omega) / (1 - Omega), Omega = 1 / (1 + exp(a b)).
    """
    return _harvest_array(np.asarray(input_power_w, dtype=float), True, 1.0, max_w, a_per_w, b_w)


def _sigmoid(x: float) -> float:
    # 1 / (1 + exp(-x)) without overflow for large |x|
    if x >= 0.0:
        return 1.0 / (1.0 + math.exp(-x))
    e = math.exp(x)
    return e / (1.0 + e)


def harvest_from_input_w(p_in, logistic, efficiency, max_w, a_per_w, b_w):  # type: ignore[no-untyped-def]
    """The harvester curve on the scalar power sent to it, W, without argument checks.

    Linear: eta P_in. Logistic: Boshkovska's curve. Both clipped to [0, P_in]. Scalar and
    written with ``math`` so that the simulator kernel calls this very function, in Python
    or compiled by numba, with the same C library underneath (bit-identical results).
    """
    if logistic:
        omega = _sigmoid(-a_per_w * b_w)
        out = max_w * (_sigmoid(a_per_w * (p_in - b_w)) - omega) / (1.0 - omega)
    else:
        out = efficiency * p_in
    return min(max(out, 0.0), p_in)


def _sigmoid_array(x: np.ndarray) -> np.ndarray:
    """:func:`_sigmoid` elementwise: both of its branches with one exp(-|x|)."""
    e = fpmath.exp(-np.abs(x))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(x >= 0.0, 1.0 / (1.0 + e), e / (1.0 + e))


def harvest_from_input_array_w(p_in, logistic, efficiency, max_w, a_per_w, b_w):  # type: ignore[no-untyped-def]
    """:func:`harvest_from_input_w` over broadcast numpy arrays (float64 out), W.

    The same operations in the same order, with the same C library ``exp``
    (:mod:`swiptopt.fpmath`), and the same clipping, written with ``np.where`` so that it
    behaves as Python's ``min``/``max`` do: the same bits as the scalar function, element
    for element. ``logistic`` is one bool for the whole array.
    """
    p = np.asarray(p_in, dtype=float)
    if logistic:
        omega = _sigmoid_array(-np.asarray(a_per_w, dtype=float) * b_w)
        out = max_w * (_sigmoid_array(a_per_w * (p - b_w)) - omega) / (1.0 - omega)
    else:
        out = efficiency * p
    out = np.where(0.0 > out, 0.0, out)  # max(out, 0.0)
    return np.asarray(np.where(p < out, p, out), dtype=float)[()]  # min(out, p_in)


_harvest_array = harvest_from_input_array_w


def harvested_power_w(
    available_power_w: ArrayLike,
    split_ratio: ArrayLike,
    efficiency: ArrayLike = 0.5,
    model: HarvesterModel = "linear",
    *,
    logistic_max_w: float = LOGISTIC_MAX_W,
    logistic_a_per_w: float = LOGISTIC_A_PER_W,
    logistic_b_w: float = LOGISTIC_B_W,
) -> np.ndarray:
    """DC power harvested from the (1 - alpha) share of the received signal, W.

    ``model="linear"``: P_h = eta_ae (1 - alpha) P_av (paper eq. 12 with the split). ``model="logistic"``: the
    Boshkovska curve of P_in = (1 - alpha) P_av, whose fitted parameters already include the
    conversion loss (``efficiency`` is not applied). Either way the result is capped at the
    input power: a fitted curve with arbitrary parameters must not create energy.
    """
    p_in = (1.0 - _split(split_ratio)) * np.asarray(available_power_w, dtype=float)
    if model not in ("linear", "logistic"):
        raise ValueError(f"model must be 'linear' or 'logistic', got {model!r}")
    eta = np.asarray(efficiency, dtype=float)
    if np.any((eta < 0) | (eta > 1)):
        raise ValueError(f"efficiency must lie in [0, 1], got {efficiency!r}")
    return _harvest_array(p_in, model == "logistic", eta, logistic_max_w, logistic_a_per_w, logistic_b_w)
