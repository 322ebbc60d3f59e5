"""Configuration of the tabular agents (the paper's Table I as defaults)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

from swiptopt.errors import ConfigError
from swiptopt.validation import Param, check_value

#: Q-learning's and SARSA's hyper-parameters, declared once (the paper's Table I as
#: defaults): :class:`TabularConfig` takes them, and the benchmark's registry reads them.
TABULAR_PARAMETERS: dict[str, Param] = {
    "learning_rate": Param(default=0.75, lo=0, lo_open=True, hi=1, doc="TD step size (paper: 0.75)"),
    "discount": Param(default=0.99, lo=0, hi=1, doc="discount factor gamma (paper: 0.99)"),
    "epsilon_start": Param(default=1.0, lo=0, hi=1, doc="exploration probability of the first episode (paper: 1.0)"),
    "epsilon_decay": Param(default=0.999, lo=0, lo_open=True, hi=1, doc="epsilon factor per episode (paper: 0.999)"),
    "epsilon_min": Param(default=0.001, lo=0, hi=1, doc="floor of epsilon (paper: 0.001)"),
    "replay_size": Param(default=0, kind="int", lo=0, hi=10**7, strict=True, unit="transitions",
                         doc="experience-replay memory, 0 for none (the paper's Table I: 1000; needs the "
                             "python training loop)"),
    "replay_batch": Param(default=4, kind="int", lo=1, hi=10**4, strict=True, unit="transitions",
                          doc="transitions replayed after every step when replay is on (Table I: 4)"),
}
_P = TABULAR_PARAMETERS


@dataclass(frozen=True)
class TabularConfig:
    """Hyper-parameters of Q-learning and SARSA (:data:`TABULAR_PARAMETERS`: each field's
    range and meaning); validated at construction."""

    learning_rate: float = _P["learning_rate"].default
    discount: float = _P["discount"].default
    epsilon_start: float = _P["epsilon_start"].default
    epsilon_decay: float = _P["epsilon_decay"].default
    epsilon_min: float = _P["epsilon_min"].default
    replay_size: int = _P["replay_size"].default
    replay_batch: int = _P["replay_batch"].default

    #: What each field may hold, checked at construction (:func:`swiptopt.validation.check_value`).
    FIELDS: ClassVar[dict[str, Param]] = TABULAR_PARAMETERS

    def __post_init__(self) -> None:
        for name, spec in self.FIELDS.items():
            check_value(name, getattr(self, name), spec)

    def replace(self, **changes: object) -> TabularConfig:
        names = {f.name for f in dataclasses.fields(self)}
        for key in changes:
            if key not in names:
                raise ConfigError(f"unknown agent setting {key!r}; known: {sorted(names)}", key)
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]
