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

To add an algorithm, add an :class:`Algorithm` to :data:`ALGORITHMS`: its settings (each
with its value under ``--quick``, when a smoke test should shrink it), a ``build`` function
and, when a task should record more than its episodes (a solver's bound and status), a
``record`` function. The validation tests, ``--quick`` and the runner pick it up from there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

from planners.optimal import BUDGETS
from swiptopt.errors import ConfigError, did_you_mean
from swiptopt.limits import check_size, limits, training_log_note
from swiptopt.validation import Spec, check_keys, check_value


@dataclass(frozen=True)
class Setting(Spec):
    """One setting of an algorithm: its default and what it may hold.

    ``limit`` names a :class:`swiptopt.limits.Limits` field that is the upper end;
    ``hi_of`` gives an upper end that depends on the scenario (``hi_doc`` says what it is);
    ``quick`` is the value under ``--quick`` (a smoke test): a number caps the setting, any
    other value replaces it, ``None`` leaves it as it is.
    """

    default: Any = None
    limit: str = ""
    hi_of: Callable[[Any], int] | None = None
    hi_doc: str = ""
    quick: Any = None

    def upper(self) -> float | None:
        """The upper end in force (the limit's current value where there is one)."""
        return getattr(limits(), self.limit) if self.limit else self.hi


@dataclass(frozen=True)
class Algorithm:
    """A named algorithm: its family, its settings, how to build it and what its tasks record.

    ``build(env, settings, seed)`` returns the policy (trained, for RL); ``record(policy,
    env)``, called after the evaluation, returns what the task stores beside its episodes
    (:func:`task_extra`).
    """

    name: str
    label: str
    family: str
    settings: dict[str, Setting] = field(default_factory=dict)
    build: Callable[[Any, dict[str, Any], int], Any] | None = None
    record: Callable[[Any, Any], dict[str, Any]] | None = None

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


def _planner(cls_name: str, *, seeded: bool = False) -> Callable[[Any, dict[str, Any], int], Any]:
    """Build ``planners.<cls_name>`` from the settings (and the task's seed when ``seeded``)."""

    def build(env: Any, settings: dict[str, Any], seed: int) -> Any:
        import planners

        cls = getattr(planners, cls_name)
        return cls(seed=seed, **settings) if seeded else cls(**settings)

    return build


def _milp(env: Any, settings: dict[str, Any], seed: int) -> Any:
    """The MILP's plan as a policy: the named budget, with the overrides that are set. The
    task's seed is not used: the solve is the same for every seed."""
    import dataclasses

    from planners.optimal import MilpPlanner

    overrides = {key: settings[key] for key in ("max_nodes", "time_limit_s") if settings[key] is not None}
    return MilpPlanner(budget=dataclasses.replace(BUDGETS[settings["budget"]], **overrides))


#: What the MILP's bound bounds (the tables' "bound" column): every policy's return with a
#: deterministic channel; with a stochastic one, the expected-rate relaxation of open-loop
#: walks only (see :mod:`planners.optimal`).
MILP_BOUND = "milp"
MILP_EXPECTED_BOUND = "milp (expected)"


def _milp_record(policy: Any, env: Any) -> dict[str, Any]:
    """The MILP's outcome under the keys a solver's task records (the tables read them):
    ``solver_status`` and ``solver_message``, ``best_return`` (the plan's value in the
    solver's model), ``bound_return`` with ``bound_label`` (what it bounds), ``solver_gap``,
    ``lp_bound_return``, ``solver_nodes``, ``solver_exact``, ``solver_time_limit_hit``."""
    from planners.service import step_model

    result = getattr(policy, "result_", None)
    if result is None:
        return {}
    out = {
        "solver_status": result.status,
        "solver_message": result.message,
        "best_return": result.objective,
        "bound_return": result.bound,
        "lp_bound_return": result.lp_bound,
        "solver_gap": result.gap,
        "solver_nodes": result.nodes,
        "solver_exact": result.exact,
        "solver_time_limit_hit": result.time_limit_hit,
    }
    if result.bound is not None and math.isfinite(result.bound):
        out["bound_label"] = MILP_BOUND if step_model(env.tables).exact else MILP_EXPECTED_BOUND
    else:
        out["bound_return"] = None
    return out


_STEPS = 1_000_000  # the longest episode a scenario allows: no step count beyond it means anything

_RL_TRAINING = {
    "train_episodes": Setting(default=20_000, kind="int", lo=0, limit="max_training_episodes", quick=2000,
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
                # the defaults are planners.RewardKMeansTspPlanner's; the old behaviour is
                # selection = "coverage", dwell = "convex", linger_steps = 2
                "selection": Setting(default="reward", kind="str", choices=("reward", "coverage"),
                                     doc="hover points: 'reward' (every K up to k_max, each walk scored by the "
                                         "simulator's reward) or 'coverage' (the old rule: the fewest groups that "
                                         "fit the cone)"),
                "dwell": Setting(default="steps", kind="str", choices=("steps", "convex"),
                                 doc="dwell: 'steps' (whole steps by marginal reward) or 'convex' (the old convex "
                                     "dwell/split program)"),
                "k": Setting(default=None, kind="int", lo=1, optional=True, hi_of=lambda s: s.n_nodes,
                             hi_doc="n_nodes", doc="hover groups (default: chosen by the selection rule)"),
                "k_max": Setting(default=12, kind="int", lo=1, hi=100,
                                 doc="largest K the reward selection tries"),
                "tsp_method": Setting(default="auto", kind="str", choices=("auto", "exact", "routing"),
                                      doc="TSP solver (coverage selection, or tours over 12 stops)"),
                "tsp_time_limit_s": Setting(default=60.0, lo=0, lo_open=True, hi=3600, unit="s",
                                            doc="TSP wall-clock safety net (the search stops on a deterministic budget)"),
                "tour_costs": Setting(default="auto", kind="str", choices=("auto", "euclidean", "grid", "ompl"),
                                      doc="costs between stops (coverage selection, or tours over 12 stops)"),
                "ompl_time_limit_s": Setting(default=0.2, lo=0, lo_open=True, hi=600, unit="s", quick=0.05,
                                             doc="OMPL time limit per pair of stops"),
                "linger_steps": Setting(default=0, kind="int", lo=0, hi=_STEPS,
                                        doc="extra hover steps while covered nodes hold data (the old planner: 2)"),
            },
            _planner("RewardKMeansTspPlanner", seeded=True),
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
        Algorithm("rate_greedy", "rate-greedy", "planner", {}, _planner("RateGreedyPlanner")),
        Algorithm(
            "milp",
            "MILP",
            "planner",
            {
                "budget": Setting(default="default", kind="str", choices=tuple(BUDGETS), quick="quick",
                                  doc="named search budget of planners.optimal.BUDGETS (deterministic limits)"),
                "max_nodes": Setting(default=None, kind="int", lo=1, hi=10**9, optional=True, quick=1,
                                     doc="branch-and-bound nodes (default: the budget's)"),
                "time_limit_s": Setting(default=None, lo=0, lo_open=True, hi=7 * 86_400, optional=True, unit="s",
                                        doc="wall-clock safety net (default: the budget's); a task that hits it "
                                            "records so, as its result then depends on the machine's speed"),
            },
            _milp,
            _milp_record,
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


def quick_settings(name: str, settings: dict[str, Any]) -> dict[str, Any]:
    """``settings`` shrunk for a smoke test (``--quick``): each setting with a ``quick`` value
    capped at it (numbers) or replaced by it (anything else)."""
    resolved = resolve_settings(name, settings)
    out = dict(settings)
    for key, spec in ALGORITHMS[name].settings.items():
        value = resolved[key]
        if spec.quick is None or value is None:
            continue
        numeric = spec.kind in ("int", "float")
        out[key] = min(value, spec.quick) if numeric else spec.quick
    return out


def task_extra(name: str, policy: Any, env: Any) -> dict[str, Any]:
    """What a task of algorithm ``name`` records beside its episodes, from the evaluated
    policy (empty for algorithms without a ``record``)."""
    record = ALGORITHMS[name].record
    return record(policy, env) if record is not None else {}


def build_policy(name: str, env: Any, settings: dict[str, Any], seed: int) -> Any:
    """The trained or planning policy of algorithm ``name`` for ``env``."""
    algorithm = ALGORITHMS[name]
    assert algorithm.build is not None
    return algorithm.build(env, resolve_settings(name, settings), seed)


def labels() -> dict[str, str]:
    return {name: a.label for name, a in ALGORITHMS.items()}


__all__ = [
    "ALGORITHMS",
    "MILP_BOUND",
    "MILP_EXPECTED_BOUND",
    "Algorithm",
    "Setting",
    "build_policy",
    "check_settings_for",
    "labels",
    "quick_settings",
    "resolve_settings",
    "task_extra",
]
