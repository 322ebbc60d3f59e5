"""The algorithms a benchmark can run, by name, with their settings validated.

This is the benchmark layer: it may import ``rl`` and ``planners`` (the model modules below
it never do). Each algorithm turns (environment, settings, seed) into a policy ready for
:func:`swiptopt.evaluate`: RL agents are trained first (the paper's protocol), planners plan
when the evaluation begins its episodes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from swiptopt.errors import ConfigError, did_you_mean


@dataclass(frozen=True)
class Algorithm:
    """A named algorithm: its family, default settings and how to build it."""

    name: str
    label: str
    family: str
    defaults: dict[str, Any] = field(default_factory=dict)
    build: Callable[[Any, dict[str, Any], int], Any] | None = None


def _rl(algorithm: str) -> Callable[[Any, dict[str, Any], int], Any]:
    def build(env: Any, settings: dict[str, Any], seed: int) -> Any:
        from rl import TabularConfig, make_agent, train

        settings = dict(settings)
        episodes = settings.pop("train_episodes")
        backend = settings.pop("backend")
        config = None if algorithm == "random" else TabularConfig().replace(**settings)
        agent = make_agent(algorithm, env.observation_space.n, config=config, seed=seed)
        if algorithm != "random":
            train(agent, env, episodes, seed=seed, backend=backend)
        return agent

    return build


def _planner(cls_name: str) -> Callable[[Any, dict[str, Any], int], Any]:
    def build(env: Any, settings: dict[str, Any], seed: int) -> Any:
        import planners.policies as policies

        cls = getattr(policies, cls_name)
        if cls_name == "KMeansTspPlanner":
            return cls(seed=seed, **settings)
        return cls(**settings)

    return build


_RL_TRAINING = {"train_episodes": 20_000, "backend": "compiled"}
_TABULAR = {"learning_rate": 0.75, "discount": 0.99, "epsilon_start": 1.0, "epsilon_decay": 0.999, "epsilon_min": 0.001}

ALGORITHMS: dict[str, Algorithm] = {
    a.name: a
    for a in (
        Algorithm("q_learning", "Q-learning", "rl", {**_RL_TRAINING, **_TABULAR}, _rl("q_learning")),
        Algorithm("sarsa", "SARSA", "rl", {**_RL_TRAINING, **_TABULAR}, _rl("sarsa")),
        Algorithm("random", "random", "rl", {"train_episodes": 0, "backend": "compiled"}, _rl("random")),
        Algorithm(
            "kmeans_tsp",
            "k-means + TSP",
            "planner",
            {"k": None, "tsp_method": "auto", "tsp_time_limit_s": 60.0, "tour_costs": "auto", "ompl_time_limit_s": 0.2, "linger_steps": 2},
            _planner("KMeansTspPlanner"),
        ),
        Algorithm("lawnmower", "lawnmower", "planner", {"depth_cell": 0, "lane_spacing_cells": None, "linger_steps": 2}, _planner("LawnmowerPlanner")),
        Algorithm("greedy", "greedy", "planner", {"max_dwell_steps": 8}, _planner("GreedyPlanner")),
    )
}


def resolve_settings(name: str, settings: dict[str, Any]) -> dict[str, Any]:
    """The algorithm's defaults updated with ``settings``; unknown names and keys are errors."""
    if name not in ALGORITHMS:
        raise ConfigError(
            f"unknown algorithm {name!r}{did_you_mean(name, ALGORITHMS)}: choose one of {', '.join(ALGORITHMS)}",
            "algorithm",
        )
    defaults = ALGORITHMS[name].defaults
    unknown = sorted(set(settings) - set(defaults))
    if unknown:
        raise ConfigError(
            f"unknown setting {unknown[0]!r}{did_you_mean(unknown[0], defaults)} for algorithm {name!r}; "
            f"known: {', '.join(sorted(defaults))}",
            unknown[0],
        )
    out = dict(defaults)
    out.update(settings)
    if name in ("q_learning", "sarsa"):
        from rl import TabularConfig

        TabularConfig(**{k: out[k] for k in _TABULAR})  # validates the values, naming the key
    episodes = out.get("train_episodes", 0)
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 0:
        raise ConfigError(f"train_episodes = {episodes!r} must be a non-negative integer", "train_episodes")
    return out


def build_policy(name: str, env: Any, settings: dict[str, Any], seed: int) -> Any:
    """The trained or planning policy of algorithm ``name`` for ``env``."""
    algorithm = ALGORITHMS[name]
    assert algorithm.build is not None
    return algorithm.build(env, resolve_settings(name, settings), seed)


def labels() -> dict[str, str]:
    return {name: a.label for name, a in ALGORITHMS.items()}


__all__ = ["ALGORITHMS", "Algorithm", "build_policy", "labels", "resolve_settings"]
