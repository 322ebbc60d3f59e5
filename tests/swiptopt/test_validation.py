"""The declarative checks: what a :class:`Spec` lets through, normalised, and the one-line
error that names the setting, the value and what is allowed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from swiptopt.errors import ConfigError
from swiptopt.validation import Param, Spec, check_params, check_value

COUNT = Spec(kind="int", lo=1)
STRICT_COUNT = Spec(kind="int", lo=1, strict=True)


def test_an_int_setting_takes_an_integral_float_unless_strict():
    assert check_value("n", 3.0, COUNT) == 3 and type(check_value("n", 3.0, COUNT)) is int
    with pytest.raises(ConfigError) as info:
        check_value("n", 3.0, STRICT_COUNT)
    assert info.value.field == "n" and str(info.value) == "n = 3.0 is not allowed: must be an integer in [1, inf)"
    for good in (3, np.int64(3), np.uint8(3)):
        assert check_value("n", good, STRICT_COUNT) == 3 and type(check_value("n", good, STRICT_COUNT)) is int
    for bad in (True, np.bool_(True), 2.5, "3", None, 0):
        with pytest.raises(ConfigError):
            check_value("n", bad, STRICT_COUNT)


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_a_strict_int_setting_refuses_every_float(value):
    with pytest.raises(ConfigError) as info:
        check_value("n", value, STRICT_COUNT)
    assert info.value.field == "n" and "\n" not in str(info.value)


@given(st.integers(min_value=-(2**70), max_value=2**70))
def test_a_strict_int_setting_takes_the_integers_in_range(value):
    spec = Spec(kind="int", lo=-5, hi=2**40, hi_open=True, strict=True)
    if -5 <= value < 2**40:
        assert check_value("n", value, spec) == value
    else:
        with pytest.raises(ConfigError, match=r"out of range: must be an integer in \[-5, 1099511627776\)"):
            check_value("n", value, spec)


def test_numbers_choices_and_optional_settings():
    share = Spec(lo=0, lo_open=True, hi=1)
    assert check_value("f", 1, share) == 1.0 and type(check_value("f", 1, share)) is float
    for bad, words in ((0, "is out of range: must be a number in (0, 1]"), (math.nan, "must be finite"),
                       ("0.5", "is not allowed")):
        with pytest.raises(ConfigError) as info:
            check_value("f", bad, share)
        assert words in str(info.value)
    mode = Spec(kind="str", choices=("raise", "hover"), optional=True)
    assert check_value("mode", None, mode) is None and check_value("mode", "hover", mode) == "hover"
    with pytest.raises(ConfigError, match=r"mode = 'hoover' \(did you mean 'hover'\?\) is not allowed"):
        check_value("mode", "hoover", mode)
    with pytest.raises(ConfigError, match="k = 13 is out of range: must be an integer in \\[1, 12\\]") as info:
        check_value("k", 13, COUNT, hi=12, field="groups")
    assert info.value.field == "groups"


def test_check_params_fills_defaults_and_refuses_unknown_names():
    params = {"k": Param(default=None, kind="int", lo=1, optional=True), "prune": Param(default=True, kind="bool")}
    assert check_params(params, {"k": 2.0}) == {"k": 2, "prune": True}
    with pytest.raises(ConfigError, match=r"unknown Planner argument 'prun' \(did you mean 'prune'\?\)") as info:
        check_params(params, {"prun": False}, "Planner")
    assert info.value.field == "prun"
