"""The C library's functions as arrays (swiptopt.fpmath): the same bits as ``math`` and as
numba-compiled code, on either backend, and no physics left on numpy's CPU-specific loops."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from swiptopt import fpmath
from swiptopt.jit import numba_available

ROOT = Path(__file__).resolve().parents[2]

_MATH = {
    "exp": math.exp, "log": math.log, "log10": math.log10, "log2": math.log2, "log1p": math.log1p,
    "pow10": lambda x: math.pow(10.0, x),
}


def _inputs(name: str) -> np.ndarray:
    rng = np.random.default_rng(7)
    if name in ("exp", "pow10"):
        return np.concatenate([rng.uniform(-300.0, 300.0, 20_000), rng.normal(0.0, 3.0, 20_000)])
    low = -1.0 if name == "log1p" else 0.0
    return np.concatenate([low + 10.0 ** rng.uniform(-12.0, 12.0, 20_000), low + rng.uniform(0.0, 5.0, 20_000)])


@pytest.mark.parametrize("backend", ["python", pytest.param("compiled", marks=pytest.mark.skipif(
    not numba_available(), reason="numba is the fast extra"))])
@pytest.mark.parametrize("name", fpmath.NAMES)
def test_each_function_is_the_c_library_bit_for_bit(name, backend):
    x = _inputs(name)
    got = getattr(fpmath, name)(x, backend=backend)
    want = np.array([_MATH[name](v) for v in x.tolist()])
    assert got.dtype == np.float64 and got.shape == x.shape
    np.testing.assert_array_equal(got, want)
    # a scalar in gives a numpy scalar out, the same value
    assert getattr(fpmath, name)(float(x[3]), backend=backend) == want[3]
    assert np.ndim(getattr(fpmath, name)(float(x[3]), backend=backend)) == 0


@pytest.mark.parametrize("backend", ["python", pytest.param("compiled", marks=pytest.mark.skipif(
    not numba_available(), reason="numba is the fast extra"))])
def test_edges_follow_numpy(backend):
    special = np.array([0.0, -0.0, -1.0, np.inf, -np.inf, np.nan, 1e308, -1e308])
    for name in fpmath.NAMES:
        got = getattr(fpmath, name)(special, backend=backend)
        with np.errstate(all="ignore"):
            want = {"exp": np.exp, "log": np.log, "log10": np.log10, "log2": np.log2, "log1p": np.log1p,
                    "pow10": lambda a: np.power(10.0, a)}[name](special)
        np.testing.assert_array_equal(got, want, err_msg=name)


@pytest.mark.skipif(not numba_available(), reason="numba is the fast extra")
def test_compiled_scalar_code_calls_the_same_functions():
    """What the kernel computes in numba-compiled code from one element is what the tables
    hold for it."""
    import numba

    @numba.njit
    def scalar_chain(x):  # the kernel's and the continuous world's scalar formulas
        out = np.empty((x.size, 5))
        for i in range(x.size):
            out[i, 0] = math.log10(x[i])
            out[i, 1] = math.pow(10.0, x[i] / 10.0)
            out[i, 2] = math.exp(-x[i] / 50.0)
            out[i, 3] = math.log2(1.0 + x[i])
            out[i, 4] = math.log(x[i])
        return out

    x = 10.0 ** np.random.default_rng(3).uniform(-3.0, 3.0, 50_000)
    got = scalar_chain(x)
    np.testing.assert_array_equal(got[:, 0], fpmath.log10(x))
    np.testing.assert_array_equal(got[:, 1], fpmath.pow10(x / 10.0))
    np.testing.assert_array_equal(got[:, 2], fpmath.exp(-x / 50.0))
    np.testing.assert_array_equal(got[:, 3], fpmath.log2(1.0 + x))
    np.testing.assert_array_equal(got[:, 4], fpmath.log(x))


def test_bad_backend_is_refused():
    with pytest.raises(ValueError, match="backend"):
        fpmath.exp(1.0, backend="gpu")


#: numpy functions whose float64 loops depend on the CPU (AVX-512 takes SIMD paths that
#: differ from the C library in the last bit), and BLAS products, whose order of additions
#: depends on the CPU's kernel.
_CPU_DEPENDENT = re.compile(
    r"\bnp\.(exp|expm1|exp2|log|log10|log2|log1p|power|float_power|tan|arctan|arctan2|arcsin|arccos|"
    r"sinh|cosh|tanh|cbrt|dot|inner|vdot)\(|\b10(\.0)? \*\* |\bnp\.polynomial\.|\bnp\.linalg\.(eig|solve|lstsq|inv)"
)


def test_no_model_or_planner_code_uses_cpu_dependent_numpy_paths():
    """The model, the planners and the agents compute through swiptopt.fpmath and numpy's
    CPU-independent operations only, so their numbers are the same on every CPU."""
    offenders = []
    for package in ("swiptopt", "planners", "rl"):
        for path in sorted((ROOT / package).rglob("*.py")):
            if path.name == "fpmath.py":
                continue
            for number, line in enumerate(path.read_text().splitlines(), 1):
                code = line.split("#", 1)[0]
                if _CPU_DEPENDENT.search(code) and not code.lstrip().startswith(('"', "'")):
                    offenders.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert offenders == []
