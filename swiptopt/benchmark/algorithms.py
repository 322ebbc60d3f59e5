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

Algorithms from outside the project (plugins) are registered without editing it, in either
of two ways; both name a *factory*, a function of no arguments that returns an
:class:`Algorithm` (:func:`sb3_algorithm` makes one for any Stable-Baselines3 algorithm):

- an entry point in the group ``swiptopt.algorithms`` of an installed distribution
  (``[project.entry-points."swiptopt.algorithms"] a2c = "my_algorithms:a2c"``): the
  algorithm is then known by the entry point's name everywhere;
- ``[plugins] a2c = "my_algorithms:a2c"`` in an experiment file, for that experiment (the
  module must be importable: on ``PYTHONPATH`` or installed), honoured only with the
  user's consent (``--allow-plugins``).

A plugin is code run in swiptopt's processes: :func:`load_plugin` imports its module and
calls only a plain function that module defines (never a builtin such as ``os.abort``), and
turns whatever the plugin raises into one line. docs/plugins.md says when plugins load.

Each algorithm runs in the worlds it declares (``worlds``: the paper's ``"grid"``, the
``"continuous"`` world, or both; :mod:`swiptopt.worlds`): the grid's agents and planners
there, SAC (``sac``) and the continuous planners (``ompl_tour``: hover points, a tour over
OMPL energy paths, an executor that follows them; ``straight_line``: the same stops reached
in straight lines) in the continuous world, PPO and the random agent (uniform velocity
commands) in both. An experiment refuses an algorithm outside its world.

