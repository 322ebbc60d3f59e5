"""One evaluation harness for anything with ``predict(obs, deterministic=True)``.

RL agents, planners and Stable-Baselines3 models alike: :func:`evaluate` runs episodes on
separate seeds and returns per-episode metrics with a summary (mean, 95 % confidence
interval, min, max), in the spirit of SB3's ``evaluate_policy``.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np

from swiptopt.env import INFO_KEY
from swiptopt.errors import ConfigError
from swiptopt.metrics import EPISODE_METRICS
from swiptopt.validation import Spec, check_value

#: Evaluation episodes are seeded from ``seed + EVALUATION_SEED_OFFSET`` (the benchmark's
#: tasks and :func:`rl.protocol.train_and_evaluate` alike), seeds that training never uses.
EVALUATION_SEED_OFFSET = 1_000_003


@runtime_checkable
class Policy(Protocol):
    """Anything that maps an observation to an action.

    ``predict`` may return the action or SB3's ``(action, state)``; on a vector env it gets a
    batch of observations. A policy that plans per episode may also define
    ``begin_episode(env, obs, info)``; :func:`evaluate` calls it after every reset with the
    unwrapped environment.
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


#: What :func:`evaluate`'s ``episodes`` may hold (:func:`swiptopt.validation.check_value`).
EPISODES = Spec(kind="int", lo=1, strict=True, doc="episodes to run")


def evaluate(policy: Policy, env: Any, episodes: int, seed: int = 0) -> EvaluationResult:
    """Run ``episodes`` episodes, episode i reset with seed ``seed + i``, greedy actions.

    ``env`` is an environment of this package, bare or wrapped (``gymnasium.make``'s
    wrappers, ``TimeLimit``, ``RecordEpisodeStatistics``, ``FlattenObservation``, SB3's
    ``Monitor``, ...), or a vector of them: an SB3 ``VecEnv`` (``DummyVecEnv``,
    ``SubprocVecEnv``, and wrappers such as ``VecNormalize``) or a Gymnasium ``VectorEnv``
    (``SyncVectorEnv``, ``AsyncVectorEnv``; any autoreset mode). A record holds the episode's
    metrics (``info["episode_metrics"]`` of its last step), its seed and the layout it ran on.

    When a wrapper ends an episode before the env does (a ``TimeLimit`` shorter than the
    scenario's ``episode_steps``), the metrics come from the unwrapped env's
    :meth:`~swiptopt.env.AuvSwiptEnv.episode_metrics`; inside a vector env that is not
    possible (it resets the sub-env at once) and is an error.

    On a vector env of n sub-envs, episodes run in rounds of n: sub-env k of round r is reset
    with seed ``seed + r n + k`` and its first episode is recorded, so the records equal
    those of a single env for a policy that acts on each observation alone. ``predict``
    then receives a batch of n observations; policies that plan per episode
    (``begin_episode``) need a single env.
    """
    episodes = check_value("episodes", episodes, EPISODES)
    if not hasattr(policy, "predict"):
        raise ConfigError(f"policy {type(policy).__name__} has no predict(obs, deterministic) method", "policy")
    vector = _vector_kind(env)
    if vector is None:
        records = _evaluate_single(policy, env, episodes, seed)
    else:
        if hasattr(policy, "begin_episode"):
            raise ConfigError(
                f"policy {type(policy).__name__} plans per episode (begin_episode): evaluate it on a single env, "
                "not a vector env",
                "env",
            )
        records = _evaluate_vector(policy, env, vector, episodes, seed)
    summary = {name: Summary.of([r[name] for r in records]) for name in EPISODE_METRICS}
    return EvaluationResult(records, summary)


def _action(policy: Policy, obs: Any) -> Any:
    action = policy.predict(obs, deterministic=True)
    return action[0] if isinstance(action, tuple) else action  # SB3 returns (action, state)


def _record(i: int, seed: int, layout_seed: Any, metrics: Any) -> dict[str, Any]:
    record: dict[str, Any] = {"episode": i, "seed": seed}
    if layout_seed is not None:
        record["layout_seed"] = int(layout_seed)
    record.update(metrics)
    return record


def _evaluate_single(policy: Policy, env: Any, episodes: int, seed: int) -> list[dict[str, Any]]:
    records = []
    for i in range(episodes):
        obs, info = env.reset(seed=seed + i)
        layout_seed = info.get("layout_seed")
        if hasattr(policy, "begin_episode"):
            policy.begin_episode(env.unwrapped, obs, info)
        while True:
            obs, _, terminated, truncated, info = env.step(_action(policy, obs))
            if terminated or truncated:
                break
        records.append(_record(i, seed + i, layout_seed, final_metrics(env, info)))
    return records


def final_metrics(env: Any, info: dict[str, Any]) -> Mapping[str, Any]:
    """The metrics of the episode that just ended on ``env`` (a single env, wrapped or not),
    given its last step's ``info``: ``info["episode_metrics"]``, or, when a wrapper ended the
    episode before the env did (a shorter ``TimeLimit``), the unwrapped env's
    :meth:`~swiptopt.env.AuvSwiptEnv.episode_metrics` (call it before the next reset)."""
    metrics = info.get(INFO_KEY)
    if metrics is not None:
        return metrics
    base = getattr(env, "unwrapped", env)
    if not callable(getattr(base, "episode_metrics", None)):
        raise ConfigError(
            f"the episode ended without info[{INFO_KEY!r}] and {type(base).__name__} is not a swiptopt "
            "environment: evaluate runs on swiptopt/AuvSwipt environments",
            "env",
        )
    return base.episode_metrics()


