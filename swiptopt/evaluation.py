"""One evaluation harness for anything with ``predict(obs, deterministic=True)``.

RL agents, planners and Stable-Baselines3 models alike: :func:`evaluate` runs episodes on
separate seeds and returns per-episode metrics with a summary (mean, 95 % confidence
interval, min, max), in the spirit of SB3's ``evaluate_policy``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from swiptopt.errors import ConfigError
from swiptopt.metrics import EPISODE_METRICS


@runtime_checkable
class Policy(Protocol):
    """Anything that maps an observation to an action.

    ``predict`` may return the action or SB3's ``(action, state)``. A policy that plans per
    episode may also define ``begin_episode(env, obs, info)``; :func:`evaluate` calls it
    after every reset with the unwrapped environment.
    """

    def predict(self, obs: Any, deterministic: bool = True) -> Any: ...


# Two-sided 95 % Student t quantiles for 1..30 degrees of freedom.
_T975 = (
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
    2.201, 2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086,
    2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042,
)


def t_quantile_975(dof: int) -> float:
    """The 97.5 % quantile of Student's t (exact table to 30 dof, Cornish-Fisher beyond)."""
    if dof < 1:
        return math.nan
    if dof <= len(_T975):
        return _T975[dof - 1]
    z = 1.959964
    return z + (z**3 + z) / (4 * dof) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * dof**2)


@dataclass(frozen=True)
class Summary:
    """Mean with a 95 % t confidence interval, min, max and count of the finite values.

    ``missing`` counts episodes where the metric had no value (a target never reached, a
    fairness index of nothing delivered); they are left out, not counted as zero.
    """

    mean: float
    ci95: float
    """Half-width of the 95 % confidence interval of the mean (NaN for fewer than 2 values)."""
    min: float
    max: float
    n: int
    missing: int

    @classmethod
    def of(cls, values: list[Any]) -> Summary:
        x = np.array([v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))], float)
        missing = len(values) - len(x)
        if len(x) == 0:
            return cls(math.nan, math.nan, math.nan, math.nan, 0, missing)
        ci = t_quantile_975(len(x) - 1) * float(np.std(x, ddof=1)) / math.sqrt(len(x)) if len(x) > 1 else math.nan
        return cls(float(np.mean(x)), ci, float(np.min(x)), float(np.max(x)), len(x), missing)


@dataclass(frozen=True)
class EvaluationResult:
    """Per-episode records (one dict of metrics per episode, with its seed) and summaries."""

    records: list[dict[str, Any]]
    summary: dict[str, Summary]

    def to_dataframe(self):  # type: ignore[no-untyped-def]
        """The records as a pandas DataFrame (needs pandas)."""
        import pandas as pd

        return pd.DataFrame.from_records(self.records)


def evaluate(policy: Policy, env: Any, episodes: int, seed: int = 0) -> EvaluationResult:
    """Run ``episodes`` episodes, episode i reset with seed ``seed + i``, greedy actions.

    ``env`` is a Gymnasium environment of this package (wrapped or not); the metrics are the
    ``info["episode"]`` of each episode's last step.
    """
    if not isinstance(episodes, int) or isinstance(episodes, bool) or episodes < 1:
        raise ConfigError(f"episodes = {episodes!r} must be a positive integer", "episodes")
    if not hasattr(policy, "predict"):
        raise ConfigError(f"policy {type(policy).__name__} has no predict(obs, deterministic) method", "policy")
    records = []
    for i in range(episodes):
        obs, info = env.reset(seed=seed + i)
        if hasattr(policy, "begin_episode"):
            policy.begin_episode(env.unwrapped, obs, info)
        while True:
            action = policy.predict(obs, deterministic=True)
            if isinstance(action, tuple):  # SB3 returns (action, state)
                action = action[0]
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        records.append({"episode": i, "seed": seed + i, **info["episode"]})
    summary = {name: Summary.of([r[name] for r in records]) for name in EPISODE_METRICS}
    return EvaluationResult(records, summary)
