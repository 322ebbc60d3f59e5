"""The algorithms a benchmark can run, by name, with their settings declared and validated.

This is the benchmark layer: it may import ``rl`` and ``planners`` (the model modules below
it never do). Each algorithm turns (environment, settings, seed) into a policy ready for
:func:`swiptopt.evaluate`: RL agents are trained first (the paper's protocol), planners plan
when the evaluation begins its episodes.

Every algorithm declares its settings: a :class:`Setting` per key with its default, type
and range or choices. :func:`resolve_settings` checks an experiment's settings against that
schema (one function for every algorithm) and :func:`check_settings_for` checks the bounds
that depend on the scenario, so an experiment refuses a bad value before any task runs,
naming the experiment's key (``algorithms.kmeans_tsp.tsp_time_limit_s``), never the
parameter of the function it ends up in.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from swiptopt.errors import ConfigError, did_you_mean
from swiptopt.limits import check_size, limits, training_log_note
from swiptopt.validation import Spec, check_keys, check_value


@dataclass(frozen=True)
class Setting(Spec):
    """One setting of an algorithm: its default and what it may hold.

    ``limit`` names a :class:`swiptopt.limits.Limits` field that is the upper end;
    ``hi_of`` gives an upper end that depends on the scenario (``hi_doc`` says what it is).
    """

    default: Any = None
    limit: str = ""
    hi_of: Callable[[Any], int] | None = None
    hi_doc: str = ""

    def upper(self) -> float | None:
        """The upper end in force (the limit's current value where there is one)."""
        return getattr(limits(), self.limit) if self.limit else self.hi


@dataclass(frozen=True)
class Algorithm:
    """A named algorithm: its family, its settings and how to build it."""

    name: str
    label: str
    family: str
    settings: dict[str, Setting] = field(default_factory=dict)
    build: Callable[[Any, dict[str, Any], int], Any] | None = None

    @property
    def defaults(self) -> dict[str, Any]:
        return {key: s.default for key, s in self.settings.items()}


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


_STEPS = 1_000_000  # the longest episode a scenario allows: no step count beyond it means anything

_RL_TRAINING = {
    "train_episodes": Setting(default=20_000, kind="int", lo=0, limit="max_training_episodes",
                              doc="training episodes before the greedy evaluation"),
    "backend": Setting(default="compiled", kind="str", choices=("python", "compiled"),
                       doc="training loop: the compiled kernel or the plain Gymnasium loop"),
}
_TABULAR = {
    "learning_rate": Setting(default=0.75, lo=0, lo_open=True, hi=1, doc="TD step size"),
    "discount": Setting(default=0.99, lo=0, hi=1, doc="discount factor gamma"),
    "epsilon_start": Setting(default=1.0, lo=0, hi=1, doc="exploration probability of the first episode"),
    "epsilon_decay": Setting(default=0.999, lo=0, lo_open=True, hi=1, doc="epsilon factor per episode"),
    "epsilon_min": Setting(default=0.001, lo=0, hi=1, doc="floor of epsilon"),
}
_LINGER = Setting(default=2, kind="int", lo=0, hi=_STEPS, doc="extra hover steps while covered nodes hold data")

ALGORITHMS: dict[str, Algorithm] = {
    a.name: a
    for a in (
        Algorithm("q_learning", "Q-learning", "rl", {**_RL_TRAINING, **_TABULAR}, _rl("q_learning")),
        Algorithm("sarsa", "SARSA", "rl", {**_RL_TRAINING, **_TABULAR}, _rl("sarsa")),
        Algorithm("random", "random", "rl", {**_RL_TRAINING, "train_episodes": Setting(
            default=0, kind="int", lo=0, limit="max_training_episodes", doc="ignored: the random agent learns nothing",
        )}, _rl("random")),
        Algorithm(
            "kmeans_tsp",
            "k-means + TSP",
            "planner",
            {
                "k": Setting(default=None, kind="int", lo=1, optional=True, hi_of=lambda s: s.n_nodes,
                             hi_doc="n_nodes", doc="hover groups (default: the fewest that fit the cone)"),
                "tsp_method": Setting(default="auto", kind="str", choices=("auto", "exact", "routing"),
                                      doc="TSP solver"),
                "tsp_time_limit_s": Setting(default=60.0, lo=0, lo_open=True, hi=3600, unit="s",
                                            doc="TSP wall-clock safety net (the search stops on a deterministic budget)"),
                "tour_costs": Setting(default="auto", kind="str", choices=("auto", "euclidean", "grid", "ompl"),
                                      doc="costs between stops"),
                "ompl_time_limit_s": Setting(default=0.2, lo=0, lo_open=True, hi=600, unit="s",
                                             doc="OMPL time limit per pair of stops"),
                "linger_steps": _LINGER,
            },
            _planner("KMeansTspPlanner"),
        ),
        Algorithm(
            "lawnmower",
            "lawnmower",
            "planner",
            {
                "depth_cell": Setting(default=0, kind="int", lo=0, hi_of=lambda s: s.grid_shape[2] - 1,
                                      hi_doc="the grid's depth cells - 1", doc="depth of the survey, cells"),
                "lane_spacing_cells": Setting(default=None, kind="int", lo=1, hi=100_000, optional=True,
                                              doc="lane spacing, cells (default: the cone's footprint)"),
                "linger_steps": _LINGER,
            },
            _planner("LawnmowerPlanner"),
        ),
        Algorithm(
            "greedy", "greedy", "planner",
            {"max_dwell_steps": Setting(default=8, kind="int", lo=1, hi=_STEPS, doc="hover steps before giving up on a node")},
            _planner("GreedyPlanner"),
        ),
    )
}


def _where(name: str, key: str) -> str:
    return f"algorithms.{name}.{key}"


def resolve_settings(name: str, settings: dict[str, Any]) -> dict[str, Any]:
    """The algorithm's defaults updated with ``settings``, each value checked against the
    algorithm's schema and normalised; an unknown algorithm, key or value is a
    :class:`ConfigError` naming the experiment's key and what is allowed."""
    if not isinstance(name, str) or name not in ALGORITHMS:
        raise ConfigError(
            f"unknown algorithm {name!r}{did_you_mean(name, ALGORITHMS)}: choose one of {', '.join(ALGORITHMS)}",
            "algorithm",
        )
    schema = ALGORITHMS[name].settings
    settings = check_keys(f"algorithms.{name}", settings, name)
    unknown = sorted(set(settings) - set(schema))
    if unknown:
        raise ConfigError(
            f"unknown setting {unknown[0]!r}{did_you_mean(unknown[0], schema)} for algorithm {name!r}; "
            f"known: {', '.join(sorted(schema))}",
            unknown[0],
        )
    out = {}
    for key, spec in schema.items():
        value = settings.get(key, spec.default)
        out[key] = check_value(_where(name, key), value, spec, field=key)
        if spec.limit and out[key] is not None:
            note = training_log_note(out[key]) if spec.limit == "max_training_episodes" else ""
            check_size(spec.limit, out[key], _where(name, key), key, note=note)
    return out


def check_settings_for(name: str, settings: dict[str, Any], scenario: Any, where: str = "") -> None:
    """Check the settings whose range depends on the scenario (a grid depth, a node count).

    ``settings`` are resolved (:func:`resolve_settings`); ``where`` says which scenario (a
    sweep point) for the message.
    """
    for key, spec in ALGORITHMS[name].settings.items():
        value = settings.get(key)
        if spec.hi_of is None or value is None:
            continue
        hi = spec.hi_of(scenario)
        if not spec.in_range(value, hi):
            raise ConfigError(
                f"{_where(name, key)} = {value!r} is out of range{where}: must be {spec.allowed(hi)} "
                f"(at most {spec.hi_doc})",
                key,
            )


def build_policy(name: str, env: Any, settings: dict[str, Any], seed: int) -> Any:
    """The trained or planning policy of algorithm ``name`` for ``env``."""
    algorithm = ALGORITHMS[name]
    assert algorithm.build is not None
    return algorithm.build(env, resolve_settings(name, settings), seed)


def labels() -> dict[str, str]:
    return {name: a.label for name, a in ALGORITHMS.items()}


__all__ = ["ALGORITHMS", "Algorithm", "Setting", "build_policy", "check_settings_for", "labels", "resolve_settings"]