Each algorithm acts on one observation of the environment (``observation``: ``"tabular"``
for the paper's agents, ``"vector"`` for deep RL; planners read the environment itself). An
experiment may say ``observation = ...`` among an algorithm's settings; any other value
than the algorithm's own is refused, naming it. The continuous world has one observation,
``"vector"``: there every other value is refused.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

from planners.bounds import MILP_EXPECTED_NAME, MILP_NAME, OPEN_LOOP
from planners.continuous.planners import OmplTourPlanner, StraightLinePlanner
from planners.optimal import BUDGETS
from planners.policies import GreedyPlanner, LawnmowerPlanner
from planners.reward_tour import RewardKMeansTspPlanner
from rl.config import TABULAR_PARAMETERS
from swiptopt.errors import ConfigError, did_you_mean
from swiptopt.limits import check_size, limits, training_log_note
from swiptopt.validation import Spec, check_keys, check_value
from swiptopt.worlds import CONTINUOUS, GRID, WORLDS
from swiptopt.worlds import OBSERVATIONS as WORLD_OBSERVATIONS


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

    def allowed(self, hi: float | None = None) -> str:
        if self.kind == INTS:
            return f"a list of 1 to {MAX_LIST_ITEMS} integers in [{self.lo:g}, {self.hi:g}]"
        return super().allowed(hi)


#: The kind of a setting that holds a list of integers (a network's layer widths).
INTS = "ints"
#: The longest list an ``ints`` setting holds.
MAX_LIST_ITEMS = 16


def check_setting(where: str, value: Any, spec: Setting, key: str) -> Any:
    """``value`` checked against ``spec`` (:func:`swiptopt.validation.check_value`, plus
    lists of integers), normalised; a :class:`ConfigError` naming ``where`` otherwise."""
    if spec.kind != INTS:
        return check_value(where, value, spec, field=key)
    if value is None and spec.optional:
        return None
    if isinstance(value, tuple):
        value = list(value)
    if not isinstance(value, list) or not 1 <= len(value) <= MAX_LIST_ITEMS:
        raise ConfigError(f"{where} = {value!r} is not allowed: must be {spec.allowed()}", key)
    item = Spec(kind="int", lo=spec.lo, hi=spec.hi)
    try:
        return [check_value(where, v, item, field=key) for v in value]
    except ConfigError:
        raise ConfigError(f"{where} = {value!r} is not allowed: must be {spec.allowed()}", key) from None


@dataclass(frozen=True)
class BuildContext:
    """What a task knows beyond (environment, settings, seed), for algorithms that need it.

    ``scenario`` is the task's scenario (its layout); ``seed_index`` the task's seed within
    its layout (0, 1, ...: the training seed of a model trained across layouts);
    ``training_layouts`` the experiment's training layouts (``None`` without); ``models_dir``
    where trained models are kept and reused (``None``: nowhere, train in memory); ``world``
    the world the task runs in (:mod:`swiptopt.worlds`).
    """

    scenario: Any
    seed_index: int = 0
    training_layouts: tuple[int, ...] | None = None
    models_dir: str | None = None
    world: str = GRID
    checkpoints: tuple[int, ...] = ()
    """Other budgets of the task's training lineage: step counts at which its training also
    saves its model (for the tasks that will load it)."""
    pretrained: tuple[str, ...] = ()
    """Read-only directories of models trained elsewhere, each vouched for by its manifest."""
    keep_state: bool = False
    """Whether the task's training keeps its state at its end in ``models_dir`` (so that a
    longer run of its lineage goes on from it: :func:`rl.deep.train_or_load_deep`)."""


@dataclass(frozen=True)
class Algorithm:
    """A named algorithm: its family, its settings, how to build it and what its tasks record.

    ``build(env, settings, seed, context)`` returns the policy (trained, for RL) for the
    environment ``env`` (:class:`BuildContext` says the rest); ``record(policy, env)``,
    called after the evaluation, returns what the task stores beside its episodes
    (:func:`task_extra`). ``observation`` is the observation the policy acts on
    (``"tabular"``, ``"vector"``, or ``None`` for planners, which read the environment);
    ``modules`` are native libraries the runner imports before its workers start (so their
    thread pools are limited to one thread); ``trains_model`` marks algorithms whose
    training dominates a task's time (the runner starts those first). ``worlds`` are the
    worlds it runs in (:mod:`swiptopt.worlds`; an experiment in another world refuses it);
    ``uses_ompl(settings)`` says whether a task with these resolved settings plans with
    OMPL (the runner then gives it a fresh process, its OMPL seed set from the task).
    """

    name: str
    label: str
    family: str
    settings: dict[str, Setting] = field(default_factory=dict)
    build: Callable[[Any, dict[str, Any], int, BuildContext], Any] | None = None
    record: Callable[[Any, Any], dict[str, Any]] | None = None
    observation: str | None = None
    modules: tuple[str, ...] = ()
    trains_model: bool = False
    fleet: bool = False
    """Runs a fleet (docs/fleet.md): its tasks run in :class:`swiptopt.env_fleet.AuvFleetEnv`
    (any ``n_auvs``, one included), ``build`` returns a fleet policy (``act(observations)``,
    :func:`swiptopt.evaluation.evaluate_fleet`), and only such algorithms run on a scenario
    with ``n_auvs > 1``."""
    check: Callable[[dict[str, Any]], None] | None = None
    """Checks between settings (called with the resolved settings; raises ConfigError)."""
    check_scenario: Callable[[dict[str, Any], Any], None] | None = None
    """Checks that depend on the scenario (called with the resolved settings and each
    scenario of the experiment before any task runs; raises ConfigError): sizes."""
    worlds: tuple[str, ...] = (GRID,)
    uses_ompl: Callable[[dict[str, Any]], bool] | None = None
    trained_model: Callable[[dict[str, Any], int, BuildContext], tuple[Any, Any]] | None = None
    """For an algorithm whose tasks keep their models in the models directory
    (:func:`rl.deep.train_or_load_deep`): the training run behind a task's model, as
    (:class:`rl.deep.DeepConfig`, the scenario that names the model), from the task's
    resolved settings, seed and context. The runner checks the models' places with it before
    any task runs."""

    @property
    def defaults(self) -> dict[str, Any]:
        return {key: s.default for key, s in self.settings.items()}


def _rl(algorithm: str) -> Callable[[Any, dict[str, Any], int, BuildContext], Any]:
    def build(env: Any, settings: dict[str, Any], seed: int, context: BuildContext) -> Any:
        from rl import TabularConfig, UniformRandomAgent, make_agent, train

        if context.world == CONTINUOUS:  # only the random agent runs there: uniform velocity commands
            return UniformRandomAgent.for_space(env.action_space, seed=seed)
        settings = dict(settings)
        episodes = settings.pop("train_episodes")
        backend = settings.pop("backend")
        config = None if algorithm == "random" else TabularConfig().replace(**settings)
        agent = make_agent(algorithm, env.observation_space.n, config=config, seed=seed)
        if algorithm != "random":
            train(agent, env, episodes, seed=seed, backend=backend)
        return agent

    return build


def _planner(cls_name: str, *, seeded: bool = False,
             module: str = "planners") -> Callable[[Any, dict[str, Any], int, BuildContext], Any]:
    """Build ``<module>.<cls_name>`` from the settings (and the task's seed when ``seeded``)."""

    def build(env: Any, settings: dict[str, Any], seed: int, context: BuildContext) -> Any:
        import importlib

        cls = getattr(importlib.import_module(module), cls_name)
        return cls(seed=seed, **settings) if seeded else cls(**settings)

    return build


def _milp(env: Any, settings: dict[str, Any], seed: int, context: BuildContext) -> Any:
    """The MILP's plan as a policy (a fleet's, :class:`planners.fleet_optimal.FleetMilpPlanner`,
    in a fleet env): the named budget, with the overrides that are set. The task's seed is
    not used: the solve is the same for every seed."""
    import dataclasses

    from planners.optimal import MilpPlanner

    overrides = {key: settings[key] for key in ("max_nodes", "time_limit_s") if settings[key] is not None}
    budget = dataclasses.replace(BUDGETS[settings["budget"]], **overrides)
    if hasattr(env, "fleet"):
        from planners.fleet_optimal import FleetMilpPlanner

        return FleetMilpPlanner(budget=budget)
    return MilpPlanner(budget=budget)


#: The MILP's dual bound as the tables name it (``bound_label``): with a deterministic
#: channel it bounds every policy; with a stochastic one it bounds the expected-rate
#: relaxation, which holds for open-loop plans that cannot end early only
#: (:func:`planners.optimal.policy_bounds`, docs/optimum.md).
MILP_BOUND = MILP_NAME
MILP_EXPECTED_BOUND = MILP_EXPECTED_NAME


def _milp_record(policy: Any, env: Any) -> dict[str, Any]:
    """The MILP's outcome under the keys a solver's task records (the tables read them):
    ``solver_status`` and ``solver_message``, ``best_return`` (the plan's value in the
    solver's model), ``bound_return`` with ``bound_label`` (its dual bound and its name),
    ``solver_gap``, ``lp_bound_return``, ``solver_nodes``, ``solver_exact``,
    ``solver_time_limit_hit``; ``policy_bounds``, each bound with the class of policy it
    holds for (``{"value", "name", "holds_for"}``), and ``policy_class``: the plan is open loop."""
    from planners.optimal import policy_bounds
    from planners.service import step_model

    result = getattr(policy, "result_", None)
    if result is None:
        return {}
    bounds = policy.policy_bounds() if callable(getattr(policy, "policy_bounds", None)) else policy_bounds(result)
    out = {
        "policy_class": OPEN_LOOP,
        "policy_bounds": [{"value": b.value, "name": b.name, "holds_for": b.holds_for} for b in bounds],
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
        tables = env.fleet.tables if hasattr(env, "fleet") else env.tables
        out["bound_label"] = MILP_BOUND if step_model(tables).exact else MILP_EXPECTED_BOUND
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
_TABULAR = {name: Setting(**{**dataclasses.asdict(param), "strict": False})
            for name, param in TABULAR_PARAMETERS.items()}


def _check_tabular(name: str) -> Callable[[dict[str, Any]], None]:
    def check(settings: dict[str, Any]) -> None:
        if settings["replay_size"] and settings["backend"] != "python":
            raise ConfigError(
                f"{_where(name, 'replay_size')} = {settings['replay_size']} needs {_where(name, 'backend')} = "
                f"'python' (experience replay runs in the Python training loop only), got {settings['backend']!r}",
                "backend",
            )

    return check
# ------------------------------------------------------------------ deep RL

#: The settings of a deep-RL algorithm that say how it trains, not what SB3 is given.
TRAINING = "training"
TRAINING_SEEDS = "training_seeds"
PER_LAYOUT, ACROSS_LAYOUTS = "per_layout", "across_layouts"
#: Settings that shape the experiment's tasks, not a task's result (left out of its key).
EXPANSION_SETTINGS = (TRAINING_SEEDS,)

_DEEP_COMMON = {
    "timesteps": Setting(default=1_000_000, kind="int", lo=1, hi=10**9, quick=1024,
                         doc="environment steps of training, all copies together (an on-policy algorithm "
                             "collects whole rollouts, so it trains up to the next multiple of n_envs x n_steps)"),
    "n_envs": Setting(default=16, kind="int", lo=1, hi=1024, quick=2,
                      doc="copies of the environment stepped together (copy i seeded with the task's seed + i)"),
    "net_arch": Setting(default=[128, 128], kind=INTS, lo=1, hi=4096, quick=[32],
                        doc="hidden layer widths of the policy (and value) network"),
    "learning_rate": Setting(default=None, lo=0, lo_open=True, hi=1, optional=True,
                             doc="optimiser step size (default: Stable-Baselines3's for the algorithm)"),
    "discount": Setting(default=None, lo=0, hi=1, optional=True, doc="discount factor gamma (default: SB3's, 0.99)"),
    TRAINING: Setting(default=PER_LAYOUT, kind="str", choices=(PER_LAYOUT, ACROSS_LAYOUTS),
                      doc="'per_layout': a model per task, trained on the task's layout with the task's seed; "
                          "'across_layouts': one model per training seed, trained on the experiment's "
                          "training_layouts (one drawn per episode) and evaluated on every layout"),
    TRAINING_SEEDS: Setting(default=3, kind="int", lo=1, hi=100, quick=1,
                            doc="training seeds per layout (replaces the experiment's 'seeds' for this algorithm)"),
}
#: SB3 constructor arguments under another name in the settings.
_SB3_NAMES = {"discount": "gamma"}
#: Settings of the deep algorithms that are not SB3 constructor arguments.
_NOT_SB3 = ("timesteps", "n_envs", "net_arch", TRAINING, TRAINING_SEEDS)

_PPO = {
    "n_steps": Setting(default=256, kind="int", lo=2, hi=1_000_000, quick=64,
                       doc="steps per copy per rollout (a rollout is n_envs x n_steps steps)"),
    "batch_size": Setting(default=512, kind="int", lo=2, hi=1_000_000, quick=64, doc="minibatch size"),
    "n_epochs": Setting(default=10, kind="int", lo=1, hi=1000, quick=2, doc="passes over each rollout"),
    "ent_coef": Setting(default=0.01, lo=0, hi=1, doc="entropy bonus coefficient"),
    "gae_lambda": Setting(default=None, lo=0, hi=1, optional=True, doc="GAE lambda (default: SB3's, 0.95)"),
    "clip_range": Setting(default=None, lo=0, lo_open=True, hi=10, optional=True,
                          doc="PPO's clipping range (default: SB3's, 0.2)"),
}
_DQN = {
    "learning_rate": Setting(default=5e-4, lo=0, lo_open=True, hi=1, doc="optimiser step size"),
    "buffer_size": Setting(default=200_000, kind="int", lo=1, hi=10**8, quick=2000, doc="replay buffer, transitions"),
    "learning_starts": Setting(default=10_000, kind="int", lo=0, hi=10**9, quick=256,
                               doc="steps before learning starts"),
    "batch_size": Setting(default=128, kind="int", lo=1, hi=1_000_000, quick=32, doc="minibatch size"),
    "train_freq": Setting(default=1, kind="int", lo=1, hi=1_000_000,
                          doc="updates every train_freq steps of every copy (n_envs x train_freq steps)"),
    "gradient_steps": Setting(default=2, kind="int", lo=1, hi=1_000_000, quick=1, doc="gradient steps per update"),
    "target_update_interval": Setting(default=2000, kind="int", lo=1, hi=10**9,
                                      doc="steps between target network updates"),
    "exploration_steps": Setting(default=200_000, kind="int", lo=1, hi=10**9, quick=256,
                                 doc="steps over which epsilon decays (whatever the total, so a shorter run's model is "
                                     "a checkpoint of a longer one)"),
    "exploration_final_eps": Setting(default=0.02, lo=0, hi=1, doc="epsilon at the end of its decay"),
}
_SAC = {
    "buffer_size": Setting(default=300_000, kind="int", lo=1, hi=10**8, quick=2000, doc="replay buffer, transitions"),
    "learning_starts": Setting(default=10_000, kind="int", lo=0, hi=10**9, quick=256,
                               doc="steps of uniform random actions before learning starts"),
    "batch_size": Setting(default=256, kind="int", lo=1, hi=1_000_000, quick=32, doc="minibatch size (SB3's default)"),
    "train_freq": Setting(default=1, kind="int", lo=1, hi=1_000_000,
                          doc="updates every train_freq steps of every copy (n_envs x train_freq steps)"),
    "gradient_steps": Setting(default=2, kind="int", lo=1, hi=1_000_000, quick=1, doc="gradient steps per update"),
}

#: What a deep-RL task imports, imported once before the workers fork: torch's optimisers
#: import torch._dynamo on first use (seconds per process otherwise).
_DEEP_MODULES = ("torch", "torch._dynamo", "stable_baselines3")

#: Bytes of a float32 value in SB3's buffers.
_FLOAT_BYTES = 4


def _check_deep_sizes(name: str, rollout: bool, candidates: bool = False) -> Callable[[dict[str, Any], Any], None]:
    """The sizes of a deep-RL task for its scenario, checked before any task runs: the
    network (parameters) and the buffer SB3 allocates at construction (an on-policy
    algorithm's rollout buffer holds n_envs x n_steps observations whatever ``timesteps``;
    a replay buffer holds buffer_size observations and the next ones)."""

    def check(settings: dict[str, Any], scenario: Any) -> None:
        from swiptopt.kernel import VECTOR_NODE_FEATURES

        obs = 4 + VECTOR_NODE_FEATURES * scenario.n_nodes
        if candidates:  # the stop-choice observation: features of up to two candidate stops per node
            obs += 2 * 4 * scenario.n_nodes
        widths = [obs, *settings["net_arch"], 8]
        parameters = sum((a + 1) * b for a, b in zip(widths, widths[1:])) * (2 if rollout else 3)
        check_size("max_network_parameters", parameters,
                   f"{_where(name, 'net_arch')} = {settings['net_arch']}: network parameters "
                   f"(observation {obs} -> {' -> '.join(map(str, settings['net_arch']))}, about)", "net_arch")
        if rollout:
            values = settings["n_envs"] * settings["n_steps"] * obs
            what = (f"{_where(name, 'n_steps')} x n_envs = {settings['n_steps']} x {settings['n_envs']}: rollout "
                    f"buffer values ({obs} per observation, {values * _FLOAT_BYTES / 2**30:,.2f} GiB)")
            check_size("max_buffer_values", values, what, "n_steps")
        else:
            values = 2 * settings["buffer_size"] * obs
            what = (f"{_where(name, 'buffer_size')} = {settings['buffer_size']:,}: replay buffer values (2 x "
                    f"{obs} per transition, {values * _FLOAT_BYTES / 2**30:,.2f} GiB)")
            check_size("max_buffer_values", values, what, "buffer_size")

    return check


def deep_hyperparams(settings: dict[str, Any]) -> dict[str, Any]:
    """The SB3 constructor arguments among resolved deep-RL settings (unset ones left out,
    so SB3's defaults apply and do not enter the model's hash)."""
    return {_SB3_NAMES.get(k, k): v for k, v in settings.items()
            if k not in _NOT_SB3 and v is not None}


def _deep_run(sb3: str, stops: bool, settings: dict[str, Any], seed: int, context: BuildContext,
              fleet: bool = False, shared: bool = False) -> tuple[Any, int, dict[str, Any]]:
    """The training run behind a deep-RL task: the scenario it trains on, its seed and the
    keyword arguments of :func:`rl.deep.train_deep` (the training layouts, the world, the
    SB3 arguments, the copies, the environment; with ``fleet``, the fleet's stop-choice
    environment on the task's scenario, its ``n_auvs`` included; with ``shared``, the
    fleet's parameter-shared vector env, :data:`rl.deep.FLEET_SHARED_ENV_ID`)."""
    scenario = context.scenario
    layouts = None
    if settings.get(TRAINING) == ACROSS_LAYOUTS:
        if not context.training_layouts:
            raise ConfigError("training = 'across_layouts' needs the experiment's training_layouts",
                              "training_layouts")
        layouts = tuple(context.training_layouts)
        scenario = scenario.replace(layout_seed=layouts[0])
        seed = context.seed_index  # one model per training seed, whichever layout it is evaluated on
    env_id, env_kwargs = None, {}
    if shared:
        from rl.deep import FLEET_SHARED_ENV_ID

        env_id = FLEET_SHARED_ENV_ID
    if stops:
        from planners.stops import FLEET_STOP_ENV_ID, STOP_ENV_IDS

        env_id = FLEET_STOP_ENV_ID if fleet else STOP_ENV_IDS[context.world]
        env_kwargs = {key: settings[key] for key in _STOP_ENV_SETTINGS[context.world]}
    arguments = dict(hyperparams=deep_hyperparams(settings), policy_kwargs={"net_arch": list(settings["net_arch"])},
                     layout_seeds=layouts, world=context.world, n_envs=settings["n_envs"], env_id=env_id,
                     env_kwargs=env_kwargs)
    return scenario, seed, arguments


def _deep_config(sb3: str, settings: dict[str, Any], seed: int, arguments: dict[str, Any]) -> Any:
    """The :class:`rl.deep.DeepConfig` of a training run (:func:`_deep_run`), as
    :func:`rl.deep.train_or_load_deep` makes it: its hash names the model's file."""
    from rl.deep import DeepConfig

    return DeepConfig(sb3, settings["timesteps"], seed, arguments["hyperparams"], arguments["policy_kwargs"],
                      arguments["layout_seeds"], arguments["world"], arguments["n_envs"], arguments["env_id"],
                      arguments["env_kwargs"])


def _deep_model(sb3: str, stops: bool = False, fleet: bool = False,
                shared: bool = False) -> Callable[[dict[str, Any], int, BuildContext], tuple[Any, Any]]:
    """An algorithm's ``trained_model``: the configuration and scenario of a task's model."""

    def model(settings: dict[str, Any], seed: int, context: BuildContext) -> tuple[Any, Any]:
        scenario, seed, arguments = _deep_run(sb3, stops, settings, seed, context, fleet, shared)
        return _deep_config(sb3, settings, seed, arguments), scenario

    return model


def _train_or_load(sb3: str, scenario: Any, settings: dict[str, Any], seed: int, context: BuildContext,
                   arguments: dict[str, Any]) -> Any:
    """The trained model of a deep-RL task (:func:`_deep_run`): trained in the task without a
    models directory; else loaded from it (or from the pretrained directories) or trained
    and kept there, saving the lineage's shorter budgets on the way (``context.checkpoints``,
    those that are exact); a directory this process cannot write is only read
    (:func:`rl.deep.train_or_load_deep`)."""
    from rl.deep import checkpoint_exact, train_deep, train_or_load_deep

    if context.models_dir is None:
        return train_deep(sb3, scenario, settings["timesteps"], seed, **arguments)
    config = _deep_config(sb3, settings, seed, arguments)
    checkpoints = [steps for steps in context.checkpoints if checkpoint_exact(config, steps, scenario)]
    return train_or_load_deep(context.models_dir, sb3, scenario, settings["timesteps"], seed,
                              checkpoints=checkpoints, pretrained=context.pretrained, keep_state=context.keep_state,
                              **arguments)


def _deep(sb3: str, stops: bool = False,
          fleet: bool = False) -> Callable[[Any, dict[str, Any], int, BuildContext], Any]:
    """Train (or load) the SB3 algorithm ``sb3`` (``"ppo"``, ``"dqn"`` or a class path); with
    ``stops``, on the world's stop-choice environment (:mod:`planners.stops`), the trained
    model then played on the kernel env by :class:`planners.stops.StopChoicePolicy`; with
    ``fleet`` too, on the fleet's (:class:`planners.stops.FleetStopChoiceEnv`), played on the
    fleet env by :class:`planners.stops.FleetStopChoicePolicy`."""

    def build(env: Any, settings: dict[str, Any], seed: int, context: BuildContext) -> Any:
        scenario, seed, arguments = _deep_run(sb3, stops, settings, seed, context, fleet)
        result = _train_or_load(sb3, scenario, settings, seed, context, arguments)
        if not stops:
            return result
        from planners.stops import FleetStopChoiceEnv, FleetStopChoicePolicy, StopChoicePolicy, make_stop_env

        if fleet:
            policy = FleetStopChoicePolicy.from_env(result.model, FleetStopChoiceEnv(context.scenario,
                                                                                     **arguments["env_kwargs"]))
            policy.result = result  # what _deep_record reads
            return policy

        return _StopPolicy(result, StopChoicePolicy.from_env(result.model, make_stop_env(
            context.world, context.scenario, **arguments["env_kwargs"])))

    return build


class _StopPolicy:
    """A trained stop-choice model as a benchmark policy: the adapter's actions, the training
    run's record (:func:`_deep_record`)."""

    def __init__(self, result: Any, adapter: Any):
        self.result = result
        self.adapter = adapter

    def begin_episode(self, env: Any, obs: Any = None, info: Any = None) -> None:
        self.adapter.begin_episode(env.unwrapped, obs, info)

    def predict(self, obs: Any, deterministic: bool = True) -> Any:
        return self.adapter.predict(obs, deterministic)


def _deep_record(policy: Any, env: Any) -> dict[str, Any]:
    """A deep-RL task's model: its hash, its training seed, whether it was loaded, the
    training time (0 when loaded), the model file's name and SHA-256, and what happened to
    an unusable stored model."""
    result = getattr(policy, "result", policy)
    out = {"model": result.config_hash, "training_seed": result.config.seed, "model_loaded": result.loaded,
           "train_seconds": result.train_seconds, "train_cpu_seconds": result.cpu_seconds}
    if getattr(result, "path", None) is not None:
        out["model_file"] = result.path.name
        out["model_sha256"] = result.sha256
        out["model_shipped"] = result.path.parent.name == "pretrained" and result.path.parent.parent.name == "benchmark"
    if getattr(result, "note", ""):
        out["model_note"] = result.note
    return out


def sb3_algorithm(sb3: str, label: str, settings: dict[str, Setting] | None = None, *, name: str = "",
                  worlds: tuple[str, ...] = (GRID,)) -> Algorithm:
    """A benchmark algorithm for a Stable-Baselines3 algorithm on the ``vector`` observation.

    ``sb3`` is ``"ppo"``, ``"dqn"``, ``"sac"`` or a class as ``"package.module:Class"`` (e.g.
    ``"stable_baselines3:A2C"``). It gets the common deep-RL settings (``timesteps``,
    ``n_envs``, ``net_arch``, ``learning_rate``, ``discount``, ``training``,
    ``training_seeds``) and ``settings`` (more SB3 constructor arguments, under their own
    names). Models are kept under the results directory and reused when a task's
    configuration matches. ``name`` defaults to the registered name (the entry point's or the
    ``[plugins]`` key); ``worlds`` are the worlds whose actions it can take (the grid's
    discrete moves, the continuous world's box).
    """
    settings = {**_DEEP_COMMON, **(settings or {})}
    rollout = "n_steps" in settings
    sized = rollout or "buffer_size" in settings
    return Algorithm(name or label.lower(), label, "rl", settings, _deep(sb3), _deep_record, observation="vector",
                     modules=_DEEP_MODULES, trains_model=True, worlds=worlds, trained_model=_deep_model(sb3),
                     check_scenario=_check_deep_sizes(name or label.lower(), rollout) if sized else None)


#: The stop-choice environment's settings the benchmark exposes, by world.
_STOP_ENV_SETTINGS = {GRID: ("candidates",), CONTINUOUS: ("legs",)}
#: MaskablePPO on the stop-choice environment: a decision is a stop and its dwell (several
#: kernel steps), so its budgets count decisions.
_STOP_PPO = {
    **_DEEP_COMMON,
    "timesteps": Setting(default=200_000, kind="int", lo=1, hi=10**9, quick=256,
                         doc="decisions of training (each a stop and its dwell: several kernel steps), all copies "
                             "together"),
    "n_envs": Setting(default=8, kind="int", lo=1, hi=1024, quick=2,
                      doc="copies of the stop-choice environment stepped together (SB3's DummyVecEnv)"),
    **_PPO,
    "n_steps": Setting(default=256, kind="int", lo=2, hi=1_000_000, quick=32,
                       doc="decisions per copy per rollout"),
    "batch_size": Setting(default=256, kind="int", lo=2, hi=1_000_000, quick=32, doc="minibatch size"),
    "candidates": Setting(default="own+shared", kind="str", choices=("own", "own+shared"),
                          doc="grid: the candidate stops, one per node ('own', where one step earns most from it) or "
                              "two ('own+shared': also the best group stop that still serves it)"),
    "legs": Setting(default="ompl", kind="str", choices=("ompl", "straight"), quick="straight",
                    doc="continuous world: legs between stops around obstacles ('ompl', planned once per layout) "
                        "or straight ('straight', given up when blocked)"),
}
_NOT_SB3 += ("candidates", "legs")


def declared(cls: Any, *, skip: tuple[str, ...] = (), **overrides: dict[str, Any]) -> dict[str, Setting]:
    """An algorithm's settings as its class declares them (``cls.parameters``, name ->
    :class:`swiptopt.validation.Param`), read, not copied: the registry adds only what is the
    benchmark's own, per setting (``quick``: the value under ``--quick``; ``hi_of`` and
    ``hi_doc``: an upper end the task's scenario sets). ``skip`` leaves out arguments the
    benchmark sets itself (the seed)."""
    out = {}
    for name, param in cls.parameters.items():  # type: ignore[attr-defined]
        if name not in skip:
            # an experiment file's 3.0 for an integer setting is read as 3 (the class, called
            # from code, may be strict about it)
            out[name] = Setting(**{**dataclasses.asdict(param), "strict": False, **overrides.get(name, {})})
    unknown = set(overrides) - set(out)
    if unknown:  # pragma: no cover - a registry typo
        raise AssertionError(f"{cls.__name__} declares no {sorted(unknown)}")
    return out


def _n_nodes(scenario: Any) -> int:
    return int(scenario.n_nodes)


def _depth_cells(scenario: Any) -> int:
    return int(scenario.grid_shape[2]) - 1


#: The classes whose declared settings are the planners' (their modules are light: no solver
#: is imported until a plan is made).
_KMEANS_TSP = declared(RewardKMeansTspPlanner, skip=("seed",),
                       k={"hi_of": _n_nodes, "hi_doc": "n_nodes"}, ompl_time_limit_s={"quick": 0.05})
_LAWNMOWER = declared(LawnmowerPlanner, depth_cell={"hi_of": _depth_cells, "hi_doc": "the grid's depth cells - 1"})
_CONTINUOUS_QUICK = {"k": {"hi_of": _n_nodes, "hi_doc": "n_nodes"}, "k_max": {"quick": 4}, "k_patience": {"quick": 1},
                     "search_evaluations": {"quick": 20}}
_OMPL_TOUR = declared(OmplTourPlanner, skip=("seed",), ompl_iterations={"quick": 50}, **_CONTINUOUS_QUICK)
_STRAIGHT_LINE = declared(StraightLinePlanner, skip=("seed",), **_CONTINUOUS_QUICK)

#: The MILP's settings, the single AUV's and the fleet's.
_MILP = {
    "budget": Setting(default="default", kind="str", choices=tuple(BUDGETS), quick="quick",
                      doc="named search budget of planners.optimal.BUDGETS (deterministic limits)"),
    "max_nodes": Setting(default=None, kind="int", lo=1, hi=10**9, optional=True, quick=1,
                         doc="branch-and-bound nodes (default: the budget's)"),
    "time_limit_s": Setting(default=None, lo=0, lo_open=True, hi=7 * 86_400, optional=True, unit="s",
                            doc="wall-clock safety net (default: the budget's); a task that hits it "
                                "records so, as its result then depends on the machine's speed"),
}

# ------------------------------------------------------------------ fleets

#: The fleet's tabular agents train in the Python loop (the fleet has no compiled trainer).
_FLEET_TRAINING = {"train_episodes": _RL_TRAINING["train_episodes"]}


def _fleet_agents(algorithm: str) -> Callable[[Any, dict[str, Any], int, BuildContext], Any]:
    """Independent agents of ``algorithm``, one per AUV (:class:`rl.fleet.IndependentAgents`),
    trained in the task's fleet env (the random agent learns nothing)."""

    def build(env: Any, settings: dict[str, Any], seed: int, context: BuildContext) -> Any:
        from rl import TabularConfig
        from rl.fleet import IndependentAgents, train_independent

        settings = dict(settings)
        episodes = settings.pop("train_episodes", 0)
        config = None if algorithm == "random" else TabularConfig().replace(**settings)
        n_states = env.observation_space(env.possible_agents[0]).n
        agents = IndependentAgents.make(algorithm, env.fleet.n_auvs, n_states, config=config, seed=seed)
        if algorithm != "random" and episodes:
            train_independent(agents, env, episodes, seed=seed)
        return agents

    return build


#: Parameter-shared PPO's settings: the deep algorithms' and PPO's, ``n_envs`` counting
#: copies of the fleet (each AUV of each copy is one sub-environment).
_SHARED_PPO = {
    "timesteps": Setting(default=262_144, kind="int", lo=1, hi=10**9, quick=1024,
                         doc="AUV steps of training, every AUV of every copy together (PPO collects whole "
                             "rollouts of n_envs x n_auvs x n_steps steps)"),
    "n_envs": Setting(default=8, kind="int", lo=1, hi=1024, quick=2,
                      doc="copies of the fleet stepped together (each AUV of each copy one sub-environment)"),
    **{name: _DEEP_COMMON[name] for name in ("net_arch", "learning_rate", "discount")},
    **_PPO,
}


def _shared_ppo(env: Any, settings: dict[str, Any], seed: int, context: BuildContext) -> Any:
    """PPO with one policy shared by every AUV (:mod:`rl.fleet`), trained on the task's
    layout with the task's seed (or loaded from the models directory, as every deep-RL
    model: :func:`_train_or_load`), then acting for each AUV on its own observation."""
    from rl.fleet import SharedPolicy

    scenario, seed, arguments = _deep_run("ppo", False, settings, seed, context, shared=True)
    result = _train_or_load("ppo", scenario, settings, seed, context, arguments)
    policy = SharedPolicy(result.model)
    policy.result = result  # what _deep_record reads
    return policy


#: The fleet's stop-choosing PPO: the single agent's settings, ``timesteps`` counting every
#: AUV's decisions.
_FLEET_STOP_PPO = {
    **{name: _STOP_PPO[name] for name in ("n_envs", "net_arch", "learning_rate", "discount", "candidates")},
    **{name: _STOP_PPO[name] for name in _PPO},
    "timesteps": Setting(default=65_536, kind="int", lo=1, hi=10**9, quick=256,
                         doc="decisions of training, every AUV's of every copy together (each a stop and its "
                             "dwell: several kernel steps)"),
}


def _fleet_routing_record(policy: Any, env: Any) -> dict[str, Any]:
    plan = getattr(policy, "plan_", None)
    if plan is None:
        return {}
    return {"plan_status": plan.status,
            "plan_details": {k: v for k, v in plan.details.items() if isinstance(v, (int, float, str, list))}}


def _fleet_algorithms() -> tuple[Algorithm, ...]:
    """The algorithms that run a fleet (docs/fleet.md)."""
    from planners.fleet import FleetRoutingPlanner

    return (
        Algorithm("fleet_routing", "k-means + vehicle routing", "planner",
                  declared(FleetRoutingPlanner, skip=("seed",), k={"hi_of": _n_nodes, "hi_doc": "n_nodes"}),
                  _planner("FleetRoutingPlanner", seeded=True, module="planners.fleet"), _fleet_routing_record,
                  fleet=True),
        Algorithm("shared_ppo", "parameter-shared PPO", "rl", _SHARED_PPO, _shared_ppo, _deep_record,
                  observation="vector", modules=_DEEP_MODULES, trains_model=True, fleet=True,
                  trained_model=_deep_model("ppo", shared=True)),
        Algorithm("fleet_stop_ppo", "stop-choosing PPO (fleet)", "rl", _FLEET_STOP_PPO,
                  _deep("maskable_ppo", stops=True, fleet=True), _deep_record, modules=(*_DEEP_MODULES, "sb3_contrib"),
                  trains_model=True, fleet=True, trained_model=_deep_model("maskable_ppo", True, True)),
        Algorithm("fleet_milp", "MILP (fleet)", "planner", _MILP, _milp, _milp_record, fleet=True),
        Algorithm("fleet_q_learning", "independent Q-learning", "rl", {**_FLEET_TRAINING, **_TABULAR},
                  _fleet_agents("q_learning"), observation="tabular", fleet=True),
        Algorithm("fleet_random", "random (each AUV)", "rl", {}, _fleet_agents("random"), observation="tabular",
                  fleet=True),
    )


ALGORITHMS: dict[str, Algorithm] = {
    a.name: a
    for a in (
        Algorithm("q_learning", "Q-learning", "rl", {**_RL_TRAINING, **_TABULAR}, _rl("q_learning"),
                  observation="tabular", check=_check_tabular("q_learning")),
        Algorithm("sarsa", "SARSA", "rl", {**_RL_TRAINING, **_TABULAR}, _rl("sarsa"), observation="tabular",
                  check=_check_tabular("sarsa")),
        Algorithm("random", "random", "rl", {**_RL_TRAINING, "train_episodes": Setting(
            default=0, kind="int", lo=0, limit="max_training_episodes", doc="ignored: the random agent learns nothing",
        )}, _rl("random"), observation="tabular", worlds=WORLDS),
        sb3_algorithm("ppo", "PPO", _PPO, name="ppo", worlds=WORLDS),
        sb3_algorithm("dqn", "DQN", _DQN, name="dqn"),
        sb3_algorithm("sac", "SAC", _SAC, name="sac", worlds=(CONTINUOUS,)),
        Algorithm("stop_ppo", "stop-choosing PPO", "rl", _STOP_PPO, _deep("maskable_ppo", stops=True), _deep_record,
                  modules=(*_DEEP_MODULES, "sb3_contrib"), trains_model=True, worlds=WORLDS,
                  trained_model=_deep_model("maskable_ppo", True),
                  check_scenario=_check_deep_sizes("stop_ppo", True, candidates=True)),
        Algorithm(
            "kmeans_tsp",
            "k-means + TSP",
            "planner",
            _KMEANS_TSP,
            _planner("RewardKMeansTspPlanner", seeded=True),
            uses_ompl=lambda settings: settings.get("tour_costs") == "ompl",
        ),
        Algorithm(
            "lawnmower",
            "lawnmower",
            "planner",
            _LAWNMOWER,
            _planner("LawnmowerPlanner"),
        ),
        Algorithm(
            "greedy", "greedy", "planner", declared(GreedyPlanner),
            _planner("GreedyPlanner"),
        ),
        Algorithm("rate_greedy", "rate-greedy", "planner", {}, _planner("RateGreedyPlanner")),
        Algorithm("ompl_tour", "OMPL tour", "planner", _OMPL_TOUR,
                  _planner("OmplTourPlanner", seeded=True, module="planners.continuous"),
                  worlds=(CONTINUOUS,), uses_ompl=lambda settings: True),
        Algorithm("straight_line", "straight line", "planner", _STRAIGHT_LINE,
                  _planner("StraightLinePlanner", seeded=True, module="planners.continuous"), worlds=(CONTINUOUS,)),
        Algorithm("milp", "MILP", "planner", _MILP, _milp, _milp_record),
        *_fleet_algorithms(),
    )
}


# ------------------------------------------------------------------ the registry

#: The entry-point group through which installed distributions add algorithms.
ENTRY_POINT_GROUP = "swiptopt.algorithms"
#: A plugin's factory: ``package.module:function`` (dotted attribute path allowed).
FACTORY_PATTERN = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*:[A-Za-z_]\w*(\.[A-Za-z_]\w*)*")
#: An algorithm's name: it names table rows and settings keys.
NAME_PATTERN = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,63}")
#: Where each observation comes from, for the error that names the valid choices.
OBSERVATIONS = WORLD_OBSERVATIONS[GRID]

#: Algorithms registered from outside the project, by name, with the factory they came from.
_PLUGINS: dict[str, tuple[str, Algorithm]] = {}


def _check_plugin(name: str, source: str, made: Any, where: str) -> Algorithm:
    if not isinstance(made, Algorithm):
        raise ConfigError(
            f"{where} = {source!r} returned {type(made).__name__}, not a swiptopt.benchmark.algorithms.Algorithm "
            "(sb3_algorithm(...) makes one for a Stable-Baselines3 algorithm)",
            name,
        )
    if not callable(made.build):
        raise ConfigError(f"{where} = {source!r} returned an Algorithm without a build function", name)
    if not isinstance(made.settings, dict) or not all(
            isinstance(k, str) and isinstance(v, Setting) for k, v in made.settings.items()):
        raise ConfigError(f"{where} = {source!r} returned an Algorithm whose settings are not Settings by name", name)
    if not isinstance(made.worlds, tuple) or not made.worlds or not set(made.worlds) <= set(WORLDS):
        raise ConfigError(f"{where} = {source!r} returned an Algorithm with worlds {made.worlds!r}: a non-empty tuple "
                          f"of {', '.join(map(repr, WORLDS))}", name)
    if made.observation not in (None, *OBSERVATIONS):
        raise ConfigError(f"{where} = {source!r} returned an Algorithm with observation {made.observation!r}: "
                          f"one of {', '.join(OBSERVATIONS)} or None", name)
    return replace(made, name=name)


def _said(exc: BaseException) -> str:
    """What an exception of a plugin's code says, on one line: ``Type: message``."""
    message = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {message}" if message else type(exc).__name__


def _is_factory(obj: Any, module_name: str) -> bool:
    """Whether ``obj`` may be called as a plugin's factory: a plain Python function defined
    in the module the source names or in one of its submodules (a package re-exporting its
    factory), callable without arguments; not a builtin such as ``os.abort`` or
    ``sys.exit``, not a class, not a function another module defines. Decided without
    calling it."""
    import inspect

    defined_in = getattr(obj, "__module__", None)
    if not inspect.isfunction(obj) or not isinstance(defined_in, str) or not (
            defined_in == module_name or defined_in.startswith(module_name + ".")):
        return False
    try:
        inspect.signature(obj).bind()
    except (TypeError, ValueError):
        return False
    return True


def load_plugin(name: str, source: Any, where: str = "") -> Algorithm:
    """Register the algorithm made by the factory ``source`` (``"package.module:function"``)
    under ``name`` and return it; anything wrong (a name taken by a built-in algorithm, a
    module that does not import, a missing factory, one that fails or returns something else
    than an :class:`Algorithm`) is a :class:`ConfigError` naming ``where``.

    This imports the module and calls the factory: the plugin's code runs in this process.
    Only a plain function defined in that module (or a submodule) and taking no arguments
    is called (or an
    :class:`Algorithm` it holds is taken); anything else (``os:abort``, ``sys:exit``, a
    class) is refused without being called. Whatever the plugin's code raises, ``SystemExit``
    and ``KeyboardInterrupt`` included, becomes a :class:`ConfigError`. Callers decide
    whether the source may be loaded at all (an experiment file's ``[plugins]`` only with
    the user's consent: :meth:`~swiptopt.benchmark.experiment.Experiment.from_dict`)."""
    import importlib

    where = where or f"plugins.{name}"
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        raise ConfigError(f"{where}: {name!r} is not allowed as an algorithm's name: a letter, then up to 63 "
                          "letters, digits, '_' or '-'", "plugins")
    if name in ALGORITHMS:
        raise ConfigError(f"{where}: {name!r} is a built-in algorithm; give the plugin another name", name)
    if not isinstance(source, str) or not FACTORY_PATTERN.fullmatch(source):
        raise ConfigError(f"{where} = {source!r} must name a factory as 'package.module:function'", name)
    known = _PLUGINS.get(name)
    if known is not None and known[0] == source:
        return known[1]
    module_name, _, attribute = source.partition(":")
    # the plugin's code may raise anything, SystemExit and KeyboardInterrupt included: all of
    # it is bad input, reported in one line
    try:
        obj: Any = importlib.import_module(module_name)
    except BaseException as exc:
        raise ConfigError(f"{where} = {source!r}: cannot import {module_name!r} ({_said(exc)})", name) from None
    try:
        for part in attribute.split("."):
            obj = getattr(obj, part)
    except AttributeError:
        raise ConfigError(f"{where} = {source!r}: module {module_name!r} has no {attribute!r}", name) from None
    except BaseException as exc:
        raise ConfigError(f"{where} = {source!r}: looking up {attribute!r} failed ({_said(exc)})", name) from None
    if isinstance(obj, Algorithm):
        made = obj
    elif _is_factory(obj, module_name):
        try:
            made = obj()
        except BaseException as exc:
            raise ConfigError(f"{where} = {source!r}: the factory failed ({_said(exc)})", name) from None
    else:
        raise ConfigError(f"{where} = {source!r} is not a factory: a function of no arguments defined in "
                          f"{module_name!r}, or an Algorithm, is required", name)
    try:
        algorithm = _check_plugin(name, source, made, where)
    except ConfigError:
        raise
    except BaseException as exc:  # an Algorithm subclass's own code
        raise ConfigError(f"{where} = {source!r}: checking what the factory returned failed ({_said(exc)})",
                          name) from None
    _PLUGINS[name] = (source, algorithm)
    return algorithm


def _entry_point(name: str) -> str | None:
    """The factory of the installed entry point ``name`` in :data:`ENTRY_POINT_GROUP`."""
    from importlib import metadata

    for entry in metadata.entry_points(group=ENTRY_POINT_GROUP):
        if entry.name == name:
            return entry.value
    return None


def entry_point_names() -> list[str]:
    """The names of the algorithms installed distributions add (entry points)."""
    from importlib import metadata

    return sorted({entry.name for entry in metadata.entry_points(group=ENTRY_POINT_GROUP)})


def get_algorithm(name: Any, plugin: str = "") -> Algorithm:
    """The algorithm ``name``: a built-in one, a plugin (``plugin`` is its factory, from an
    experiment's ``[plugins]``) or an installed entry point; an unknown name is a
    :class:`ConfigError` naming the valid choices."""
    if isinstance(name, str) and name in ALGORITHMS:
        return ALGORITHMS[name]
    if plugin:
        return load_plugin(name, plugin)
    if isinstance(name, str) and name in _PLUGINS:
        return _PLUGINS[name][1]
    if isinstance(name, str) and NAME_PATTERN.fullmatch(name):
        source = _entry_point(name)
        if source is not None:
            return load_plugin(name, source, f"entry point {name!r} of group {ENTRY_POINT_GROUP!r}")
    known = [*ALGORITHMS, *entry_point_names()]
    raise ConfigError(
        f"unknown algorithm {name!r}{did_you_mean(name, known)}: choose one of {', '.join(known)} "
        "(or add one through [plugins] or an entry point)",
        "algorithm",
    )


def _where(name: str, key: str) -> str:
    return f"algorithms.{name}.{key}"


def _plugin_code(name: str, what: str, call: Callable[..., Any], *args: Any) -> Any:
    """``call(*args)``, code of algorithm ``name``: a built-in algorithm's as it is (an
    exception other than a :class:`ConfigError` is a bug there), a plugin's with whatever it
    raises (``SystemExit`` included) turned into a one-line :class:`ConfigError`."""
    if name in ALGORITHMS:
        return call(*args)
    try:
        return call(*args)
    except ConfigError:
        raise
    except BaseException as exc:
        raise ConfigError(f"algorithms.{name}: its {what} failed ({_said(exc)})", name) from None


def resolve_settings(name: str, settings: dict[str, Any], world: str = GRID) -> dict[str, Any]:
    """The algorithm's defaults updated with ``settings``, each value checked against the
    algorithm's schema and normalised; an unknown algorithm, key or value is a
    :class:`ConfigError` naming the experiment's key and what is allowed.

    ``observation``, where given, must be the one the algorithm acts on in ``world`` (the
    continuous world has only ``"vector"``) and is left out of the result (it is the
    algorithm's, not a choice)."""
    algorithm = get_algorithm(name)
    schema = algorithm.settings
    settings = check_keys(f"algorithms.{name}", settings, name)
    if "observation" in settings and "observation" not in schema:
        _check_observation(algorithm, settings.pop("observation"), world)
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
        out[key] = check_setting(_where(name, key), value, spec, key)
        if spec.limit and out[key] is not None:
            note = training_log_note(out[key]) if spec.limit == "max_training_episodes" else ""
            check_size(spec.limit, out[key], _where(name, key), key, note=note)
    if algorithm.check is not None:
        _plugin_code(name, "settings check", algorithm.check, out)
    return out


#: The one observation of the continuous world (every algorithm acts on it there).
CONTINUOUS_OBSERVATION = "vector"


def _check_observation(algorithm: Algorithm, value: Any, world: str = GRID) -> None:
    where = _where(algorithm.name, "observation")
    if world == CONTINUOUS:
        if value != CONTINUOUS_OBSERVATION:
            raise ConfigError(f"{where} = {value!r} is not allowed: the continuous world has one observation, "
                              f"{CONTINUOUS_OBSERVATION!r}", "observation")
        return
    if algorithm.observation is None:
        if value not in OBSERVATIONS:
            raise ConfigError(f"{where} = {value!r} is not allowed: must be one of "
                              f"{', '.join(map(repr, OBSERVATIONS))}", "observation")
        return
    if value != algorithm.observation:
        others = "; ".join(
            f"on {o!r}: {', '.join(n for n, a in ALGORITHMS.items() if a.observation == o)}"
            for o in OBSERVATIONS if o != algorithm.observation
        )
        raise ConfigError(
            f"{where} = {value!r} is not allowed: {algorithm.label} acts on the {algorithm.observation!r} "
            f"observation, the only valid choice (algorithms {others})",
            "observation",
        )


def check_settings_for(name: str, settings: dict[str, Any], scenario: Any, where: str = "") -> None:
    """Check the settings whose range depends on the scenario (a grid depth, a node count).

    ``settings`` are resolved (:func:`resolve_settings`); ``where`` says which scenario (a
    sweep point) for the message.
    """
    algorithm = get_algorithm(name)
    n_auvs = getattr(scenario, "n_auvs", 1)
    if n_auvs > 1 and not algorithm.fleet:
        fleet = [n for n, a in ALGORITHMS.items() if a.fleet]
        raise ConfigError(
            f"algorithms.{name}: {algorithm.label} runs one AUV, and the scenario{where} has n_auvs = {n_auvs}: "
            f"a fleet runs {', '.join(fleet)}", "n_auvs",
        )
    if algorithm.check_scenario is not None:
        _plugin_code(name, "scenario check", algorithm.check_scenario, settings, scenario)
    for key, spec in algorithm.settings.items():
        value = settings.get(key)
        if spec.hi_of is None or value is None:
            continue
        hi = _plugin_code(name, f"upper end of {key!r}", spec.hi_of, scenario)
        if not spec.in_range(value, hi):
            raise ConfigError(
                f"{_where(name, key)} = {value!r} is out of range{where}: must be {spec.allowed(hi)} "
                f"(at most {spec.hi_doc})",
                key,
            )


def check_world_of(name: str, world: str) -> None:
    """A :class:`ConfigError` unless algorithm ``name`` runs in ``world``, naming the
    algorithm, the worlds it runs in and the algorithms that run in ``world``."""
    algorithm = get_algorithm(name)
    if world in algorithm.worlds:
        return
    here = [n for n, a in ALGORITHMS.items() if world in a.worlds]
    raise ConfigError(
        f"algorithms.{name}: {algorithm.label} runs in the {' and '.join(algorithm.worlds)} world only, not in this "
        f"experiment's world = {world!r}; the algorithms of the {world} world are {', '.join(here)}",
        "world",
    )


def quick_settings(name: str, settings: dict[str, Any], world: str = GRID) -> dict[str, Any]:
    """``settings`` shrunk for a smoke test (``--quick``): each setting with a ``quick`` value
    capped at it (numbers) or replaced by it (anything else). ``world``: the experiment's."""
    resolved = resolve_settings(name, settings, world)
    out = dict(settings)
    for key, spec in get_algorithm(name).settings.items():
        value = resolved[key]
        if spec.quick is None or value is None:
            continue
        numeric = spec.kind in ("int", "float")
        out[key] = min(value, spec.quick) if numeric else spec.quick
    return out


def task_extra(name: str, policy: Any, env: Any) -> dict[str, Any]:
    """What a task of algorithm ``name`` records beside its episodes, from the evaluated
    policy (empty for algorithms without a ``record``)."""
    record = get_algorithm(name).record
    return record(policy, env) if record is not None else {}


def build_policy(name: str, env: Any, settings: dict[str, Any], seed: int, context: BuildContext | None = None) -> Any:
    """The trained or planning policy of algorithm ``name`` for ``env`` (``context``:
    what the task knows besides; by default the environment's scenario and world, and
    nothing else). An algorithm that does not run in the env's world is a ConfigError."""
    from swiptopt.env_continuous import AuvSwiptContinuousEnv

    algorithm = get_algorithm(name)
    assert algorithm.build is not None
    if context is None:
        world = CONTINUOUS if isinstance(env.unwrapped, AuvSwiptContinuousEnv) else GRID
        context = BuildContext(scenario=env.unwrapped.scenario, world=world)
    check_world_of(name, context.world)
    return algorithm.build(env, resolve_settings(name, settings), seed, context)


def labels() -> dict[str, str]:
    """Every known algorithm's label by name (built-in and registered plugins)."""
    out = {name: a.label for name, a in ALGORITHMS.items()}
    out.update({name: a.label for name, (_, a) in _PLUGINS.items()})
    return out


__all__ = [
    "ACROSS_LAYOUTS",
    "ALGORITHMS",
    "BuildContext",
    "ENTRY_POINT_GROUP",
    "PER_LAYOUT",
    "get_algorithm",
    "load_plugin",
    "sb3_algorithm",
    "MILP_BOUND",
    "MILP_EXPECTED_BOUND",
    "Algorithm",
    "Setting",
    "build_policy",
    "check_settings_for",
    "check_world_of",
    "labels",
    "quick_settings",
    "resolve_settings",
    "task_extra",
]