def _vector_kind(env: Any) -> str | None:
    """``"sb3"`` for a Stable-Baselines3 VecEnv, ``"gymnasium"`` for a Gymnasium VectorEnv."""
    sb3 = sys.modules.get("stable_baselines3.common.vec_env")  # an SB3 VecEnv means SB3 is loaded
    if sb3 is not None and isinstance(env, sb3.VecEnv):
        return "sb3"
    if isinstance(env, gym.vector.VectorEnv):
        return "gymnasium"
    return None


def _evaluate_vector(policy: Policy, env: Any, kind: str, episodes: int, seed: int) -> list[dict[str, Any]]:
    n = env.num_envs
    records = []
    for first in range(0, episodes, n):
        wanted = min(n, episodes - first)
        if kind == "sb3":
            env.seed(seed + first)  # SB3 gives sub-env k the seed seed + first + k at the next reset
            obs = env.reset()
            inner = env
            while hasattr(inner, "venv"):  # SB3's VecEnv wrappers do not pass reset_infos on
                inner = inner.venv
            layouts = [info.get("layout_seed") for info in inner.reset_infos]
        else:
            obs, infos = env.reset(seed=[seed + first + k for k in range(n)])
            layouts = [infos["layout_seed"][k] if infos.get("_layout_seed", np.zeros(n))[k] else None for k in range(n)]
        metrics: list[Any] = [None] * wanted
        finished = np.zeros(n, dtype=bool)
        while not finished[:wanted].all():
            if kind == "sb3":
                obs, _, dones, infos = env.step(_action(policy, obs))
                ended = [infos[k].get(INFO_KEY) if dones[k] else None for k in range(n)]
            else:
                obs, dones, ended = _gymnasium_vector_step(env, _action(policy, obs))
            for k in np.flatnonzero(dones[:wanted] & ~finished[:wanted]):
                if ended[k] is None:
                    raise ConfigError(
                        f"sub-env {k} ended an episode without info[{INFO_KEY!r}]: a wrapper inside the vector env "
                        "(a TimeLimit?) cut it short; set the scenario's episode_steps instead, or evaluate on a "
                        "single env",
                        "env",
                    )
                metrics[k] = ended[k]
            finished |= np.asarray(dones, dtype=bool)
        records += [_record(first + k, seed + first + k, layouts[k], metrics[k]) for k in range(wanted)]
    return records


def _gymnasium_vector_step(env: Any, actions: Any) -> tuple[Any, np.ndarray, list[Any]]:
    """One step of a Gymnasium VectorEnv: observations, which sub-envs ended an episode, and
    the metrics of each that did (``None`` where none)."""
    from gymnasium.vector import AutoresetMode

    obs, _, terminated, truncated, infos = env.step(actions)
    dones = np.logical_or(terminated, truncated)
    mode = env.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
    source = infos.get("final_info", {}) if mode == AutoresetMode.SAME_STEP else infos
    values = source.get(INFO_KEY)
    present = source.get("_" + INFO_KEY, np.zeros(env.num_envs, dtype=bool))
    ended = [values[k] if values is not None and present[k] else None for k in range(env.num_envs)]
    if mode == AutoresetMode.DISABLED and dones.any():
        # without autoreset a finished sub-env must be reset before the next step
        obs, _ = env.reset(options={"reset_mask": dones})
    return obs, dones, ended


# ----------------------------------------------------------------------- fleets

#: The metrics :func:`evaluate_fleet` summarises: the single AUV's, for the fleet as a
#: whole, then the fleet's own (:func:`swiptopt.fleet.fleet_metrics`; its per-AUV lists
#: stay in the records).
FLEET_SUMMARY_METRICS = (*EPISODE_METRICS, "makespan_s", "jain_auv_energy")


@runtime_checkable
class FleetPolicy(Protocol):
    """Anything that acts for a fleet: ``act(observations)`` maps each live agent's
    observation (a dict, as :class:`~swiptopt.env_fleet.AuvFleetEnv` gives them) to its
    action. A policy that plans per episode may also define ``begin_episode(env,
    observations, infos)``; :func:`evaluate_fleet` calls it after every reset."""

    def act(self, observations: Mapping[str, Any]) -> Mapping[str, Any]: ...


def evaluate_fleet(policy: FleetPolicy, env: Any, episodes: int, seed: int = 0) -> EvaluationResult:
    """Run ``episodes`` episodes of a fleet env (:class:`~swiptopt.env_fleet.AuvFleetEnv`),
    episode i reset with seed ``seed + i``; a record holds the fleet's metrics (its per-AUV
    lists among them), its seed and layout, as :func:`evaluate`'s do for one AUV."""
    episodes = check_value("episodes", episodes, EPISODES)
    if not callable(getattr(policy, "act", None)):
        raise ConfigError(f"policy {type(policy).__name__} has no act(observations) method", "policy")
    records = []
    for i in range(episodes):
        observations, infos = env.reset(seed=seed + i)
        layout_seed = next(iter(infos.values()), {}).get("layout_seed")
        if hasattr(policy, "begin_episode"):
            policy.begin_episode(env, observations, infos)
        while env.agents:
            observations, *_ = env.step(policy.act(observations))
        records.append(_record(i, seed + i, layout_seed, env.episode_metrics()))
    summary = {name: Summary.of([r[name] for r in records]) for name in FLEET_SUMMARY_METRICS}
    return EvaluationResult(records, summary)
