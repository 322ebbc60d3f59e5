"""Compile plain-Python functions with numba from their own source, as a family.

The kernel, the agents' action selection and the trainer are written once, as plain
Python over numpy arrays and scalars. :func:`compile_family` compiles a set of them so that,
inside the compiled code, each name refers to the compiled version of the same function;
the Python originals stay untouched and remain the reference implementation.
"""

from __future__ import annotations

import hashlib
import types
from collections.abc import Callable, Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any


def numba_available() -> bool:
    """Whether numba can be imported (it is the ``fast`` extra)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


@lru_cache(maxsize=1)
def source_tag() -> str:
    """A hash of the sources of ``swiptopt`` and ``rl``, the packages compiled here.

    Numba's disk cache checks only the compiled function's own file, not what it inlines
    (the physics, the kernel) nor the compile flags; naming every compiled function with
    this tag makes any edit to either package a cache miss instead of stale machine code.
    """
    digest = hashlib.sha1()
    root = Path(__file__).resolve().parent.parent
    for package in ("swiptopt", "rl"):
        for path in sorted((root / package).glob("*.py")):
            digest.update(path.name.encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def compile_family(
    functions: Mapping[str, Callable[..., Any]],
    compiled_globals: Mapping[str, Any] = {},
    *,
    inline: bool = True,
) -> dict[str, Callable[..., Any]]:
    """Compile ``functions`` (name -> Python function) against each other.

    Each function is cloned with globals where its own module's names are overlaid by
    ``compiled_globals`` (already compiled helpers) and by the compiled members of the family,
    in the order given (a function may call those before it). Cached on disk by numba.

    With ``inline`` (the default) numba inlines the functions into their compiled callers:
    a call between compiled functions otherwise costs reference-count updates on every
    array argument, which dominated the kernel's step time.
    """
    import numba

    jit = numba.njit(cache=True, nogil=True, error_model="numpy", inline="always" if inline else "never")
    out: dict[str, Callable[..., Any]] = {}
    for name, fn in functions.items():
        namespace = dict(fn.__globals__)
        namespace.update(compiled_globals)
        namespace.update(out)
        clone = types.FunctionType(fn.__code__, namespace, fn.__name__, fn.__defaults__)
        clone.__qualname__ = f"{fn.__qualname__}_{source_tag()}"
        clone.__module__ = fn.__module__
        out[name] = jit(clone)
    return out
