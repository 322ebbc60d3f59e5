"""Configuration of the tabular agents (the paper's Table I as defaults)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from swiptopt.errors import ConfigError


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

    def __post_init__(self) -> None:
        def check(name: str, ok: bool, allowed: str) -> None:
            value = getattr(self, name)
            if isinstance(value, bool) or not ok:
                raise ConfigError(f"{name} = {value!r} is out of range: must be {allowed}", name)

        lr, d = self.learning_rate, self.discount
        check("learning_rate", isinstance(lr, (int, float)) and 0 < lr <= 1, "a number in (0, 1]")
        check("discount", isinstance(d, (int, float)) and 0 <= d <= 1, "a number in [0, 1]")
        for name in ("epsilon_start", "epsilon_min"):
            v = getattr(self, name)
            check(name, isinstance(v, (int, float)) and 0 <= v <= 1, "a number in [0, 1]")
        v = self.epsilon_decay
        check("epsilon_decay", isinstance(v, (int, float)) and 0 < v <= 1, "a number in (0, 1]")
        check("replay_size", isinstance(self.replay_size, int) and 0 <= self.replay_size <= 10**7, "an integer in [0, 10000000]")
        check("replay_batch", isinstance(self.replay_batch, int) and 1 <= self.replay_batch <= 10**4, "an integer in [1, 10000]")

    def replace(self, **changes: object) -> TabularConfig:
        names = {f.name for f in dataclasses.fields(self)}
        for key in changes:
            if key not in names:
                raise ConfigError(f"unknown agent setting {key!r}; known: {sorted(names)}", key)
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]
