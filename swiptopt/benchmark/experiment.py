"""Experiments: scenarios, a sweep, algorithms, layouts, seeds and episodes, as TOML.

An experiment expands into tasks, one per (scenario, algorithm, seed); a task's key is a
hash of its fully resolved configuration (every scenario field, every algorithm setting,
the seed, the episode count), so the results store recognises finished work whatever file
or command produced it. Experiments are validated like scenarios: unknown keys, wrong
types and out-of-range values are errors that name the key. All of it is checked when an
:class:`Experiment` is built, so nothing runs before the check: every algorithm setting
against the algorithm's schema (:mod:`swiptopt.benchmark.algorithms`), every sweep point's
scenario, sweep values that would repeat a point, the name (it names files, so letters,
digits, ``-``, ``_`` and ``.`` only), and the sizes of :mod:`swiptopt.limits` (tasks and
evaluation episodes, and each scenario's grid).

File format::

    name = "my-sweep"
    world = "grid"       # optional: "grid" (the paper's, the default) or "continuous"
    layouts = 5          # layout seeds 0..4 per sweep point, or a list: layouts = [50, 51, 52]
    seeds = 1            # training/evaluation seeds per layout
    episodes = 10        # greedy evaluation episodes per task
    training_layouts = [100, 101, 102]   # optional: where algorithms that learn across
                                         # layouts train (or {start = 100, count = 50})

    [scenario]           # a preset and Scenario overrides
    preset = "paper"
    n_nodes = 25

    [sweep]              # optional: Scenario fields, or algorithm settings, and their values
    n_nodes = [10, 20, 30]

    [algorithms.q_learning]      # one table per algorithm, with its settings
    train_episodes = 20000
    [algorithms.greedy]

    [figure]             # optional: what `swiptopt plot` draws
    metric = "data_bits"

A sweep key is a Scenario field or a setting of some of the experiment's algorithms
(``timesteps = [62500, 250000, 1000000]`` trains every deep-RL algorithm at each budget: a
learning curve); a swept setting applies to the algorithms that have it, and the others'
tasks are the same at every point (computed once).

``budgets = {ppo = [62500, 250000, 1000000], stop_ppo = [25000, 100000]}`` runs each named
algorithm at every budget of its list, a row each (``PPO @ 250,000``): a learning curve,
each algorithm on its own scale. A budget sets deep RL's ``timesteps`` or, for an algorithm
without it (tabular RL), its ``train_episodes`` (:data:`BUDGET_SETTINGS`). A training run
serves every budget of its lineage where the shorter run's model is a checkpoint of the
longer one (:func:`rl.deep.checkpoint_exact`), so a curve costs about its longest budget.
A curve runs at one point: with ``budgets``, each swept setting lists one value (a curve's
table and figure have one line per algorithm; write a file per point).

A top-level ``baseline = "random"`` (one of the experiment's algorithms) adds a second
table: every other algorithm's mean over the baseline's on the same layouts, with a
bootstrap confidence interval and the number of layouts won.

Layouts: ``layouts`` is a count (layout seeds 0 .. N-1) or a list of distinct layout seeds
in [0, :data:`MAX_LAYOUT`]. ``training_layouts`` (a list, or ``{start, count}``) is where
algorithms with ``training = "across_layouts"`` (deep RL) train one model per training
seed, evaluated on every evaluation layout; it is required when such an algorithm is in the
experiment and refused otherwise (it would do nothing). It may overlap the evaluation
layouts (the ``compare`` suite trains on the very layouts it evaluates, as the tabular
agents do); held-out layouts (the ``generalisation`` experiment) measure generalisation.

Seeds: a task's seed is ``1000 x layout + s`` for s in 0 .. seeds-1; an algorithm with a
``training_seeds`` setting (deep RL) runs that many seeds per layout instead of ``seeds``.

Worlds: ``world`` (top-level, :mod:`swiptopt.worlds`) says where every task runs: the
paper's grid, or the continuous world (a continuous position, velocity commands, motion
stopped by obstacles; the ``harbour`` suite). Each algorithm declares the worlds it runs in
(the tabular agents, DQN and the grid planners: the grid; SAC and the continuous planners:
the continuous world; PPO and random: both), and an experiment naming one outside its
world is refused before any task runs. A grid task's key is what it was before worlds
existed; a continuous task's key includes its world.

Plugins: ``[plugins] a2c = "my_module:factory"`` registers an algorithm from outside the
project for this experiment (:mod:`swiptopt.benchmark.algorithms`); ``[algorithms.a2c]``
then runs it. Loading one imports the module and calls the factory, so a file's
``[plugins]`` is honoured only with the user's consent (``allow_plugins=True``: the CLI's
``--allow-plugins``); without it the file is refused before anything is imported. An
experiment built in Python (``Experiment(..., plugins=...)``) loads its plugins.

Stored experiments: a run records its configuration (:meth:`Experiment.to_dict`) and
:meth:`Experiment.record` (the order of its algorithms, sweep keys and budgets, and the
resolved settings of every algorithm that is not built in). :meth:`Experiment.from_stored`
rebuilds it from those alone: reading a store imports and calls nothing it names.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from swiptopt.benchmark.algorithms import (
    ACROSS_LAYOUTS,
    ALGORITHMS,
    EXPANSION_SETTINGS,
    TRAINING,
    TRAINING_SEEDS,
    check_setting,
    check_settings_for,
    check_world_of,
    get_algorithm,
    load_plugin,
    quick_settings,
    resolve_settings,
)
from swiptopt.benchmark.algorithms import PER_LAYOUT as PER_LAYOUT_TRAINING
from swiptopt.errors import ConfigError, did_you_mean
from swiptopt.limits import check_size
from swiptopt.metrics import EPISODE_METRICS
from swiptopt.scenario import Scenario, ScenarioError
from swiptopt.tomlfile import read_toml
from swiptopt.validation import Spec, check_keys, check_value
from swiptopt.worlds import CONTINUOUS, GRID, check_world

#: Task seeds of one layout: layout L's tasks have seeds SEEDS_PER_LAYOUT * L + 0, 1, ...
SEEDS_PER_LAYOUT = 1000

TOP_KEYS = {"name", "description", "layouts", "seeds", "episodes", "scenario", "sweep", "algorithms", "figure",
            "baseline", "training_layouts", "plugins", "world", "budgets"}
#: The settings a learning curve's budgets may set, the first an algorithm has: deep RL's
#: training steps, else tabular RL's training episodes.
BUDGET_SETTINGS = ("timesteps", "train_episodes")
#: The most budgets one algorithm's curve may list.
MAX_BUDGETS = 32
#: The largest layout seed an experiment names: a task's seed, 1000 x layout + s, and its
#: evaluation seeds then stay below 2**32 (what NumPy's and torch's legacy seeding take).
MAX_LAYOUT = 1_000_000
#: The most layouts one list may name.
MAX_LAYOUTS = 100_000
FIGURE_KEYS = {"metric", "x", "title", "ylabel", "xlabel"}


#: The counts of an experiment. A task's seed is 1000 x layout + seed index, so more than
#: 1000 seeds per layout would give two tasks one seed.
_COUNTS = {
    "layouts": Spec(kind="int", lo=1, hi=100_000),
    "seeds": Spec(kind="int", lo=1, hi=SEEDS_PER_LAYOUT),
    "episodes": Spec(kind="int", lo=1, hi=100_000),
}


@dataclass(frozen=True)
class Task:
    """One unit of work: train (if RL) and evaluate one algorithm on one scenario and seed."""

    experiment: str
    scenario: dict[str, Any]
    algorithm: str
    settings: dict[str, Any]
    seed: int
    episodes: int
    point: dict[str, Any]
    """The sweep values of this task (empty without a sweep)."""
    training_layouts: tuple[int, ...] | list[int] | None = None
    """Where the task's model was trained, for an algorithm that trains across layouts."""
    plugin: str = ""
    """The factory of a plugin algorithm (``package.module:function``), from ``[plugins]``."""
    world: str = GRID
    """The world the task runs in (:mod:`swiptopt.worlds`)."""
    budget: int | None = None
    """The learning-curve budget this task is a point of (its ``timesteps`` or, for tabular
    RL, ``train_episodes``), if any."""

    @property
    def row(self) -> str:
        """The table row the task belongs to: its algorithm, at its budget if it has one."""
        return self.algorithm if self.budget is None else budget_row(self.algorithm, self.budget)

    @property
    def key(self) -> str:
        """Hash of everything that determines the result (not the experiment's name). The
        training layouts, the plugin's factory and a world other than the grid enter it only
        when set, so the keys of tasks without them are those of earlier versions."""
        content: dict[str, Any] = {"scenario": self.scenario, "algorithm": self.algorithm, "settings": self.settings,
                                   "seed": self.seed, "episodes": self.episodes}
        if self.training_layouts is not None:
            content["training_layouts"] = list(self.training_layouts)
        if self.plugin:
            content["plugin"] = self.plugin
        if self.world != GRID:
            content["world"] = self.world
        payload = json.dumps(content, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(payload.encode()).hexdigest()

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class Experiment:
    """A validated experiment; :meth:`tasks` expands it."""

    name: str
    scenario: dict[str, Any]
    algorithms: dict[str, dict[str, Any]]
    sweep: dict[str, list[Any]] = field(default_factory=dict)
    layouts: int | tuple[int, ...] = 5
    """A count (layout seeds 0 .. N-1) or the layout seeds themselves."""
    seeds: int = 1
    episodes: int = 10
    figure: dict[str, Any] = field(default_factory=dict)
    description: str = ""
    baseline: str = ""
    """An algorithm of the experiment that the others are compared with, layout by layout."""
    training_layouts: tuple[int, ...] | None = None
    """Where algorithms that train across layouts train (``None``: none do)."""
    plugins: dict[str, str] = field(default_factory=dict)
    """Algorithms from outside the project: name -> ``package.module:factory``."""
    world: str = GRID
    """The world every task runs in (:mod:`swiptopt.worlds`): ``"grid"`` or ``"continuous"``."""
    budgets: dict[str, list[int]] = field(default_factory=dict)
    """Learning curves: algorithm -> the ``timesteps`` it runs at, a row each."""
    recorded_settings: dict[str, dict[str, Any]] = field(default_factory=dict, compare=False, repr=False)
    """Algorithms taken as a results store recorded them (:meth:`from_stored`), never looked
    up, imported or called: name -> ``{"settings": resolved settings, "sweep": {setting:
    its swept values, normalised}}`` (:meth:`record`). Not part of :meth:`to_dict`."""

    def __post_init__(self) -> None:
        _check_name(self.name)
        for name, entry in self.recorded_settings.items():
            if not _is_recorded_entry(entry):
                raise ConfigError(f"recorded settings of {name!r} must be {{'settings': {{...}}, 'sweep': {{...}}}}",
                                  "recorded_settings")
        object.__setattr__(self, "world", check_world(self.world))
        for key in ("description", "baseline"):
            if not isinstance(getattr(self, key), str):
                raise ConfigError(f"{key} = {getattr(self, key)!r} must be a string", key)
        if isinstance(self.layouts, (list, tuple)):
            object.__setattr__(self, "layouts", _check_layout_list("layouts", self.layouts))
            counts = {k: v for k, v in _COUNTS.items() if k != "layouts"}
        else:
            counts = _COUNTS
        for key, spec in counts.items():
            object.__setattr__(self, key, check_value(key, getattr(self, key), spec))
        scenario = check_keys("[scenario]", self.scenario, "scenario")
        if "layout_seed" in scenario:
            raise ConfigError("scenario.layout_seed cannot be set: layouts are set by 'layouts'", "layout_seed")
        if "world" in scenario:
            _misplaced_world("scenario.world")
        resolved = self._check_algorithms()
        self._check_training_layouts(resolved)
        self._check_budgets()
        if self.baseline and self.baseline not in resolved:
            raise ConfigError(
                f"baseline = {self.baseline!r} is not one of the experiment's algorithms ({', '.join(resolved)})",
                "baseline",
            )
        self._check_sweep()
        self._check_figure()
        self._check_sizes(resolved)
        self._check_points(resolved)

    def _check_algorithms(self) -> dict[str, dict[str, Any]]:
        """Check the plugins (loading those not taken as recorded) and the algorithms: their
        settings and worlds; returns each algorithm's resolved settings."""
        plugins = check_keys("[plugins]", self.plugins, "plugins")
        algorithms = check_keys("[algorithms]", self.algorithms, "algorithms")
        if not algorithms:
            raise ConfigError("an experiment needs at least one algorithm in [algorithms]", "algorithms")
        unused = sorted(set(plugins) - set(algorithms))
        if unused:
            raise ConfigError(f"plugins.{unused[0]} is registered but not run: add [algorithms.{unused[0]}] or "
                              "remove it", "plugins")
        for name, source in plugins.items():
            if name not in self.recorded_settings:
                load_plugin(name, source)
        object.__setattr__(self, "plugins", plugins)
        for name, settings in algorithms.items():
            if isinstance(settings, dict) and "world" in settings:
                _misplaced_world(f"algorithms.{name}.world")
        resolved = {name: self._resolve(name, settings) for name, settings in algorithms.items()}
        for name in algorithms:
            if name not in self.recorded_settings:
                check_world_of(name, self.world)
        return resolved

    def _check_sizes(self, resolved: dict[str, dict[str, Any]]) -> None:
        """The number of tasks and of evaluation episodes against :mod:`swiptopt.limits`."""
        n_points = math.prod(len(v) for v in self.sweep.values())
        n_layouts = len(self.layout_seeds())
        runs = sum(self.seeds_of(settings) * len(self.budgets.get(name, [None])) for name, settings in resolved.items())
        n_tasks = n_points * n_layouts * runs
        check_size(
            "max_tasks", n_tasks,
            f"tasks ({n_points:,} sweep points x {n_layouts:,} layouts x {runs:,} (algorithm, seed) pairs)",
            "sweep" if n_points > 1 else "layouts",
        )
        check_size("max_evaluation_episodes", n_tasks * self.episodes,
                   f"evaluation episodes ({n_tasks:,} tasks x episodes = {self.episodes:,})", "episodes")

    def _check_points(self, resolved: dict[str, dict[str, Any]]) -> None:
        """Every scenario of the sweep now, so a bad value fails before any work, with each
        algorithm's settings there; a point that resolves to the same scenario as another
        would be counted twice."""
        keys = list(self.sweep)
        seen: dict[str, tuple[int, ...]] = {}
        for index in itertools.product(*(range(len(self.sweep[k])) for k in keys)):
            point = {k: self.sweep[k][i] for k, i in zip(keys, index)}
            built = self.scenario_for(point, self.layout_seeds()[0])
            where = f" at sweep point {point}" if point else ""
            for name in resolved:
                if name not in self.recorded_settings:
                    check_settings_for(name, self.settings_at(name, point), built, where)
            fingerprint = json.dumps([built.to_dict(), self._split(point)[1]], sort_keys=True)
            if fingerprint in seen:
                key, i, j = next((k, i, j) for k, i, j in zip(keys, seen[fingerprint], index) if i != j)
                a, b = self.sweep[key][i], self.sweep[key][j]
                same = (f"lists {a!r} twice" if repr(a) == repr(b)
                        else f"lists {a!r} and {b!r}, which give the same scenario")
                raise ConfigError(f"sweep.{key} {same}: remove the duplicate", key)
            seen[fingerprint] = index

    def _check_training_layouts(self, resolved: dict[str, dict[str, Any]]) -> None:
        swept = self.sweep.get(TRAINING) if isinstance(self.sweep, dict) else None
        across = [name for name, settings in resolved.items() if settings.get(TRAINING) == ACROSS_LAYOUTS
                  or (TRAINING in settings and isinstance(swept, list) and ACROSS_LAYOUTS in swept)]
        value = self.training_layouts
        if value is None:
            if across:
                raise ConfigError(
                    f"algorithms.{across[0]}.training = {ACROSS_LAYOUTS!r} needs training_layouts: a list of layout "
                    "seeds, or {start = ..., count = ...}",
                    "training_layouts",
                )
            return
        if not across and not self.recorded_settings:
            raise ConfigError(
                f"training_layouts is set but no algorithm trains across layouts: set training = {ACROSS_LAYOUTS!r} "
                "on a deep-RL algorithm, or remove training_layouts",
                "training_layouts",
            )
        if isinstance(value, dict):
            table = check_keys("training_layouts", value, "training_layouts")
            if set(table) != {"start", "count"}:
                raise ConfigError(f"training_layouts = {value!r} must be a list of layout seeds or a table with "
                                  "exactly 'start' and 'count'", "training_layouts")
            start = check_value("training_layouts.start", table["start"], Spec(kind="int", lo=0, hi=MAX_LAYOUT),
                                field="training_layouts")
            count = check_value("training_layouts.count", table["count"], Spec(kind="int", lo=1, hi=MAX_LAYOUTS),
                                field="training_layouts")
            if start + count - 1 > MAX_LAYOUT:
                raise ConfigError(f"training_layouts = {value!r} reaches past the largest layout seed, {MAX_LAYOUT:,}",
                                  "training_layouts")
            value = list(range(start, start + count))
        object.__setattr__(self, "training_layouts", _check_layout_list("training_layouts", value))

    def _check_budgets(self) -> None:
        budgets = check_keys("budgets", self.budgets, "budgets")
        out = {}
        for name, values in budgets.items():
            if name not in self.algorithms:
                raise ConfigError(f"budgets.{name}: {name!r} is not one of the experiment's algorithms "
                                  f"({', '.join(self.algorithms)})", "budgets")
            setting = self.budget_setting(name)
            if setting is None:
                raise ConfigError(f"budgets.{name}: {name} has no {' or '.join(map(repr, BUDGET_SETTINGS))} setting "
                                  "to run at budgets (deep and tabular RL have)", "budgets")
            if name in self.recorded_settings:  # checked against the algorithm's own when it ran
                spec = Spec(kind="int", lo=1)
            else:
                spec = get_algorithm(name, self.plugins.get(name, "")).settings[setting]
            if not isinstance(values, list) or not 1 <= len(values) <= MAX_BUDGETS:
                raise ConfigError(f"budgets.{name} = {values!r} must be a list of 1 to {MAX_BUDGETS} values of "
                                  f"{setting}", "budgets")
            checked = [check_setting(f"budgets.{name}[{i}]", v, spec, "budgets") for i, v in enumerate(values)]
            if len(set(checked)) < len(checked) or checked != sorted(checked):
                raise ConfigError(f"budgets.{name} = {values!r} must list distinct values of {setting} in "
                                  "increasing order", "budgets")
            if setting in self.algorithms[name] or setting in self.sweep:
                raise ConfigError(f"budgets.{name} and {setting} set elsewhere: the budgets set it", "budgets")
            out[name] = checked
        sweep = self.sweep if isinstance(self.sweep, dict) else {}  # a malformed sweep is refused later
        points = math.prod(len(v) for v in sweep.values() if isinstance(v, list))
        if out and points > 1:
            # the curve's table and figure have one line per algorithm, so they would show one
            # point's and hide the others'
            raise ConfigError(f"budgets with a sweep of {points} points: a learning curve runs at one point; "
                              "write one experiment file per point (a sweep with one value each)", "budgets")
        object.__setattr__(self, "budgets", out)

    def budget_setting(self, name: str) -> str | None:
        """The setting algorithm ``name``'s learning-curve budgets set (:data:`BUDGET_SETTINGS`),
        or None if it has neither."""
        names = self._setting_names(name)
        return next((setting for setting in BUDGET_SETTINGS if setting in names), None)

    def budget_unit(self, name: str) -> str:
        """What algorithm ``name``'s learning-curve budgets count: ``episodes`` (tabular RL,
        whose budgets set ``train_episodes``), ``decisions`` (a stop-choosing agent, the
        fleet's too: a stop and its dwell, several steps) or ``steps``."""
        if self.budget_setting(name) == "train_episodes":
            return "episodes"
        return training_unit(name)

    def rows(self) -> list[tuple[str, str, int | None]]:
        """The table's rows in order: (row name, algorithm, budget); an algorithm with
        budgets has a row per budget."""
        out = []
        for name in self.algorithms:
            if name in self.budgets:
                out += [(budget_row(name, b), name, b) for b in self.budgets[name]]
            else:
                out.append((name, name, None))
        return out

    def layout_seeds(self) -> tuple[int, ...]:
        """The evaluation layouts' seeds."""
        return tuple(range(self.layouts)) if isinstance(self.layouts, int) else tuple(self.layouts)

    def seeds_of(self, settings: dict[str, Any]) -> int:
        """Seeds per layout of an algorithm with these resolved settings: its
        ``training_seeds`` where it has that setting, else the experiment's ``seeds``."""
        return int(settings.get(TRAINING_SEEDS) or self.seeds)

    def _check_sweep(self) -> None:
        sweep = check_keys("[sweep]", self.sweep, "sweep")
        names = {f.name for f in dataclasses.fields(Scenario)}
        settings = self._swept_settings_of()
        for key, values in sweep.items():
            if key == "world":
                raise ConfigError("sweep.world: a sweep cannot change the world; run one experiment per world "
                                  "(world = ... at the top of each file)", "world")
            if key == "layout_seed" or (key not in names and key not in settings):
                known = sorted(names - {"layout_seed"} | set(settings))
                raise ConfigError(
                    f"sweep key {key!r}{did_you_mean(key, known)} is neither a scenario field nor a setting of the "
                    "experiment's algorithms (layouts are set by 'layouts')",
                    key,
                )
            if key in names and key in settings:
                raise ConfigError(f"sweep key {key!r} is both a scenario field and a setting of "
                                  f"{', '.join(settings[key])}: it cannot be swept", key)
            if not isinstance(values, list) or not values:
                raise ConfigError(f"sweep.{key} must be a non-empty list of values", key)
            for value in values if key in settings else ():
                for name in settings[key]:
                    if name in self.recorded_settings:
                        continue
                    try:
                        resolve_settings(name, {**self.algorithms[name], key: value}, self.world)
                    except ConfigError as exc:
                        raise ConfigError(f"sweep.{key} = {value!r} for {name}: {exc}", key) from None

    def _swept_settings_of(self) -> dict[str, list[str]]:
        """Setting name -> the experiment's algorithms that have it (the sweep keys that
        are settings apply to those)."""
        out: dict[str, list[str]] = {}
        for name in self.algorithms:
            for key in self._setting_names(name):
                out.setdefault(key, []).append(name)
        return out

    def _setting_names(self, name: str) -> list[str]:
        """The names of algorithm ``name``'s settings (as recorded, for one taken from a store)."""
        recorded = self.recorded_settings.get(name)
        if recorded is not None:
            return list(dict.fromkeys([*recorded["settings"], *recorded["sweep"]]))
        return list(get_algorithm(name, self.plugins.get(name, "")).settings)

    def _resolve(self, name: str, settings: dict[str, Any]) -> dict[str, Any]:
        """Algorithm ``name``'s ``settings`` resolved (as recorded, for one taken from a store)."""
        recorded = self.recorded_settings.get(name)
        if recorded is not None:
            return dict(recorded["settings"])
        return resolve_settings(name, settings, self.world)

    def _split(self, point: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
        """A sweep point's scenario fields and its algorithm settings."""
        names = {f.name for f in dataclasses.fields(Scenario)}
        return ({k: v for k, v in point.items() if k in names}, {k: v for k, v in point.items() if k not in names})

    def settings_at(self, name: str, point: dict[str, Any]) -> dict[str, Any]:
        """Algorithm ``name``'s settings at sweep point ``point``, resolved (the point's
        settings that the algorithm has override the experiment's)."""
        recorded = self.recorded_settings.get(name)
        if recorded is not None:
            out = dict(recorded["settings"])
            for key, values in recorded["sweep"].items():
                if key in point and key in self.sweep and len(values) == len(self.sweep[key]):
                    out[key] = values[self.sweep[key].index(point[key])]
            return out
        schema = get_algorithm(name, self.plugins.get(name, "")).settings
        swept = {k: v for k, v in self._split(point)[1].items() if k in schema}
        return resolve_settings(name, {**self.algorithms[name], **swept}, self.world)

    def _check_figure(self) -> None:
        figure = check_keys("[figure]", self.figure, "figure")
        unknown = sorted(set(figure) - FIGURE_KEYS)
        if unknown:
            raise ConfigError(f"unknown figure key {unknown[0]!r}; known: {', '.join(sorted(FIGURE_KEYS))}", unknown[0])
        for key, value in figure.items():
            if not isinstance(value, str):
                raise ConfigError(f"figure.{key} = {value!r} must be a string", key)
        metric = figure.get("metric")
        if metric is not None and metric not in EPISODE_METRICS:
            raise ConfigError(f"figure.metric = {metric!r} is not a metric: choose one of "
                              f"{', '.join(EPISODE_METRICS)}", "metric")
        if figure and not self.sweep:
            raise ConfigError("[figure] needs a [sweep]: a figure draws a metric against a swept value", "figure")
        x = figure.get("x")
        if x is not None and x not in self.sweep:
            raise ConfigError(f"figure.x = {x!r} is not swept: choose one of the sweep's keys "
                              f"({', '.join(self.sweep)})", "x")

    # ------------------------------------------------------------ construction

    @staticmethod
    def _fields(data: Any) -> dict[str, Any]:
        """The constructor's arguments from a table of an experiment file's keys (checked
        for unknown keys and tables of the wrong kind; nothing imported)."""
        data = check_keys("an experiment", data, "experiment")
        unknown = sorted(set(data) - TOP_KEYS)
        if unknown:
            raise ConfigError(
                f"unknown experiment key {unknown[0]!r}{did_you_mean(unknown[0], TOP_KEYS)}; "
                f"known: {', '.join(sorted(TOP_KEYS))}",
                unknown[0],
            )
        for key in ("scenario", "sweep", "algorithms", "figure", "plugins", "budgets"):
            if key in data and not isinstance(data[key], dict):
                raise ConfigError(f"[{key}] must be a table", key)
        if not isinstance(data.get("baseline", ""), str):
            raise ConfigError(f"baseline = {data['baseline']!r} must be an algorithm's name", "baseline")
        algorithms = check_keys("[algorithms]", data.get("algorithms", {}), "algorithms")
        return dict(
            name=data.get("name", "experiment"),
            scenario=dict(data.get("scenario", {"preset": "paper"})),
            algorithms={k: dict(v) if isinstance(v, dict) else v for k, v in algorithms.items()},
            sweep=dict(data.get("sweep", {})),
            layouts=data.get("layouts", 5),
            seeds=data.get("seeds", 1),
            episodes=data.get("episodes", 10),
            figure=dict(data.get("figure", {})),
            description=data.get("description", ""),
            baseline=data.get("baseline", ""),
            training_layouts=data.get("training_layouts"),
            plugins=dict(data.get("plugins", {})),
            world=data.get("world", GRID),
            budgets=dict(data.get("budgets", {})),
        )

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, allow_plugins: bool = False) -> Experiment:
        """An experiment from the keys of an experiment file. Its ``[plugins]`` import and
        run the code they name, so they are refused, before anything is imported, unless
        ``allow_plugins`` (the CLI's ``--allow-plugins``: the user's consent)."""
        fields = cls._fields(data)
        if fields["plugins"] and not allow_plugins:
            name = next(iter(fields["plugins"]))
            raise ConfigError(f"plugins.{name} names code to import and run: allowed only with --allow-plugins "
                              "(allow_plugins=True in Python)", "plugins")
        return cls(**fields)

    @classmethod
    def from_toml(cls, path: str | Path, *, allow_plugins: bool = False) -> Experiment:
        """An experiment file (:meth:`from_dict`; ``allow_plugins``: honour its ``[plugins]``)."""
        data = read_toml(path, "experiment")
        try:
            return cls.from_dict(data, allow_plugins=allow_plugins)
        except ConfigError as exc:
            raise ConfigError(f"{path}: {exc}", exc.field) from None

    @classmethod
    def from_stored(cls, data: Any, record: Any = None) -> Experiment:
        """The experiment of a stored run, from its configuration (:meth:`to_dict`) and its
        :meth:`record`, as data alone: nothing they name is imported or called.

        Built-in algorithms are checked as in a new experiment. Any other (a plugin, an
        entry point) is taken with the settings the run recorded; its row's label is then its
        name. Without a record (a store from before records), the configuration's key order
        is the stored one and such an algorithm keeps only its explicit settings, so its
        results are not found (counted as missing)."""
        fields = cls._fields(data)
        record = record if isinstance(record, dict) else {}
        order = record.get("order") if isinstance(record.get("order"), dict) else {}
        for key in ("algorithms", "sweep", "budgets"):
            fields[key] = _in_order(fields[key], order.get(key))
        if not all(isinstance(v, str) for v in fields["plugins"].values()):
            raise ConfigError("[plugins] must map names to factories ('package.module:function')", "plugins")
        recorded = record.get("settings") if isinstance(record.get("settings"), dict) else {}
        names = {f.name for f in dataclasses.fields(Scenario)}
        opaque = {}
        for name, settings in fields["algorithms"].items():
            if name in ALGORITHMS:
                continue
            entry = recorded.get(name)
            if _is_recorded_entry(entry):
                opaque[name] = {"settings": dict(entry["settings"]), "sweep": dict(entry["sweep"])}
            else:  # a run recorded before records: its explicit settings, every non-scenario sweep key
                explicit = dict(settings) if isinstance(settings, dict) else {}
                explicit.pop("observation", None)
                opaque[name] = {"settings": explicit, "sweep": {k: v for k, v in fields["sweep"].items()
                                                                if k not in names and isinstance(v, list)}}
        return cls(**fields, recorded_settings=opaque)

    def record(self) -> dict[str, Any]:
        """What a store keeps beside :meth:`to_dict` so that :meth:`from_stored` needs no
        algorithm's code: ``order``, the order of the algorithms, sweep keys and budgets
        (a stored configuration's keys are sorted), and ``settings``, for every algorithm
        that is not built in, its resolved settings and the normalised values of its swept
        settings (what its tasks' keys are made of)."""
        scenario_fields = {f.name for f in dataclasses.fields(Scenario)}
        settings: dict[str, Any] = {}
        for name in self.algorithms:
            if name in ALGORITHMS:
                continue
            if name in self.recorded_settings:
                settings[name] = self.recorded_settings[name]
                continue
            own = set(self._setting_names(name))
            swept = {key: [self.settings_at(name, {key: value})[key] for value in values]
                     for key, values in self.sweep.items() if key in own and key not in scenario_fields}
            settings[name] = {"settings": self.settings_at(name, {}), "sweep": swept}
        return {"order": {"algorithms": list(self.algorithms), "sweep": list(self.sweep),
                          "budgets": list(self.budgets)},
                "settings": settings}

    def quick(self) -> Experiment:
        """The same experiment shrunk to a smoke test: 2 layouts, 1 seed, 2 episodes, the
        first two sweep values, and each algorithm's settings at their ``--quick`` values
        (short training, one training seed, short solver limits, the MILP's ``quick``
        budget; :func:`~swiptopt.benchmark.algorithms.quick_settings`). Not for an
        experiment read from a store with algorithms taken as recorded (:meth:`from_stored`)."""
        if self.recorded_settings:
            raise ConfigError(f"{self.name}: an experiment read from a store cannot be shrunk (--quick)", "quick")
        return dataclasses.replace(
            self,
            name=self.name,
            layouts=min(self.layouts, 2) if isinstance(self.layouts, int) else self.layouts[:2],
            seeds=1,
            episodes=min(self.episodes, 2),
            sweep={k: self._quick_values(k, v[:2]) for k, v in self.sweep.items()},
            budgets={name: self._quick_budgets(name, v) for name, v in self.budgets.items()},
            algorithms={name: self._without_budget(name, quick_settings(name, settings, self.world))
                        for name, settings in self.algorithms.items()},
        )

    def _without_budget(self, name: str, settings: dict[str, Any]) -> dict[str, Any]:
        """``settings`` without the budget setting when the budgets set it."""
        return {k: v for k, v in settings.items() if not (name in self.budgets and k == self.budget_setting(name))}

    def _quick_budgets(self, name: str, values: list[int]) -> list[int]:
        """An algorithm's first two budgets under ``--quick``: its budget setting's quick value
        and twice it."""
        quick = get_algorithm(name, self.plugins.get(name, "")).settings[self.budget_setting(name)].quick
        return [min(v, quick * 2**i) if quick is not None else v for i, v in enumerate(values[:2])]

    def _quick_values(self, key: str, values: list[Any]) -> list[Any]:
        """A swept setting's first values under ``--quick``: numbers capped at the setting's
        quick value times 1, 2, ... (so they stay distinct and in order), others as they are."""
        owners = self._swept_settings_of().get(key)
        if not owners or key in {f.name for f in dataclasses.fields(Scenario)}:
            return values
        spec = get_algorithm(owners[0], self.plugins.get(owners[0], "")).settings[key]
        if spec.quick is None or spec.kind not in ("int", "float"):
            return values
        return [min(v, spec.quick * 2**i) if isinstance(v, (int, float)) else v for i, v in enumerate(values)]

    # ------------------------------------------------------------ expansion

    def points(self) -> list[dict[str, Any]]:
        """Every combination of the sweep's values (one empty point without a sweep)."""
        keys = list(self.sweep)
        return [dict(zip(keys, values)) for values in itertools.product(*(self.sweep[k] for k in keys))]

    def scenario_for(self, point: dict[str, Any], layout: int) -> Scenario:
        values = {**self.scenario, **self._split(point)[0], "layout_seed": layout}
        try:
            return Scenario.from_dict(values)
        except ScenarioError as exc:
            where = f" at sweep point {point}" if point else ""
            raise ConfigError(f"scenario{where}: {exc}", exc.field) from None

    def tasks(self) -> list[Task]:
        """All tasks: sweep point x layout x algorithm x seed (the algorithm's seeds,
        :meth:`seeds_of`). A task's settings leave out those that only shape the expansion
        (``training_seeds``); a task that trains across layouts carries them."""
        out = []
        for point in self.points():
            resolved = {name: self.settings_at(name, point) for name in self.algorithms}
            for layout in self.layout_seeds():
                scenario = self.scenario_for(point, layout).to_dict()
                for name, settings in resolved.items():
                    task_settings = {k: v for k, v in settings.items() if k not in EXPANSION_SETTINGS}
                    across = settings.get(TRAINING) == ACROSS_LAYOUTS
                    training = tuple(self.training_layouts) if across and self.training_layouts else None
                    setting = self.budget_setting(name) if name in self.budgets else None
                    for budget in self.budgets.get(name, [None]):
                        at = task_settings if budget is None else {**task_settings, setting: budget}
                        for s in range(self.seeds_of(settings)):
                            out.append(Task(self.name, scenario, name, at, SEEDS_PER_LAYOUT * layout + s,
                                            self.episodes, point, training, self.plugins.get(name, ""), self.world,
                                            budget))
        return out

    def to_dict(self) -> dict[str, Any]:
        """The configuration, with the keys of an experiment file (:meth:`from_dict`)."""
        out = dataclasses.asdict(self)
        del out["recorded_settings"]
        return out


def _in_order(table: dict[str, Any], names: Any) -> dict[str, Any]:
    """``table`` with its keys in the order of ``names`` when that lists exactly its keys
    (a recorded order), else as it is."""
    if isinstance(names, list) and all(isinstance(n, str) for n in names) and len(names) == len(table) \
            and set(names) == set(table):
        return {name: table[name] for name in names}
    return table


def _is_recorded_entry(entry: Any) -> bool:
    """Whether ``entry`` has the shape of an algorithm's recorded settings (:meth:`Experiment.record`)."""
    return (isinstance(entry, dict) and isinstance(entry.get("settings"), dict)
            and isinstance(entry.get("sweep"), dict)
            and all(isinstance(k, str) for k in entry["settings"])
            and all(isinstance(k, str) and isinstance(v, list) for k, v in entry["sweep"].items()))


# ------------------------------------------------------------------- built-ins

_PAPER_ALGORITHMS = {"q_learning": {}, "sarsa": {}, "random": {}}
#: The tabular agents and every planner but the MILP: cheap enough for every figure's sweep.
_AGENTS_AND_PLANNERS = {**_PAPER_ALGORITHMS, "kmeans_tsp": {}, "lawnmower": {}, "greedy": {}, "rate_greedy": {}}
#: The deterministic paper preset: no fading, no link failures (the MILP is then exact).
_DETERMINISTIC = {"channel": "none", "failure_prob_min": 0.0, "failure_prob_max": 0.0}
_NODE_SWEEP = {"n_nodes": [10, 20, 30, 40, 50]}
#: The layouts of the standard suite.
_COMPARE_LAYOUTS = 6
#: The learning curves' budgets (``swiptopt run learning-curve``): powers of two times a
#: rollout (PPO: 16 copies x 256 steps; the stop-choosing agent: 8 x 256 decisions), so one
#: training run per lineage saves every budget's model on its way (:func:`learning_curves`).
_GRID_CURVE = (65_536, 131_072, 262_144, 524_288, 1_048_576)
_STOP_CURVE = (16_384, 32_768, 65_536, 131_072, 262_144)
_SAC_CURVE = (32_768, 65_536, 131_072, 262_144)


def _doubled(budgets: tuple[int, ...]) -> list[int]:
    return [2 * b for b in budgets]


def _doublings_more(budgets: tuple[int, ...] | list[int], n: int = 1) -> list[int]:
    """A curve's budgets and its last doubled n times (for a curve still rising at its end)."""
    return [*budgets, *(budgets[-1] << k for k in range(1, n + 1))]


#: Deep RL in the suites: one model per algorithm and training seed, trained across the
#: suite's own layouts (as the tabular agents train on the layouts they are evaluated on),
#: at the last budget of its learning curve across layouts (``learning-curve-across``,
#: ``learning-curve-harbour-across``): the same tasks, so the same models. Those models are
#: shipped (swiptopt/benchmark/pretrained), so ``compare`` evaluates them instead of training
#: them; ``--retrain`` trains them afresh (hours on two cores).
#: The budgets across layouts: the per-layout curves' doubled on the grid (a model serves
#: every layout), DQN's with one more doubling (its curve still rose at 2,097,152); in the
#: harbour, PPO's doubled and two doublings more (8.29 at 4,194,304 steps, flat at 8,388,608
#: with 8.78, docs/results.md), SAC's the per-layout curve's and five doublings more (it
#: still rose at 524,288 and at 4,194,304 steps, flat at 8,388,608 with 12.80; a SAC step
#: costs many PPO steps: a lineage to 8,388,608 took about 211 CPU-minutes) and the
#: stop-choosing agent's from half the per-layout curve's first budget to twice its last.
ACROSS_BUDGETS = {
    "grid": {"ppo": _doubled(_GRID_CURVE), "dqn": _doublings_more(_doubled(_GRID_CURVE)),
             "stop_ppo": _doubled(_STOP_CURVE)},
    "harbour": {"ppo": _doublings_more(_doubled(_GRID_CURVE), 2),
                "sac": _doublings_more(_SAC_CURVE, 5),
                "stop_ppo": [_STOP_CURVE[0] // 2, *_doublings_more(_STOP_CURVE)]},
}
COMPARE_DEEP_TIMESTEPS = {name: budgets[-1] for name, budgets in ACROSS_BUDGETS["grid"].items()}
_COMPARE_DEEP = {name: {"timesteps": steps, "training": "across_layouts"}
                 for name, steps in COMPARE_DEEP_TIMESTEPS.items()}
#: The harbour suite: the continuous world on the harbour preset (a pier, a moored hull, a
#: wreck, a sloping seabed and a current), where straight lines are wrong.
_HARBOUR_LAYOUTS = 8
HARBOUR_DEEP_TIMESTEPS = {name: budgets[-1] for name, budgets in ACROSS_BUDGETS["harbour"].items()}
_HARBOUR_ALGORITHMS = {
    "ompl_tour": {},
    "straight_line": {},
    **{name: {"timesteps": steps, "training": "across_layouts"} for name, steps in HARBOUR_DEEP_TIMESTEPS.items()},
    "random": {},
}
#: The generalisation experiment: deep RL trained on layouts 1000..1199, evaluated on the
#: held-out layouts 0..9, at a larger budget than the standard suite's.
GENERALISATION_TIMESTEPS = 50_000
GENERALISATION_TRAINING = {"start": 1000, "count": 200}


#: The learning curves (``swiptopt run learning-curve``): every deep-RL contender of both
#: worlds at budgets that double, trained per layout (a model per layout and seed, as the
#: planners plan per layout) and across layouts (a model per seed for every layout of the
#: suite, as ``compare`` trains), beside the planners on the same layouts. Budgets are
#: powers of two times a rollout (PPO: 16 copies x 256 steps; the stop-choosing agent: 8 x
#: 256 decisions), so one run per lineage saves every budget's model on its way.
CURVE_LAYOUTS = 6


def learning_curves() -> list[Experiment]:
    """The four experiments of ``learning-curve``: (grid, harbour) x (per layout, across layouts)."""
    grid_planners = {"kmeans_tsp": {}, "rate_greedy": {}, "milp": {"budget": "compare"}}
    harbour_planners = {"ompl_tour": {}, "straight_line": {}}
    per = {"training": PER_LAYOUT_TRAINING}
    across = {"training": ACROSS_LAYOUTS}
    common = dict(episodes=10)
    return [
        _builtin(
            "learning-curve",
            "the learning curve of PPO, DQN and the stop-choosing agent on the standard suite's scenario, "
            f"trained per layout ({CURVE_LAYOUTS} layouts, 3 seeds), beside k-means + TSP, rate-greedy and the MILP",
            scenario={"preset": "paper", "n_nodes": 25},
            algorithms={"ppo": per, "dqn": per, "stop_ppo": per, **grid_planners},
            # DQN per layout one doubling further: its curve still rose at 1,048,576 steps
            # (17.12 -> 19.39) and is flat at 2,097,152 (18.80, docs/results.md); the shorter
            # budgets' tasks are unchanged
            budgets={"ppo": list(_GRID_CURVE), "dqn": _doublings_more(_GRID_CURVE),
                     "stop_ppo": list(_STOP_CURVE)},
            layouts=CURVE_LAYOUTS, baseline="milp", **common,
        ),
        _builtin(
            "learning-curve-across",
            "the learning curve of PPO, DQN and the stop-choosing agent trained across the standard suite's "
            f"{_COMPARE_LAYOUTS} layouts (3 seeds), as compare trains them",
            scenario={"preset": "paper", "n_nodes": 25},
            algorithms={"ppo": across, "dqn": across, "stop_ppo": across, **grid_planners},
            budgets=ACROSS_BUDGETS["grid"],
            layouts=_COMPARE_LAYOUTS, training_layouts=tuple(range(_COMPARE_LAYOUTS)), baseline="milp", **common,
        ),
        _builtin(
            "learning-curve-harbour",
            "the learning curve of PPO, SAC and the stop-choosing agent in the harbour (continuous world), "
            f"trained per layout ({CURVE_LAYOUTS} layouts, 3 seeds), beside the OMPL tour and the straight line",
            world=CONTINUOUS,
            scenario={"preset": "harbour"},
            algorithms={"ppo": per, "sac": per, "stop_ppo": per, **harbour_planners},
            # PPO per layout one doubling further: its curve still rose at 1,048,576 steps
            # (8.13 -> 9.21) and is flat at 2,097,152 (9.82, docs/results.md); SAC per layout
            # three doublings further (4.00 at 262,144, 7.74 at 524,288, 12.17 at 1,048,576, 15.57
            # at 2,097,152, still rising); the shorter budgets' tasks are unchanged
            budgets={"ppo": _doublings_more(_GRID_CURVE), "sac": _doublings_more(_SAC_CURVE, 3),
                     "stop_ppo": list(_STOP_CURVE)},
            layouts=CURVE_LAYOUTS, baseline="ompl_tour", **common,
        ),
        _builtin(
            "learning-curve-harbour-across",
            "the learning curve of PPO, SAC and the stop-choosing agent trained across the harbour suite's "
            f"{_HARBOUR_LAYOUTS} layouts (3 seeds), as compare trains them",
            world=CONTINUOUS,
            scenario={"preset": "harbour"},
            algorithms={"ppo": across, "sac": across, "stop_ppo": across, **harbour_planners},
            budgets=ACROSS_BUDGETS["harbour"],
            layouts=_HARBOUR_LAYOUTS, training_layouts=tuple(range(_HARBOUR_LAYOUTS)), baseline="ompl_tour",
            **common,
        ),
    ]


#: Built-in experiments that run together under one name.
GROUPS = {"learning-curve": ("learning-curve", "learning-curve-across", "learning-curve-harbour",
                             "learning-curve-harbour-across")}


#: An experiment's name names its files: letters, digits, '-', '_' and '.', not only dots.
NAME_PATTERN = re.compile(r"[A-Za-z0-9._-]{1,100}")


def training_unit(algorithm: str) -> str:
    """What a deep-RL algorithm's training counts: ``decisions`` for a stop-choosing agent
    (the fleet's too: a stop and its dwell, several steps of the world), ``steps`` for the
    others."""
    return "decisions" if algorithm.endswith("stop_ppo") else "steps"


def budget_row(algorithm: str, budget: int) -> str:
    """The table row of an algorithm at a learning-curve budget."""
    return f"{algorithm}@{budget}"


def _check_layout_list(key: str, values: Any) -> tuple[int, ...]:
    """A list of distinct layout seeds in [0, MAX_LAYOUT], as a tuple."""
    if not isinstance(values, (list, tuple)) or not values:
        raise ConfigError(f"{key} must be a count or a non-empty list of layout seeds", key)
    if len(values) > MAX_LAYOUTS:
        raise ConfigError(f"{key} lists {len(values):,} layouts: at most {MAX_LAYOUTS:,}", key)
    spec = Spec(kind="int", lo=0, hi=MAX_LAYOUT)
    out = tuple(check_value(f"{key}[{i}]", v, spec, field=key) for i, v in enumerate(values))
    repeated = sorted({v for v in out if out.count(v) > 1}) if len(set(out)) < len(out) else []
    if repeated:
        raise ConfigError(f"{key} lists layout {repeated[0]} more than once: each layout once", key)
    return out


def _misplaced_world(where: str) -> None:
    raise ConfigError(
        f"{where}: the world is the experiment's, not a setting here: write world = {CONTINUOUS!r} (or {GRID!r}) "
        "at the top of the file, before any [table]",
        "world",
    )


def _check_name(name: Any) -> None:
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name) or ".." in name or not name.strip("."):
        raise ConfigError(
            f"name = {name!r} is not allowed: an experiment's name names its files, so it must be 1 to 100 "
            "letters, digits, '-', '_' or '.', without '..'",
            "name",
        )


def _builtin(name: str, description: str, **fields: Any) -> Experiment:
    return Experiment(name=name, description=description, **fields)


def technologies() -> Experiment:
    """The ``technologies`` experiment: the standard suite's planners and tabular agents on the
    same layouts with each link technology (docs/links.md). Deep RL is left out: its plateau
    budgets per technology would take hours of training each."""
    paper = {"preset": "paper"}
    return _builtin(
        "technologies",
        "the standard suite's planners and tabular agents on the same layouts with each link technology: "
        "the paper's acoustic link, underwater optical (UWOC, clear ocean) and magnetic induction; paper "
        "preset, 25 nodes (docs/links.md)",
        scenario={**paper, "n_nodes": 25},
        sweep={"technology": ["acoustic", "optical", "magnetic_induction"]},
        algorithms={**_AGENTS_AND_PLANNERS, "milp": {"budget": "compare"}},
        layouts=_COMPARE_LAYOUTS,
        episodes=10,
        baseline="random",
    )


#: The fleet suite's field (docs/fleet.md): the paper preset over four times its area
#: (200 m x 200 m, 50 m deep), 60 nodes and 100 steps, more than one AUV can serve in an
#: episode; fleets of 1, 2 and 4 AUVs, their default start cells spread across the surface.
FLEET_SCENARIO = {"preset": "paper", "length_m": 200.0, "width_m": 200.0, "n_nodes": 60, "episode_steps": 100}
FLEET_SIZES = [1, 2, 4]
_FLEET_LAYOUTS = 4
#: The fleet suite's learners' budgets (docs/fleet.md): the stop-choosing PPO's decisions at
#: its learning curves' plateaus on the suite's field (flat from 65,536 with one AUV, 131,072
#: with two and 262,144 with four: benchmarks/learning-curve-fleet-stop-ppo*.toml);
#: parameter-shared PPO's AUV steps where its curves are within 10 % of their last budgets
#: with every fleet size (benchmarks/learning-curve-fleet-shared-ppo*.toml: flat at
#: 2,097,152 with one AUV, at 4,194,304 with two and four, where 2,097,152 gives 0.95x and
#: 0.91x of the last).
FLEET_TIMESTEPS = {"fleet_stop_ppo": 262_144, "shared_ppo": 2_097_152}
#: Independent Q-learning's training episodes in the fleet suite and in fleet-optimum: the
#: end of its learning curves, flat from 20,000 episodes on the suite's field with 1, 2 and 4
#: AUVs (benchmarks/learning-curve-fleet-q-learning-*.toml) and from 10,000 on the
#: yardstick's (benchmarks/learning-curve-fleet-optimum-q-learning-*.toml); 5,000
#: understated it up to 3.6 times.
FLEET_Q_EPISODES = 40_000


def fleet_suite() -> Experiment:
    """The ``fleet`` experiment: k-means + vehicle routing against the stop-choosing PPO and
    parameter-shared PPO (one policy for every AUV), independent Q-learning and random moves,
    for fleets of 1, 2 and 4 AUVs."""
    return _builtin(
        "fleet",
        "fleets of 1, 2 and 4 AUVs on a field four times the paper's area (200 m x 200 m, 60 nodes, 100 steps): "
        "k-means + OR-Tools vehicle routing against the stop-choosing PPO and parameter-shared PPO (one policy "
        "for every AUV, trained per layout), independent Q-learning (one agent per AUV) and random moves "
        "(docs/fleet.md)",
        scenario=FLEET_SCENARIO,
        sweep={"n_auvs": FLEET_SIZES},
        algorithms={"fleet_routing": {}, **{name: {"timesteps": steps} for name, steps in FLEET_TIMESTEPS.items()},
                    "fleet_q_learning": {"train_episodes": FLEET_Q_EPISODES}, "fleet_random": {}},
        layouts=_FLEET_LAYOUTS,
        episodes=10,
        baseline="fleet_random",
    )


#: The fleet's yardstick (docs/fleet.md): a deterministic field small enough for the fleet
#: MILP (planners.fleet_optimal), whose bound then holds for every fleet policy.
FLEET_OPTIMUM_SCENARIO = {"preset": "paper", **_DETERMINISTIC, "n_nodes": 10, "episode_steps": 40}


def fleet_optimum() -> Experiment:
    """The ``fleet-optimum`` experiment: every fleet algorithm beside the fleet MILP and its
    bound, for fleets of 1 and 2 AUVs on a deterministic field of 10 nodes."""
    return _builtin(
        "fleet-optimum",
        "every fleet algorithm's gap to the fleet MILP's bound (which holds for every fleet policy on a "
        "deterministic channel): the paper preset without fading or link failures, 10 nodes, 40 steps, "
        "fleets of 1 and 2 AUVs (docs/fleet.md)",
        scenario=FLEET_OPTIMUM_SCENARIO,
        sweep={"n_auvs": [1, 2]},
        algorithms={"fleet_milp": {"budget": "compare"}, "fleet_routing": {}, "fleet_stop_ppo": {},
                    "shared_ppo": {}, "fleet_q_learning": {"train_episodes": FLEET_Q_EPISODES}, "fleet_random": {}},
        layouts=_FLEET_LAYOUTS,
        episodes=10,
        baseline="fleet_milp",
    )


def builtin_experiments() -> dict[str, Experiment]:
    """The named experiments: ``compare`` (the standard suite), ``harbour`` (the continuous
    world's suite), ``generalisation`` and one per figure of the paper."""
    paper = {"preset": "paper"}
    return {
        e.name: e
        for e in (
            _builtin(
                "compare",
                "every algorithm on the standard suite: the paper preset, 25 nodes (the MILP at its "
                "'compare' budget; PPO, DQN and the stop-choosing agent trained across the 6 layouts at the last "
                "budget of their learning curves, 3 seeds)",
                scenario={**paper, "n_nodes": 25},
                algorithms={**_AGENTS_AND_PLANNERS, "milp": {"budget": "compare"}, **_COMPARE_DEEP},
                layouts=_COMPARE_LAYOUTS,
                training_layouts=tuple(range(_COMPARE_LAYOUTS)),
                episodes=10,
                baseline="random",
            ),
            _builtin(
                "harbour",
                "the continuous world on the harbour preset (pier, hull, wreck, sloping seabed, current): the "
                f"OMPL tour against straight lines, PPO, SAC and the stop-choosing agent (trained across the "
                f"{_HARBOUR_LAYOUTS} layouts at the last budget of their learning curves, 3 seeds) and random actions",
                world=CONTINUOUS,
                scenario={"preset": "harbour"},
                algorithms=_HARBOUR_ALGORITHMS,
                layouts=_HARBOUR_LAYOUTS,
                training_layouts=tuple(range(_HARBOUR_LAYOUTS)),
                episodes=10,
                baseline="straight_line",
            ),
            _builtin(
                "generalisation",
                f"deep RL trained across 200 layouts (1000-1199, {GENERALISATION_TIMESTEPS:,} steps, 3 seeds), "
                "evaluated on 10 held-out layouts against planners that plan per layout and Q-learning "
                "trained per layout; paper preset, 25 nodes",
                scenario={**paper, "n_nodes": 25},
                algorithms={
                    "ppo": {"timesteps": GENERALISATION_TIMESTEPS, "training": "across_layouts"},
                    "dqn": {"timesteps": GENERALISATION_TIMESTEPS, "training": "across_layouts"},
                    "q_learning": {}, "random": {}, "kmeans_tsp": {}, "rate_greedy": {},
                },
                layouts=10,
                training_layouts=GENERALISATION_TRAINING,
                episodes=10,
                baseline="random",
            ),
            _builtin(
                "optimum",
                "every algorithm's gap to the optimum: the deterministic paper preset (no fading, no link "
                "failures), 25 nodes, 10 layouts, the MILP at its 'default' budget",
                scenario={**paper, **_DETERMINISTIC, "n_nodes": 25},
                algorithms={**_AGENTS_AND_PLANNERS, "milp": {"budget": "default"}},
                layouts=10,
                episodes=10,
                baseline="milp",
            ),
            _builtin(
                "rl-vs-random",
                "the paper's claim: trained Q-learning and SARSA against the random trajectory, "
                "paper preset, 25 nodes, 40 layouts",
                scenario={**paper, "n_nodes": 25},
                algorithms=_PAPER_ALGORITHMS,
                layouts=40,
                episodes=20,
                baseline="random",
            ),
            technologies(),
            fleet_suite(),
            fleet_optimum(),
            *learning_curves(),
            *paper_figures(),
        )
    }


#: The paper's reward-weight extremes (Section IV, on Fig. 6: "only values of eta = 1 and
#: eta = 0 ... These values represent the extreme ends of the reward function"): its data
#: figures weigh throughput only (Gamma = 1 in eq. 23), its energy figures harvesting only
#: (Gamma = 0) with all of the received power sent to the harvester (alpha = 0, Section IV,
#: on Fig. 10).
#: Section IV names the weight eta and pairs 1 with harvesting; eq. 23 pairs Gamma = 1 with
#: throughput, and we follow the equation.
PAPER_DATA_WEIGHT = {"reward_weight": 1.0}
PAPER_ENERGY_WEIGHT = {"reward_weight": 0.0, "split_ratio": 0.0}

#: Each reading of the paper's energy efficiency (Section IV, on Fig. 9) as a figure of its
#: own; the four share their tasks (a task's key does not include the experiment's name).
EFFICIENCY_FIGURES = {
    "fig-efficiency-vs-nodes": ("energy_efficiency_bit_per_j", "projector counted while it serves"),
    "fig-efficiency-always-on-vs-nodes": ("energy_efficiency_always_on_bit_per_j", "projector counted every step"),
    "fig-efficiency-per-node-vs-nodes": ("energy_efficiency_per_node_bit_per_j", "projector counted per covered node"),
    "fig-mobility-efficiency-vs-nodes": ("mobility_efficiency_bit_per_j", "motion energy only"),
}


def paper_figures(link: str | None = None) -> list[Experiment]:
    """The experiments behind the paper's figures, at the paper's reward weights.

    ``link`` (``"downlink_split"`` or ``"uplink"``) runs every figure on that data link;
    the uplink's experiments are named with an ``-uplink`` suffix so that their figures and
    tables sit beside the downlink's. ``None`` keeps the preset's link (the power-split
    downlink) and the plain names.
    """
    paper: dict[str, Any] = {"preset": "paper"}
    suffix = ""
    if link is not None:
        paper["link"] = link
        suffix = "-uplink" if link == "uplink" else ""
    common = dict(sweep=_NODE_SWEEP, algorithms=_AGENTS_AND_PLANNERS, layouts=20, episodes=5)
    data = {**paper, **PAPER_DATA_WEIGHT}
    energy = {**paper, **PAPER_ENERGY_WEIGHT}
    steps_doc = "of what the coverable nodes hold (nodes no cell covers count in neither)"
    figures = [
        _builtin(
            "fig-reward-vs-split",
            "reward (return) against the power-splitting factor, 25 nodes, Gamma = 0.5",
            scenario={**paper, "n_nodes": 25},
            sweep={"split_ratio": [0.1, 0.3, 0.5, 0.7, 0.9]},
            algorithms=_AGENTS_AND_PLANNERS,
            layouts=20,
            episodes=5,
            figure={"metric": "return", "x": "split_ratio", "xlabel": "split ratio alpha"},
        ),
        _builtin(
            "fig-throughput-vs-nodes",
            "data collected against the number of nodes, Gamma = 1 (throughput only)",
            scenario=data, **common, figure={"metric": "data_bits", "x": "n_nodes"},
        ),
        _builtin(
            "fig-steps-to-data-target",
            f"steps to collect half {steps_doc}, against the number of nodes, Gamma = 1",
            scenario=data, **common, figure={"metric": "steps_to_data_target", "x": "n_nodes"},
        ),
        *(
            _builtin(
                name,
                f"energy efficiency ({what}) against the number of nodes, Gamma = 1",
                scenario=data, **common, figure={"metric": metric, "x": "n_nodes"},
            )
            for name, (metric, what) in EFFICIENCY_FIGURES.items()
        ),
        _builtin(
            "fig-harvested-vs-nodes",
            "energy delivered to the nodes against the number of nodes, Gamma = 0, alpha = 0 (harvesting only)",
            scenario=energy, **common, figure={"metric": "energy_delivered_j", "x": "n_nodes"},
        ),
        _builtin(
            "fig-steps-to-energy-target",
            "steps to deliver half of the energy the coverable nodes can store, against the number of nodes, "
            "Gamma = 0, alpha = 0",
            scenario=energy, **common, figure={"metric": "steps_to_energy_target", "x": "n_nodes"},
        ),
    ]
    if link == "uplink":
        # on the uplink alpha has no effect (all received power charges): no split sweep
        figures = [dataclasses.replace(e, name=e.name + suffix) for e in figures if e.name != "fig-reward-vs-split"]
    return figures


def load_experiments(spec: str, *, allow_plugins: bool = False) -> list[Experiment]:
    """The experiments ``spec`` names: a group of built-ins (:data:`GROUPS`), one built-in
    by name, or a TOML file (``allow_plugins``: honour its ``[plugins]``)."""
    if spec in GROUPS:
        builtins = builtin_experiments()
        return [builtins[name] for name in GROUPS[spec]]
    return [load_experiment(spec, allow_plugins=allow_plugins)]


def load_experiment(spec: str, *, allow_plugins: bool = False) -> Experiment:
    """A built-in experiment by name or a TOML file (``allow_plugins``: honour its ``[plugins]``)."""
    builtins = builtin_experiments()
    if spec in builtins:
        return builtins[spec]
    path = Path(spec)
    if path.suffix.lower() == ".toml" or path.exists():
        return Experiment.from_toml(path, allow_plugins=allow_plugins)
    raise ConfigError(
        f"{spec!r} is neither a built-in experiment{did_you_mean(spec, builtins)} ({', '.join(builtins)}) "
        "nor a .toml file",
        "experiment",
    )
