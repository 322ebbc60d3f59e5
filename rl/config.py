"""Configuration of the tabular agents (the paper's Table I as defaults)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

from swiptopt.errors import ConfigError
from swiptopt.validation import Spec, check_value


@dataclass(frozen=True)
class TabularConfig:
    """Hyper-parameters of Q-learning and SARSA; validated at construction."""

    learning_rate: float = 0.75
    """Step size of the TD update, in (0, 1] (paper: 0.75)."""
    discount: float = 0.99
    """Discount factor gamma, in [0, 1] (paper: 0.99)."""
    epsilon_start: float = 1.0
    """Exploration probability of the first episode, in [0, 1] (paper: 1.0)."""
    epsilon_decay: float = 0.999
    """Factor applied to epsilon after every episode, in (0, 1] (paper: 0.999)."""
    epsilon_min: float = 0.001
    """Floor of epsilon, in [0, 1] (paper: 0.001)."""
    replay_size: int = 0
    """Transitions kept for experience replay; 0 turns replay off (paper's Table I: 1000)."""
    replay_batch: int = 4
    """Transitions replayed after every step when replay is on (paper's Table I: 4)."""

    #: What each field may hold, checked at construction (:func:`swiptopt.validation.check_value`).
    FIELDS: ClassVar[dict[str, Spec]] = {
        "learning_rate": Spec(lo=0, lo_open=True, hi=1),
        "discount": Spec(lo=0, hi=1),
        "epsilon_start": Spec(lo=0, hi=1),
        "epsilon_decay": Spec(lo=0, lo_open=True, hi=1),
        "epsilon_min": Spec(lo=0, hi=1),
        "replay_size": Spec(kind="int", lo=0, hi=10**7, strict=True, unit="transitions"),
        "replay_batch": Spec(kind="int", lo=1, hi=10**4, strict=True, unit="transitions"),
    }

    def __post_init__(self) -> None:
        for name, spec in self.FIELDS.items():
            check_value(name, getattr(self, name), spec)

    def replace(self, **changes: object) -> TabularConfig:
        names = {f.name for f in dataclasses.fields(self)}
        for key in changes:
            if key not in names:
                raise ConfigError(f"unknown agent setting {key!r}; known: {sorted(names)}", key)
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]
