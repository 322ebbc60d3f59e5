"""Elementwise exp, log, log10, log2, log1p and 10**x through the C library, on any CPU.

numpy evaluates these functions with loops chosen for the CPU it runs on: with AVX-512
(numpy's ``X86_V4`` features) it takes SIMD implementations whose results differ from the
C library's scalar functions in the last bit for a few percent of the inputs; without it,
it calls the C library. The simulator kernel calls the C library (through Python's
``math`` or numba-compiled code), so tables built with numpy's loops would disagree with
the kernel on some CPUs and with themselves across CPUs. Every physical quantity the
model computes as an array goes through these functions instead, which call the C
library's ``exp``, ``log``, ``log10``, ``log2``, ``log1p`` and ``pow`` element by element:
an array built here holds, bit for bit, what the kernel computes from one element, on
every CPU.

With numba (the ``fast`` extra) the functions are numba ufuncs compiled on first use and
cached on disk; without it, the same C functions through ``math``, one element at a time
(about 100 ns each). Both follow numpy's conventions at the edges (``log10(0) = -inf``,
``log10(-1) = nan``, ``exp(1000) = inf``) and give the same bits; a test holds them to
each other and to ``math``. numpy's ``sqrt``, ``hypot`` and the arithmetic operators are
exact or CPU-independent and stay numpy's; :func:`dot` replaces BLAS's products.

torch has CPU-specific paths of its own (ATen's AVX-512 softmax, MKL's matrix products);
:func:`pin_torch_cpu_paths` holds them to the paths every x86-64 CPU with AVX2 shares.
"""

from __future__ import annotations

import math
import os
import platform
from collections.abc import Callable
from functools import cache

import numpy as np
from numpy.typing import ArrayLike

from swiptopt.jit import numba_available

#: The functions of this module; each takes array-likes and returns float64 arrays (a
#: numpy scalar for scalar input).
NAMES = ("exp", "log", "log10", "log2", "log1p", "pow10")


def _exp(x):  # type: ignore[no-untyped-def]
    return math.exp(x)


def _log(x):  # type: ignore[no-untyped-def]
    return math.log(x)


def _log10(x):  # type: ignore[no-untyped-def]
    return math.log10(x)


def _log2(x):  # type: ignore[no-untyped-def]
    return math.log2(x)


def _log1p(x):  # type: ignore[no-untyped-def]
    return math.log1p(x)


def _pow10(x):  # type: ignore[no-untyped-def]
    return math.pow(10.0, x)


_SCALAR: dict[str, Callable[[float], float]] = {
    "exp": _exp, "log": _log, "log10": _log10, "log2": _log2, "log1p": _log1p, "pow10": _pow10,
}


def _python_scalar(name: str) -> Callable[[float], float]:
    """The scalar function with numpy's results where ``math`` raises."""
    fn = _SCALAR[name]
    if name in ("exp", "pow10"):

        def overflowing(x: float) -> float:
            try:
                return fn(x)
            except OverflowError:
                return math.inf

        return overflowing
    lowest = -1.0 if name == "log1p" else 0.0

    def logarithm(x: float) -> float:
        if x > lowest or x != x:
            return fn(x)
        return -math.inf if x == lowest else math.nan

    return logarithm


@cache
def _ufunc(name: str, compiled: bool) -> Callable[[np.ndarray], np.ndarray]:
    if compiled:
        import numba

        return numba.vectorize(["float64(float64)"], cache=True)(_SCALAR[name])
    scalar = np.frompyfunc(_python_scalar(name), 1, 1)

    def elementwise(x: np.ndarray) -> np.ndarray:
        return np.asarray(scalar(x), dtype=float)

    return elementwise


