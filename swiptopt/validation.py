"""Declarative checks of configuration values: a type, a range or a set of choices.

One :class:`Spec` describes what a scalar setting may hold; :func:`check_value` checks a
value against it and returns it normalised (an integral float for an integer setting becomes
an int, an int for a float setting a float), or raises one error that names the setting, the
value and what is allowed. Scenario fields, the benchmark's algorithm settings and the
arguments of the planners, the agents and the environments are all checked here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from swiptopt.errors import ConfigError, did_you_mean

KINDS = ("float", "int", "str", "bool")


@dataclass(frozen=True)
class Spec:
    """What one setting may hold.

    ``kind`` is the type (``float``, ``int``, ``str``, ``bool``; scenarios add kinds of their
    own); numbers lie in the interval from ``lo`` to ``hi`` (``None``: unbounded; ``*_open``:
    the end itself excluded); strings with ``choices`` must be one of them; ``optional``
    allows ``None`` (the setting left out). An ``int`` setting takes an integral float
    (``3.0``) as its integer unless ``strict``: then only integers (Python's or numpy's) are
    allowed, for arguments a caller passes in code rather than reads from a file.
    """

    unit: str = ""
    doc: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    kind: str = "float"
    choices: tuple[str, ...] = ()
    optional: bool = False
    strict: bool = False

    def allowed(self, hi: float | None = None) -> str:
        """What the setting may hold, in words; ``hi`` replaces the spec's upper end."""
        if self.kind == "bool":
            return "true or false"
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.kind == "str":
            return "a string"
        hi = self.hi if hi is None else hi
        what = "an integer" if self.kind == "int" else "a number"
        if self.lo is None and hi is None:
            return what
        number = (lambda x: str(int(x))) if self.kind == "int" else (lambda x: f"{x:g}")
        lo_text = "-inf" if self.lo is None else number(self.lo)
        hi_text = "inf" if hi is None else number(hi)
        left = "(" if self.lo_open or self.lo is None else "["
        right = ")" if self.hi_open or hi is None else "]"
        return f"{what} in {left}{lo_text}, {hi_text}{right}"

    def in_range(self, x: float, hi: float | None = None) -> bool:
        hi = self.hi if hi is None else hi
        if self.lo is not None and (x < self.lo or (self.lo_open and x == self.lo)):
            return False
        if hi is not None and (x > hi or (self.hi_open and x == hi)):
            return False
        return True


def check_value(
    name: str,
    value: Any,
    spec: Spec,
    *,
    field: str | None = None,
    hi: float | None = None,
    error: type[ConfigError] = ConfigError,
) -> Any:
    """``value`` checked against ``spec`` and normalised; otherwise ``error`` naming ``name``.

    ``field`` is the error's field (default ``name``); ``hi`` replaces the spec's upper end
    (a bound that depends on context, such as a scenario's grid).
    """
    field = field or name
    if value is None:
        if spec.optional:
            return None
        raise error(f"{name} must be set: {spec.allowed(hi)}", field)
    kind = spec.kind
    if kind == "str":
        if not isinstance(value, str):
            raise error(f"{name} = {value!r} must be {spec.allowed()}", field)
        if spec.choices and value not in spec.choices:
            raise error(
                f"{name} = {value!r}{did_you_mean(value, spec.choices)} is not allowed: must be {spec.allowed()}",
                field,
            )
        return value
    if kind == "bool":
        if not isinstance(value, (bool, np.bool_)):
            raise error(f"{name} = {value!r} must be true or false", field)
        return bool(value)
    if kind not in ("int", "float"):
        raise TypeError(f"check_value checks {', '.join(KINDS)}, not {kind!r}")
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise error(f"{name} = {value!r} is not allowed: must be {spec.allowed(hi)}", field)
    if kind == "int":
        if isinstance(value, (float, np.floating)):
            if spec.strict or not float(value).is_integer():
                raise error(f"{name} = {value!r} is not allowed: must be {spec.allowed(hi)}", field)
        value = int(value)
    else:
        value = float(value)
        if not math.isfinite(value):
            raise error(f"{name} = {value!r} must be finite: {spec.allowed(hi)}", field)
    if not spec.in_range(value, hi):
        raise error(f"{name} = {value!r} is out of range: must be {spec.allowed(hi)}", field)
    return value


@dataclass(frozen=True)
class Param(Spec):
    """A constructor argument declared once, on the class that takes it: its default and
    what it may hold. A class lists its ``parameters`` (name -> Param); :func:`check_params`
    checks its arguments against them, and the benchmark's registry reads the same
    declarations for its settings, its listing and its validation."""

    default: Any = None


def check_params(params: Mapping[str, Param], values: Mapping[str, Any], owner: str = "") -> dict[str, Any]:
    """``values`` checked against ``params`` (unknown names refused, naming the allowed
    ones) with the defaults of those not given, normalised; a :class:`ConfigError` naming the
    argument otherwise."""
    for name in values:
        if name not in params:
            whose = f"{owner} " if owner else ""
            raise ConfigError(f"unknown {whose}argument {name!r}{did_you_mean(name, params)}: allowed are "
                              f"{', '.join(params)}", name)
    return {name: check_value(name, values.get(name, param.default), param) for name, param in params.items()}


class Parameterised:
    """A class whose constructor takes the keyword arguments declared once, in
    :attr:`parameters` (name -> :class:`Param`): the constructor checks them against the
    declarations (:func:`check_params`) and keeps each as the attribute of the same name,
    and each subclass gets the signature its declarations make (``help`` and ``inspect``
    show ``Planner(*, k=None, k_max=20, ...)``). The benchmark's registry, its listing and
    its validation read the same declarations. Names in :attr:`positional` may also be given
    by position, in that order."""

    #: The constructor's arguments, name -> declaration.
    parameters: ClassVar[dict[str, Param]] = {}
    #: Arguments that may be given by position, in order.
    positional: ClassVar[tuple[str, ...]] = ()

    def __init__(self, *args: Any, **settings: Any) -> None:
        if len(args) > len(self.positional):
            raise ConfigError(f"{type(self).__name__} takes at most {len(self.positional)} positional arguments "
                              f"({', '.join(self.positional) or 'none'}): give the others by name", "arguments")
        for name, value in zip(self.positional, args):
            if name in settings:
                raise ConfigError(f"{type(self).__name__} got {name!r} twice", name)
            settings[name] = value
        for name, value in check_params(self.parameters, settings, type(self).__name__).items():
            setattr(self, name, value)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        import inspect

        super().__init_subclass__(**kwargs)
        kinds = {name: inspect.Parameter.POSITIONAL_OR_KEYWORD for name in cls.positional}
        ordered = [*cls.positional, *(n for n in cls.parameters if n not in cls.positional)]
        cls.__signature__ = inspect.Signature([  # type: ignore[attr-defined]
            inspect.Parameter(name, kinds.get(name, inspect.Parameter.KEYWORD_ONLY),
                              default=cls.parameters[name].default)
            for name in ordered
        ])


def check_keys(where: str, mapping: Any, field: str | None = None, error: type[ConfigError] = ConfigError) -> dict:
    """``mapping`` as a dict whose keys are all strings; otherwise ``error`` naming ``where``."""
    if not isinstance(mapping, Mapping):
        raise error(f"{where} must be a table of settings, got {type(mapping).__name__}", field or where)
    for key in mapping:
        if not isinstance(key, str):
            raise error(f"{where} has a key {key!r} that is not a string: keys are setting names", field or where)
    return dict(mapping)


__all__ = ["KINDS", "Param", "Parameterised", "Spec", "check_keys", "check_params", "check_value"]