def _apply(name: str, x: ArrayLike, backend: str) -> np.ndarray:
    if backend not in ("auto", "compiled", "python"):
        raise ValueError(f"backend must be 'auto', 'compiled' or 'python', got {backend!r}")
    compiled = numba_available() if backend == "auto" else backend == "compiled"
    arr = np.asarray(x, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        out = _ufunc(name, compiled)(arr)
    return np.asarray(out, dtype=float)[()] if arr.ndim == 0 else np.asarray(out, dtype=float)


def dot(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """Sum over the last axis of ``a * b`` (broadcast), in numpy's pairwise order.

    ``np.dot`` and ``@`` hand float products to BLAS, whose kernels add in an order chosen
    for the CPU (OpenBLAS's AVX-512 kernels differ from its AVX2 ones in the last bit);
    numpy's own sum adds in one order on every CPU.
    """
    return np.sum(np.multiply(a, b), axis=-1)


def exp(x: ArrayLike, *, backend: str = "auto") -> np.ndarray:
    """e**x, elementwise, by the C library's ``exp``."""
    return _apply("exp", x, backend)


def log(x: ArrayLike, *, backend: str = "auto") -> np.ndarray:
    """Natural logarithm, elementwise, by the C library's ``log``."""
    return _apply("log", x, backend)


def log10(x: ArrayLike, *, backend: str = "auto") -> np.ndarray:
    """Base-10 logarithm, elementwise, by the C library's ``log10``."""
    return _apply("log10", x, backend)


def log2(x: ArrayLike, *, backend: str = "auto") -> np.ndarray:
    """Base-2 logarithm, elementwise, by the C library's ``log2``."""
    return _apply("log2", x, backend)


def log1p(x: ArrayLike, *, backend: str = "auto") -> np.ndarray:
    """log(1 + x), elementwise, by the C library's ``log1p``."""
    return _apply("log1p", x, backend)


def pow10(x: ArrayLike, *, backend: str = "auto") -> np.ndarray:
    """10**x, elementwise, by the C library's ``pow(10, x)`` (``math.pow(10.0, x)``, in
    Python and in numba-compiled code)."""
    return _apply("pow10", x, backend)


#: torch's CPU paths, held to those every x86-64 CPU with AVX2 runs alike (``x86-64-v3``:
#: Intel since Haswell, AMD since Excavator): ATen's vectorised kernels at AVX2 (its AVX-512
#: softmax and log-softmax differ in the last bit), and MKL's conditional numerical
#: reproducibility in its ``COMPATIBLE`` mode, the one Intel documents to give the same
#: results on Intel and AMD processors (MKL otherwise chooses matrix-product kernels by CPU
#: and vendor). ``benchmarks/deeprl_speed.py`` prints what it costs.
TORCH_CPU_PATHS = {"ATEN_CPU_CAPABILITY": "avx2", "MKL_CBWR": "COMPATIBLE"}


def _x86_64() -> bool:
    return platform.machine().lower() in ("x86_64", "amd64")


def pin_torch_cpu_paths() -> dict[str, str | None]:
    """Set :data:`TORCH_CPU_PATHS` in this process's environment, unless the user has set
    them, so that torch trains the same model on any x86-64 CPU with AVX2; returns what
    is in effect. Both are read when torch first computes, so call this before any torch
    computation in the process (an import alone is fine). Nothing is set on other
    architectures."""
    if _x86_64():
        for name, value in TORCH_CPU_PATHS.items():
            os.environ.setdefault(name, value)
    return {name: os.environ.get(name) for name in TORCH_CPU_PATHS}


def torch_cpu_path_overrides() -> dict[str, str]:
    """The settings of :data:`TORCH_CPU_PATHS` the user has set to something else (on
    x86-64; compared without regard to case), as this process's environment holds them.
    torch trains other weights on other paths, so a trained model's name includes these
    (``rl.deep``): empty, as under the pin, it leaves the name as it was."""
    if not _x86_64():
        return {}
    return {name: os.environ[name] for name, pinned in TORCH_CPU_PATHS.items()
            if os.environ.get(name, pinned).strip().upper() != pinned.upper()}
