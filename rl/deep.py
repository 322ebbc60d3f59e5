"""Deep-RL contenders: Stable-Baselines3's PPO, DQN and SAC and sb3-contrib's MaskablePPO.

One entry point trains any of them (:func:`train_deep`), or any other SB3 algorithm named by
its class (``"stable_baselines3:A2C"``), in either world (:mod:`swiptopt.worlds`): the
paper's grid (discrete moves: PPO, DQN) or the continuous world (velocity commands in a
``Box``: PPO, SAC), or on any registered environment over a scenario (``env_id``: the stop
choosing environment of :mod:`planners.stops`, which MaskablePPO trains on). ``n_envs``
copies of the environment train at once, stepped together by
:class:`rl.vec_env.Sb3VectorEnv` (one compiled call for all copies of a world's env) or by
SB3's ``DummyVecEnv`` (other environments): the same episodes either way.

Trained models are kept as their network weights (:func:`save_weights`: a ``.npz`` of
arrays and a JSON header, read back with ``allow_pickle=False``), never as SB3's ``.zip``,
whose ``load`` unpickles what the file holds: a weights file is data, and reading one runs
no code. :func:`train_or_load_deep` keeps them in a directory under names made of
:func:`deep_config_hash` and records each file's SHA-256 in the directory's manifest
(``manifest.json``, written atomically): it loads only a file whose digest the manifest
records, so a model it reuses is one it wrote (or one a directory of ``pretrained`` models
vouches for), and retrains otherwise, saying why in the result's ``note``.
:func:`save_deep` / :func:`load_deep` still read and write SB3's zips for users who want
them; such a zip is code, like a pickle: load only zips you made, or check one against the
SHA-256 you recorded (``load_deep(..., sha256=...)``).

Reproducible on the CPU: the same configuration gives the same trained model, bit for bit,
on any run and any x86-64 CPU with AVX2. :func:`pin_torch` runs torch on one thread with
deterministic algorithms and the CPU paths of :func:`swiptopt.fpmath.pin_torch_cpu_paths`,
the device is always ``"cpu"``, SB3 seeds its generators from the configuration's seed, and
copy i of the environment is seeded with seed + i at the first reset. SB3's seeding also
sets Python's ``random``, NumPy's global generator and torch's global seed (SB3 draws from
them): a side effect of training with SB3, not of this project.

Stable-Baselines3 and torch (the ``deeprl`` extra) load inside the functions that use them:
``import rl`` does not import them.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import hashlib
import inspect
import json
import math
import os
import re
import time
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from swiptopt.env import INFO_KEY, check_layout_seeds
from swiptopt.errors import ConfigError, did_you_mean
from swiptopt.files import can_make_files_in
from swiptopt.fpmath import pin_torch_cpu_paths, torch_cpu_path_overrides
from swiptopt.scenario import Scenario
from swiptopt.validation import Spec, check_value
from swiptopt.worlds import ENV_IDS, GRID, check_world, make_env

#: The algorithms :func:`train_deep` trains by name, with their class. Any other SB3
#: algorithm is named by its class as ``"package.module:Class"`` (``"stable_baselines3:A2C"``).
DEEP_ALGORITHMS = {
    "dqn": "rl.deep:StepDQN",
    "ppo": "stable_baselines3:PPO",
    "sac": "stable_baselines3:SAC",
    "maskable_ppo": "sb3_contrib:MaskablePPO",
}
#: ``"package.module:Class"``: an algorithm class named by where it lives.
CLASS_PATH = re.compile(r"[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*:[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*")
#: The attribute a model saved by :func:`save_deep` carries with its :func:`deep_config_hash`.
HASH_ATTRIBUTE = "swiptopt_config_hash"
#: The format named in a weights file's header (:func:`save_weights`).
WEIGHTS_FORMAT = "swiptopt-weights-1"
#: The manifest of a model directory: file name -> SHA-256 and what the file holds.
MANIFEST = "manifest.json"
#: The suffix of weights files.
WEIGHTS_SUFFIX = ".npz"

#: SB3 constructor arguments :func:`train_deep` sets itself (never through ``hyperparams``).
_RESERVED = ("policy", "env", "seed", "device", "policy_kwargs", "verbose", "tensorboard_log", "_init_setup_model")

#: The observation the deep agents act on.
OBSERVATION = "vector"
#: The most copies of the environment one training steps at once.
MAX_ENVS = 1024
#: The ``env_id`` of parameter-shared fleet training: not a Gymnasium registration but
#: :func:`rl.fleet.make_shared_vec_env` over ``n_envs`` copies of the scenario's fleet, whose
#: sub-environments are every AUV of every copy (one policy for all of them). Its steps are
#: AUV steps, and an on-policy rollout is ``n_envs * n_auvs * n_steps`` of them.
FLEET_SHARED_ENV_ID = "swiptopt/FleetShared"


def _check_algorithm(algorithm: Any) -> str:
    if isinstance(algorithm, str) and (algorithm in DEEP_ALGORITHMS or CLASS_PATH.fullmatch(algorithm)):
        return algorithm
    raise ConfigError(
        f"unknown deep-RL algorithm {algorithm!r}{did_you_mean(algorithm, DEEP_ALGORITHMS)}: "
        f"choose one of {sorted(DEEP_ALGORITHMS)} or name an SB3 algorithm class as 'package.module:Class'",
        "algorithm",
    )


def _algorithm_class(algorithm: str) -> type:
    """The SB3 class of ``algorithm`` (a name of :data:`DEEP_ALGORITHMS` or a class path)."""
    import importlib

    try:
        from stable_baselines3.common.base_class import BaseAlgorithm
    except ImportError:  # pragma: no cover - depends on the installation
        raise ConfigError(
            "deep RL needs Stable-Baselines3: pip install 'swiptopt[deeprl]'", "algorithm"
        ) from None
    module_name, _, qualname = DEEP_ALGORITHMS.get(algorithm, _check_algorithm(algorithm)).partition(":")
    try:
        obj: Any = importlib.import_module(module_name)
        for part in qualname.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError) as exc:
        raise ConfigError(f"deep-RL algorithm {algorithm!r} cannot be loaded: {type(exc).__name__}: {exc}",
                          "algorithm") from None
    if not (isinstance(obj, type) and issubclass(obj, BaseAlgorithm)):
        raise ConfigError(f"deep-RL algorithm {algorithm!r} is not a Stable-Baselines3 algorithm class", "algorithm")
    return obj


def _step_dqn_class() -> type:
    """:class:`StepDQN`, built on first use (SB3 loads then)."""
    from stable_baselines3 import DQN

    class StepDQN(DQN):
        """SB3's DQN with its exploration decaying over a fixed number of steps.

        ``exploration_steps``: epsilon falls linearly from ``exploration_initial_eps`` to
        ``exploration_final_eps`` over that many environment steps, then stays there,
        whatever the run's total (SB3's own ``exploration_fraction`` is a share of the
        total, so a longer run explores longer and its model after n steps is not the model
        of a run of n steps; this one's is: :func:`checkpoint_exact`). Everything else is
        SB3's DQN.
        """

        def __init__(self, *args: Any, exploration_steps: int = 100_000, **kwargs: Any):
            steps = Spec(kind="int", lo=1, strict=True, unit="steps")
            self.exploration_steps = check_value("exploration_steps", exploration_steps, steps)
            super().__init__(*args, **kwargs)

        def _on_step(self) -> None:
            super()._on_step()
            done = min(1.0, self.num_timesteps / self.exploration_steps)
            start, end = self.exploration_initial_eps, self.exploration_final_eps
            self.exploration_rate = start + done * (end - start)
            self.logger.record("rollout/exploration_rate", self.exploration_rate)

    StepDQN.__module__ = __name__
    StepDQN.__qualname__ = "StepDQN"
    return StepDQN


_LAZY: dict[str, Callable[[], type]] = {"StepDQN": _step_dqn_class}
_BUILT: dict[str, type] = {}


def __getattr__(name: str) -> Any:
    """The classes built on first use (:class:`StepDQN`), so that ``import rl.deep`` loads
    no SB3."""
    if name in _LAZY:
        if name not in _BUILT:
            _BUILT[name] = _LAZY[name]()
        return _BUILT[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _file_stem(algorithm: str) -> str:
    """A file-name-safe form of an algorithm's name (a class path's class, in lower case)."""
    name = algorithm.rpartition(":")[2].rpartition(".")[2].lower() if ":" in algorithm else algorithm
    return re.sub(r"[^A-Za-z0-9_-]+", "_", name)


def _constructor_arguments(cls: type) -> set[str]:
    """The named arguments of ``cls``'s constructor, a subclass's ``**kwargs`` followed up
    its bases."""
    names: set[str] = set()
    for klass in cls.__mro__:
        init = klass.__dict__.get("__init__")
        if init is None:
            continue
        params = inspect.signature(init).parameters.values()
        names |= {p.name for p in params if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)}
        if not any(p.kind == p.VAR_KEYWORD for p in params):
            break
    return names


#: Ranges of SB3's numeric constructor arguments, checked before SB3 sees them (SB3 takes
#: some out-of-range values and fails later, mid-training). A callable (a schedule) is not
#: checked.
HYPERPARAM_BOUNDS: dict[str, Spec] = {
    "n_steps": Spec(kind="int", lo=1, hi=1 << 30, strict=True),
    "batch_size": Spec(kind="int", lo=2, hi=1 << 30, strict=True),
    "n_epochs": Spec(kind="int", lo=1, hi=10_000, strict=True),
    "buffer_size": Spec(kind="int", lo=1, hi=1 << 34, strict=True),
    "learning_starts": Spec(kind="int", lo=0, hi=1 << 40, strict=True),
    "gradient_steps": Spec(kind="int", lo=-1, hi=1 << 20, strict=True),
    "target_update_interval": Spec(kind="int", lo=1, hi=1 << 40, strict=True),
    "exploration_steps": Spec(kind="int", lo=1, hi=1 << 40, strict=True),
    "learning_rate": Spec(lo=0, lo_open=True),
    "gamma": Spec(lo=0, hi=1),
    "gae_lambda": Spec(lo=0, hi=1),
    "tau": Spec(lo=0, lo_open=True, hi=1),
    "ent_coef": Spec(lo=0),
    "vf_coef": Spec(lo=0),
    "clip_range": Spec(lo=0, lo_open=True),
    "max_grad_norm": Spec(lo=0, lo_open=True),
    "exploration_fraction": Spec(lo=0, hi=1),
    "exploration_initial_eps": Spec(lo=0, hi=1),
    "exploration_final_eps": Spec(lo=0, hi=1),
}
#: The widest hidden layer and the most layers a network of ``net_arch`` may have.
MAX_LAYER_WIDTH = 65_536
MAX_LAYERS = 64


def _check_layers(name: str, layers: Any) -> None:
    if not isinstance(layers, (list, tuple)) or len(layers) > MAX_LAYERS or not all(
            isinstance(w, (int, np.integer)) and not isinstance(w, bool) and 1 <= w <= MAX_LAYER_WIDTH for w in layers):
        raise ConfigError(
            f"{name} = {layers!r} must be a list of at most {MAX_LAYERS} layer widths, each an integer in "
            f"[1, {MAX_LAYER_WIDTH:,}]", "policy_kwargs")


def _check_policy_kwargs(cls: type, policy_kwargs: Mapping[str, Any]) -> None:
    """``policy_kwargs`` that ``cls``'s ``MlpPolicy`` takes, with a well-formed ``net_arch``."""
    policy = getattr(cls, "policy_aliases", {}).get("MlpPolicy")
    if policy is not None:
        allowed = sorted(_constructor_arguments(policy) - {"self", "observation_space", "action_space", "lr_schedule"})
        for key in policy_kwargs:
            if key not in allowed:
                raise ConfigError(f"unknown policy_kwargs key {key!r}{did_you_mean(key, allowed)}: "
                                  f"{policy.__name__} takes {', '.join(allowed)}", "policy_kwargs")
    arch = policy_kwargs.get("net_arch")
    if isinstance(arch, Mapping):
        for key, layers in arch.items():
            _check_layers(f"policy_kwargs.net_arch.{key}", layers)
    elif arch is not None:
        _check_layers("policy_kwargs.net_arch", arch)


def _blame(exc: BaseException) -> str:
    """The argument an error SB3 raised while building a model comes from: ``policy_kwargs``
    when the failing code is the policy's or torch's (a network it cannot build), else
    ``hyperparams``."""
    import traceback

    files = [frame.filename.replace("\\", "/") for frame in traceback.extract_tb(exc.__traceback__)]
    policy_code = ("stable_baselines3/common/policies.py", "stable_baselines3/common/torch_layers.py",
                   "/policies.py", "torch/nn/")
    return "policy_kwargs" if files and any(part in files[-1] for part in policy_code) else "hyperparams"


def _plain(name: str, value: Any) -> Any:
    """``value`` if it is JSON-able plain data (what a configuration may hold), else an error."""
    try:
        json.dumps(value, allow_nan=False)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} = {value!r} must be plain data (numbers, strings, lists, mappings)", name) from None
    return value


@dataclass(frozen=True)
class DeepConfig:
    """One deep-RL training run, validated at construction."""

    algorithm: str
    """A name of :data:`DEEP_ALGORITHMS`, or an SB3 algorithm class as ``"package.module:Class"``."""
    timesteps: int
    """Environment steps of training (all copies together). An on-policy algorithm collects
    whole rollouts of ``n_envs * n_steps`` steps, so it trains up to the next multiple."""
    seed: int = 0
    """Seeds SB3 (network initialisation, sampling, exploration) and the environments."""
    hyperparams: Mapping[str, Any] = field(default_factory=dict)
    """SB3 constructor arguments (``learning_rate``, ``n_steps``, ``buffer_size``, ...);
    unset ones keep SB3's defaults."""
    policy_kwargs: Mapping[str, Any] = field(default_factory=dict)
    """SB3's ``policy_kwargs`` (e.g. ``{"net_arch": [64, 64]}``)."""
    layout_seeds: range | tuple[int, ...] | None = None
    """Train across these layouts, one drawn per episode; ``None``: the scenario's layout. A
    ``range`` stays a range (it names its layouts by start, stop and step)."""
    world: str = GRID
    """The world trained in (:mod:`swiptopt.worlds`): ``"grid"`` or ``"continuous"``."""
    n_envs: int = 1
    """Copies of the environment stepped together (copy i seeded with ``seed + i``)."""
    env_id: str | None = None
    """A registered environment to train on instead of the world's own (made with
    ``gymnasium.make(env_id, scenario=..., layout_seeds=..., **env_kwargs)``), or
    :data:`FLEET_SHARED_ENV_ID` (the fleet's parameter-shared vector env)."""
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    """More arguments of ``env_id``'s environment (plain data)."""

    #: What the run's counts may hold, checked (and made Python ints) at construction.
    COUNTS: ClassVar[dict[str, Spec]] = {
        "timesteps": Spec(kind="int", lo=1, strict=True, unit="steps"),
        "seed": Spec(kind="int", lo=0, strict=True),
        "n_envs": Spec(kind="int", lo=1, hi=MAX_ENVS, strict=True),
    }

    def __post_init__(self) -> None:
        _check_algorithm(self.algorithm)
        object.__setattr__(self, "world", check_world(self.world))
        for name, spec in self.COUNTS.items():
            object.__setattr__(self, name, check_value(name, getattr(self, name), spec))
        for name in ("hyperparams", "policy_kwargs", "env_kwargs"):
            value = getattr(self, name)
            if not isinstance(value, Mapping) or not all(isinstance(k, str) for k in value):
                raise ConfigError(f"{name} = {value!r} must be a mapping of argument names to values", name)
            object.__setattr__(self, name, dict(value))
        if self.env_id is not None and not isinstance(self.env_id, str):
            raise ConfigError(f"env_id = {self.env_id!r} must be a registered environment id (a string)", "env_id")
        _plain("env_kwargs", dict(self.env_kwargs))
        seeds = check_layout_seeds(self.layout_seeds)
        if seeds is not None and not isinstance(seeds, range):
            seeds = tuple(int(s) for s in seeds)
        object.__setattr__(self, "layout_seeds", seeds)

    def check_hyperparams(self) -> None:
        """Unknown SB3 arguments, SB3 arguments out of their ranges (:data:`HYPERPARAM_BOUNDS`)
        and ``policy_kwargs`` the algorithm's policy does not take or cannot build are errors
        naming the argument and what is allowed (imports SB3)."""
        cls = _algorithm_class(self.algorithm)
        allowed = sorted(_constructor_arguments(cls) - {"self", *_RESERVED})
        for key in self.hyperparams:
            if key in _RESERVED:
                raise ConfigError(
                    f"{self.algorithm} setting {key!r} is not a hyperparameter: train_deep sets it itself "
                    "(seed and policy_kwargs are its own arguments; the device is the CPU)",
                    "hyperparams",
                )
            if key not in allowed:
                raise ConfigError(
                    f"unknown {self.algorithm} setting {key!r}{did_you_mean(key, allowed)}: allowed settings are "
                    f"{', '.join(allowed)}",
                    "hyperparams",
                )
        for key, value in self.hyperparams.items():
            spec = HYPERPARAM_BOUNDS.get(key)
            if spec is not None and not callable(value):
                check_value(f"hyperparams.{key}", value, spec, field="hyperparams")
        _check_policy_kwargs(cls, self.policy_kwargs)

    def replace(self, **changes: Any) -> DeepConfig:
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """The configuration as plain data; the world, the copies and the environment only
        when they are not the defaults, so that configurations that use none of them read
        as before."""
        out = {
            "algorithm": self.algorithm,
            "timesteps": self.timesteps,
            "seed": self.seed,
            "hyperparams": dict(self.hyperparams),
            "policy_kwargs": dict(self.policy_kwargs),
            "layout_seeds": _layout_seeds_dict(self.layout_seeds),
        }
        if self.world != GRID:
            out["world"] = self.world
        if self.n_envs != 1:
            out["n_envs"] = self.n_envs
        if self.env_id is not None:
            out["env_id"] = self.env_id
        if self.env_kwargs:
            out["env_kwargs"] = dict(self.env_kwargs)
        return out


def _layout_seeds_dict(seeds: range | tuple[int, ...] | None) -> Any:
    if isinstance(seeds, range):
        return {"start": seeds.start, "stop": seeds.stop, "step": seeds.step}
    return None if seeds is None else list(seeds)


@dataclass(frozen=True, eq=False)
class DeepResult:
    """A trained (or loaded) deep-RL model with what produced it.

    ``model`` is the SB3 model; it is a policy for :func:`swiptopt.evaluate`
    (``model.predict(obs, deterministic=True)``). ``episode_returns`` are the returns of the
    training episodes in order (empty for a loaded model); ``train_seconds`` the wall-clock
    training time (informative only: nothing depends on it).
    """

    model: Any
    config: DeepConfig
    config_hash: str | None
    """:func:`deep_config_hash` of the run; ``None`` when trained on an environment given
    as such (its configuration is not known)."""
    train_seconds: float
    episode_returns: np.ndarray
    loaded: bool = False
    """Whether the model was loaded from a stored file instead of trained."""
    note: str = ""
    """What happened to a stored model that could not be used (it was replaced)."""
    path: Path | None = None
    """The weights file the model was saved to or loaded from (:func:`train_or_load_deep`)."""
    sha256: str | None = None
    """That file's SHA-256."""
    cpu_seconds: float = 0.0
    """CPU time of the training (this process), s; 0 when loaded."""

    def predict(self, obs: Any, deterministic: bool = True) -> Any:
        """The model's ``predict``, so a result is a policy itself."""
        return self.model.predict(obs, deterministic=deterministic)


def pin_torch() -> None:
    """One torch thread (intra- and inter-op), deterministic algorithms and the CPU paths
    of :func:`swiptopt.fpmath.pin_torch_cpu_paths`, for this process.

    Training and acting are then bit-reproducible on the CPU, the same on any x86-64 CPU
    with AVX2 (when no torch computation ran in this process before), and a worker process
    uses one core. torch allows setting the inter-op thread count only before its first
    parallel work; if that has happened, the count is left as it is (it does not change
    results).
    """
    pin_torch_cpu_paths()
    import torch

    torch.set_num_threads(1)
    try:
        torch.set_num_interop_threads(1)
    except RuntimeError:
        pass  # already set, or parallel work already ran in this process
    # torch.use_deterministic_algorithms(True) also configures torch's compiler (unused here),
    # whose import makes a cache folder under the system's temporary directory: set the
    # flag itself, which is all the eager CPU kernels read
    set_deterministic = getattr(torch._C, "_set_deterministic_algorithms", None)
    if set_deterministic is not None:
        set_deterministic(True)
    else:  # pragma: no cover - another torch
        torch.use_deterministic_algorithms(True)


def model_versions() -> dict[str, str]:
    """The versions of the packages that name a trained model (:func:`deep_config_hash`):
    Stable-Baselines3, sb3-contrib (when installed), torch and Gymnasium, as installed."""
    out = {}
    for package in ("stable_baselines3", "sb3_contrib", "torch", "gymnasium"):
        try:
            out[package] = version(package)
        except PackageNotFoundError:  # pragma: no cover - depends on the installation
            out[package] = "absent"
    if out["sb3_contrib"] == "absent":
        del out["sb3_contrib"]
    return out


def _canonical(value: Any) -> Any:
    """A JSON-able form of settings values (classes by qualified name, arrays as lists)."""
    if isinstance(value, type) or callable(value):
        return f"{getattr(value, '__module__', '')}.{getattr(value, '__qualname__', repr(value))}"
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot hash a setting of type {type(value).__name__}: {value!r}")


def _env_id(config: DeepConfig) -> str:
    return config.env_id if config.env_id is not None else ENV_IDS[config.world]


def deep_config_hash(config: DeepConfig, scenario: Scenario) -> str:
    """A hex SHA-256 naming a training run: the configuration (algorithm, timesteps, seed,
    settings, layouts, world, copies, environment), the scenario, the observation, the
    environment's id and version, the versions of Stable-Baselines3 (and sb3-contrib),
    torch and Gymnasium, and torch's CPU-path settings where the user changed them from the
    pinned ones (:func:`swiptopt.fpmath.torch_cpu_path_overrides`). Equal hashes mean the
    same trained model."""
    return _run_hash(config.to_dict(), config, scenario)


def lineage_hash(config: DeepConfig, scenario: Scenario) -> str:
    """A hex SHA-256 naming a training run whatever its length: :func:`deep_config_hash`
    without ``timesteps``. Runs of one lineage pass through the same states where
    :func:`checkpoint_exact` holds, so a state file (:mod:`rl.resume`) is named by it."""
    plain = config.to_dict()
    del plain["timesteps"]
    return _run_hash(plain, config, scenario)


def _run_hash(plain: Mapping[str, Any], config: DeepConfig, scenario: Scenario) -> str:
    payload = {
        "config": plain,
        "scenario": scenario.to_dict(),
        "observation": OBSERVATION,
        "env": _env_id(config),
        "versions": model_versions(),
    }
    overrides = torch_cpu_path_overrides()
    if overrides:  # torch on other CPU paths trains other weights (absent under the pin: names unchanged)
        payload["cpu_paths"] = overrides
    text = json.dumps(payload, sort_keys=True, default=_canonical, allow_nan=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


# ------------------------------------------------------------------ training


#: Seconds between two reports of one training's progress (:func:`reporting_progress`).
PROGRESS_INTERVAL_S = 2.0
#: Who hears of the progress of a training in this context (:func:`reporting_progress`).
_PROGRESS: contextvars.ContextVar[Callable[[int, int, bool], None] | None] = contextvars.ContextVar(
    "swiptopt_training_progress", default=None)


@contextlib.contextmanager
def reporting_progress(report: Callable[[int, int, bool], None] | None) -> Iterator[None]:
    """Within the block, every :func:`train_deep` tells ``report(steps, total, finished)``
    how far it has trained: when it starts, between rollouts at most every
    :data:`PROGRESS_INTERVAL_S` seconds, and when it ends (``finished``). Reporting reads
    the step count and changes nothing in the training (the same model comes out, bit for
    bit; a test compares them). ``None`` reports nothing."""
    token = _PROGRESS.set(report)
    try:
        yield
    finally:
        _PROGRESS.reset(token)


def _callbacks(checkpoints: Mapping[int, Callable[[Any], None]], total: int,
               returns: Sequence[float] = ()) -> tuple[Any, list[Any]]:
    """SB3 callbacks: the one that collects the return of every training episode as it
    ends (after ``returns``, those of the run so far when it resumes), and all of them: it,
    a call of ``checkpoints[n]`` with the model when training has reached n steps (between
    rollouts, where a run of n steps would have stopped), and the reports of
    :func:`reporting_progress` if a report is set."""
    from stable_baselines3.common.callbacks import BaseCallback

    class EpisodeLog(BaseCallback):
        """Collects the return of every training episode as it ends."""

        def __init__(self) -> None:
            super().__init__()
            self.returns: list[float] = [float(r) for r in returns]

        def _on_step(self) -> bool:
            for info, done in zip(self.locals["infos"], self.locals["dones"]):
                if done:
                    ours, monitor = info.get(INFO_KEY), info.get("episode")
                    if ours is not None:
                        self.returns.append(float(ours["return"]))
                    elif monitor is not None:  # another env under SB3's Monitor
                        self.returns.append(float(monitor["r"]))
                    else:
                        self.returns.append(math.nan)
            return True

    class Checkpoints(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.pending = dict(checkpoints)

        def _on_step(self) -> bool:
            return True

        def _on_rollout_start(self) -> None:
            saver = self.pending.pop(self.model.num_timesteps, None)
            if saver is not None:
                saver(self.model)

    log, report = EpisodeLog(), _PROGRESS.get()
    return log, [log, Checkpoints(), *([_progress_callback(report, total)] if report is not None else [])]


def _progress_callback(report: Callable[[int, int, bool], None], total: int) -> Any:
    """The SB3 callback that tells ``report`` how far a training of ``total`` steps has got
    (:func:`reporting_progress`)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Progress(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.last = -math.inf

        def _on_step(self) -> bool:
            return True

        def _on_rollout_start(self) -> None:
            now = time.monotonic()
            if now - self.last >= PROGRESS_INTERVAL_S:
                self.last = now
                report(int(self.model.num_timesteps), total, False)

        def _on_training_end(self) -> None:
            report(int(self.model.num_timesteps), total, True)

    return Progress()


#: Seconds of training between two saves of its state (:func:`train_deep`'s ``state_file``).
STATE_INTERVAL_S = 600.0


def _state_keeper(path: Path, lineage: str, log: Any, prior: Mapping[str, Any], keep_end: bool) -> Any:
    """The SB3 callback that keeps a run's state at ``path`` (:mod:`rl.resume`): it records
    every action sent to the environments and saves the state at the start of a rollout
    once :data:`STATE_INTERVAL_S` seconds have passed since the last save, and (with
    ``keep_end``) when training ends; never over a state further along its lineage.
    ``prior``: what the run had done before it resumed (actions, times)."""
    from stable_baselines3.common.callbacks import BaseCallback

    from rl.resume import save_state

    class StateKeeper(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.actions: list[np.ndarray] = list(prior.get("actions", ()))
            self.last = time.monotonic()
            self.start, self.cpu = time.perf_counter(), time.process_time()

        def _on_step(self) -> bool:
            sent = self.locals.get("clipped_actions")
            self.actions.append(np.array(self.locals["actions"] if sent is None else sent, copy=True))
            return True

        def _on_rollout_start(self) -> None:
            if time.monotonic() - self.last >= STATE_INTERVAL_S:
                self.save()

        def _on_training_end(self) -> None:
            if keep_end:
                self.save()

        def save(self) -> None:
            self.last = time.monotonic()
            steps = int(self.model.num_timesteps)
            kept = _state_steps(path)
            if kept is not None and kept >= steps:
                return
            extra = {"lineage": lineage, "steps": steps,
                     "train_seconds": prior.get("train_seconds", 0.0) + time.perf_counter() - self.start,
                     "cpu_seconds": prior.get("cpu_seconds", 0.0) + time.process_time() - self.cpu}
            save_state(path, self.model, self.actions, extra, {"returns": np.asarray(log.returns, dtype=float)})

    return StateKeeper()


def _resume(model: Any, path: Path, config: DeepConfig, scenario: Scenario) -> dict[str, Any]:
    """Put the state at ``path`` into the fresh ``model`` of ``config`` if the file holds a
    state of its lineage no further along than ``config.timesteps``; what the run had done
    before (``steps``, ``actions``, ``returns``, ``train_seconds``, ``cpu_seconds``), empty
    when there is nothing to resume from. A file of another lineage or one that does not
    restore is a :class:`~swiptopt.ConfigError` naming the file (field ``state_file``)."""
    from rl.resume import FIELD, read_state, restore_state

    if not path.is_file():
        return {}
    header, _ = read_state(path, header_only=True)
    steps = header.get("steps")
    if header.get("lineage") != lineage_hash(config, scenario) or not isinstance(steps, int):
        raise ConfigError(f"{path} holds the state of another training run than this {config.algorithm} run's", FIELD)
    if steps > config.timesteps:
        return {}
    if not checkpoint_exact(config, steps, scenario):
        raise ConfigError(f"{path}: a {config.algorithm} run cannot go on from its state at {steps} steps "
                          "(its training depends on its total, or the count ends no rollout)", FIELD)
    header, arrays = read_state(path)
    restore_state(model, header, arrays, path)
    return {"steps": steps, "actions": list(arrays["actions"]), "returns": arrays.get("extra/returns", ()),
            "train_seconds": float(header.get("train_seconds", 0.0)),
            "cpu_seconds": float(header.get("cpu_seconds", 0.0))}


def resumable(config: DeepConfig, scenario: Scenario | None = None) -> bool:
    """Whether runs of ``config`` can keep their state and go on from it (:mod:`rl.resume`):
    where their state after n steps is the same whatever their total
    (:func:`checkpoint_exact` at a rollout's end)."""
    steps = rollout_steps(config, scenario)
    return checkpoint_exact(config.replace(timesteps=steps), steps, scenario)


def _fleet_shared(n_copies: int, config: DeepConfig, scenario: Scenario) -> Any:
    """The parameter-shared vector env of :data:`FLEET_SHARED_ENV_ID` over ``n_copies``
    copies of the scenario's fleet (on its own layout)."""
    from rl.fleet import make_shared_vec_env

    if config.layout_seeds is not None:
        raise ConfigError(f"{FLEET_SHARED_ENV_ID} trains on the scenario's layout: layout_seeds must be None",
                          "layout_seeds")
    return make_shared_vec_env(n_copies, scenario, **config.env_kwargs)


def _make_one(config: DeepConfig, scenario: Scenario) -> Any:
    """One copy of the training environment of ``config`` on ``scenario`` (for the fleet's
    shared env, one copy of the fleet: a vector env of its AUVs)."""
    if config.env_id == FLEET_SHARED_ENV_ID:
        return _fleet_shared(1, config, scenario)
    if config.env_id is None:
        return make_env(config.world, scenario, observation=OBSERVATION, layout_seeds=config.layout_seeds)
    import gymnasium as gym

    try:
        return gym.make(config.env_id, scenario=scenario, layout_seeds=config.layout_seeds,
                        disable_env_checker=True, **config.env_kwargs)
    except gym.error.Error as exc:
        raise ConfigError(f"env_id = {config.env_id!r}: {exc}", "env_id") from None


def _vector_env(config: DeepConfig, scenario: Scenario) -> Any:
    """The training environment: with ``n_envs = 1`` one copy (SB3 wraps it in its
    ``Monitor`` and ``DummyVecEnv``); else ``n_envs`` copies as an SB3 ``VecEnv``, the world's
    own env stepped together by :class:`rl.vec_env.Sb3VectorEnv`, any other by
    ``DummyVecEnv`` (the same episodes either way, copy i seeded with seed + i); for
    :data:`FLEET_SHARED_ENV_ID`, the fleet's shared vector env over ``n_envs`` copies."""
    if config.env_id == FLEET_SHARED_ENV_ID:
        return _fleet_shared(config.n_envs, config, scenario)
    if config.n_envs == 1:
        return _make_one(config, scenario)
    if config.env_id is None:
        from rl.vec_env import make_sb3_vec_env

        return make_sb3_vec_env(config.n_envs, config.world, scenario, observation=OBSERVATION,
                                layout_seeds=config.layout_seeds)
    from stable_baselines3.common.vec_env import DummyVecEnv

    return DummyVecEnv([lambda: _make_one(config, scenario) for _ in range(config.n_envs)])


def _training_env(scenario_or_env: Any, config: DeepConfig) -> tuple[Any, Scenario | None]:
    """The environment to train on, and the scenario it was built from (if it was)."""
    if isinstance(scenario_or_env, Scenario):
        return _vector_env(config, scenario_or_env), scenario_or_env
    for name, default in (("layout_seeds", None), ("world", GRID), ("env_id", None), ("n_envs", 1)):
        if getattr(config, name) != default:
            raise ConfigError(
                f"{name} applies when training on a Scenario; an environment given as such is trained as it is",
                name,
            )
    if not hasattr(scenario_or_env, "observation_space") or not hasattr(scenario_or_env, "step"):
        raise ConfigError(
            f"train_deep trains on a Scenario or a Gymnasium environment, got {type(scenario_or_env).__name__}", "env"
        )
    from gymnasium import spaces

    if not isinstance(scenario_or_env.observation_space, spaces.Box):
        raise ConfigError(
            f"{config.algorithm} acts on a vector observation (a Box), got {scenario_or_env.observation_space}: "
            "make the env with observation='vector'",
            "observation",
        )
    return scenario_or_env, None


def _new_model(config: DeepConfig, env: Any, scenario: Scenario | None) -> Any:
    """The untrained SB3 model of ``config`` on ``env``; a one-line error for settings SB3
    refuses or actions it cannot take."""
    cls = _algorithm_class(config.algorithm)
    try:
        return cls("MlpPolicy", env, seed=config.seed, device="cpu", policy_kwargs=dict(config.policy_kwargs) or None,
                   verbose=0, **config.hyperparams)
    except (TypeError, ValueError, AssertionError, RuntimeError, UnboundLocalError) as exc:
        if "action spaces" in str(exc) or "action space" in str(exc).lower() and "support" in str(exc).lower():
            whose = f"the {config.world} world's actions" if scenario is not None else "the environment's actions"
            raise ConfigError(
                f"{config.algorithm} cannot act on {env.action_space} ({whose}): {exc}", "world"
            ) from None
        field_name = _blame(exc)
        raise ConfigError(f"{config.algorithm} rejected its {field_name}: {type(exc).__name__}: {_short(exc)}",
                          field_name) from None


def _short(exc: BaseException, limit: int = 300) -> str:
    """An exception's message on one line, at most ``limit`` characters."""
    text = " ".join(str(exc).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _silence(model: Any) -> None:
    """Give the model a logger that writes nothing: SB3's default one makes a directory under
    the system's temporary folder for every training run, and nothing is written outside
    the directories the user named."""
    from stable_baselines3.common.logger import Logger

    model.set_logger(Logger(folder=None, output_formats=[]))


def rollout_steps(config: DeepConfig, scenario: Scenario | None = None) -> int:
    """Environment steps between two points where training can stop: an on-policy
    algorithm's rollout (``n_envs * n_steps``), one step of every copy otherwise. On the
    fleet's shared env (:data:`FLEET_SHARED_ENV_ID`) every AUV of every copy steps, so the
    ``scenario`` (its ``n_auvs``) is needed."""
    cls = _algorithm_class(config.algorithm)
    from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

    copies = config.n_envs
    if config.env_id == FLEET_SHARED_ENV_ID:
        if scenario is None:
            raise ConfigError(f"the rollout of {FLEET_SHARED_ENV_ID} depends on the scenario's n_auvs: give the "
                              "scenario", "scenario")
        copies *= int(scenario.n_auvs)
    if issubclass(cls, OnPolicyAlgorithm):
        n_steps = config.hyperparams.get("n_steps", inspect.signature(cls.__init__).parameters["n_steps"].default)
        return copies * int(n_steps)
    return copies


def checkpoint_exact(config: DeepConfig, steps: int, scenario: Scenario | None = None) -> bool:
    """Whether the model a run of ``config`` (on ``scenario``, which the fleet's shared env
    needs: :func:`rollout_steps`) holds after ``steps`` steps is, bit for bit, the model of
    the same run with ``timesteps = steps``: true when ``steps`` ends a rollout and nothing
    in the algorithm depends on the total (PPO, MaskablePPO, SAC and :class:`StepDQN` with
    constant schedules; not SB3's own DQN, whose exploration decays over a share of the
    total)."""
    if steps % rollout_steps(config, scenario) or steps > config.timesteps:
        return False
    cls = _algorithm_class(config.algorithm)
    from stable_baselines3 import DQN

    if issubclass(cls, DQN) and cls is not _algorithm_class("dqn"):
        return False  # SB3's own DQN: its exploration decays over a share of the total
    return not any(callable(v) for v in config.hyperparams.values())


def train_deep(
    algorithm: str,
    scenario_or_env: Scenario | Any,
    timesteps: int,
    seed: int = 0,
    *,
    hyperparams: Mapping[str, Any] | None = None,
    policy_kwargs: Mapping[str, Any] | None = None,
    layout_seeds: Sequence[int] | None = None,
    world: str = GRID,
    n_envs: int = 1,
    env_id: str | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    checkpoints: Mapping[int, Callable[[Any], None]] | None = None,
    state_file: str | Path | None = None,
    keep_state: bool = True,
) -> DeepResult:
    """Train ``algorithm`` (:data:`DEEP_ALGORITHMS`) for ``timesteps`` environment steps.

    On a :class:`~swiptopt.Scenario`: ``n_envs`` copies of the environment of ``world``
    (:func:`swiptopt.worlds.make_env`, the vector observation) or of the registered
    ``env_id``, on the scenario's layout or, with ``layout_seeds``, on one of those drawn per
    episode (a policy for many layouts). DQN needs the grid's discrete actions and SAC the
    continuous world's box; the other pairings are refused in one line. On a Gymnasium
    environment: that environment as it is (any with a Box observation). ``hyperparams`` are
    SB3 constructor arguments, ``policy_kwargs`` SB3's. ``checkpoints`` maps step counts to
    functions called with the model when training reaches them (between rollouts). Inside
    :func:`reporting_progress` it reports how far it has trained. The same arguments give
    the same model, bit for bit (see the module docstring).

    ``state_file`` (training on a Scenario, where :func:`resumable`): the run keeps its
    state there (:mod:`rl.resume`; every :data:`STATE_INTERVAL_S` seconds, and at its end
    with ``keep_state``), and if the file holds a state of the same run, or of a run of the
    same lineage (:func:`lineage_hash`) at most ``timesteps`` long, training goes on from
    it: the model is the uninterrupted run's, bit for bit, and its ``episode_returns`` and
    times cover the whole run. A file that holds another run's state, or one that does not
    restore, is a :class:`~swiptopt.ConfigError` (field ``state_file``); nothing is trained.
    """
    config = DeepConfig(algorithm, timesteps, seed, hyperparams or {}, policy_kwargs or {}, layout_seeds, world,
                        n_envs, env_id, env_kwargs or {})
    config.check_hyperparams()
    pin_torch()
    env, scenario = _training_env(scenario_or_env, config)
    if state_file is not None and (scenario is None or not resumable(config, scenario)):
        how = "on an environment given as such" if scenario is None else "with these settings"
        raise ConfigError(f"state_file: a {config.algorithm} run {how} cannot go on from a saved state (it needs a "
                          "Scenario, and training that does not depend on its total)", "state_file")
    model = _new_model(config, env, scenario)
    _silence(model)
    prior = {} if state_file is None else _resume(model, Path(state_file), config, scenario)
    log, callbacks = _callbacks(checkpoints or {}, config.timesteps, prior.get("returns", ()))
    if state_file is not None:
        callbacks.append(_state_keeper(Path(state_file), lineage_hash(config, scenario), log, prior, keep_state))
    start, cpu = time.perf_counter(), time.process_time()
    try:
        model.learn(total_timesteps=config.timesteps - prior.get("steps", 0), callback=callbacks, progress_bar=False,
                    reset_num_timesteps=not prior)
    except (ValueError, RuntimeError, UnboundLocalError) as exc:  # settings SB3 accepted but cannot train with
        raise ConfigError(f"{config.algorithm} failed to train with its settings: {type(exc).__name__}: {_short(exc)}",
                          "hyperparams") from None
    return DeepResult(
        model=model,
        config=config,
        config_hash=None if scenario is None else deep_config_hash(config, scenario),
        train_seconds=prior.get("train_seconds", 0.0) + time.perf_counter() - start,
        episode_returns=np.asarray(log.returns, dtype=float),
        cpu_seconds=prior.get("cpu_seconds", 0.0) + time.process_time() - cpu,
    )


# ------------------------------------------------------------------ weights files


def file_sha256(path: str | Path) -> str:
    """The hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _atomic_write(path: Path, write: Callable[[Any], None]) -> None:
    """Write ``path`` through a temporary file beside it, renamed into place: ``path`` is
    either absent, as before, or whole."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def save_weights(model: Any, path: str | Path, header: Mapping[str, Any]) -> str:
    """Save the network weights of an SB3 model (its policy's ``state_dict``) at ``path`` as
    a ``.npz`` of float arrays with a JSON ``header`` (plain data), atomically; returns the
    file's SHA-256. Nothing in the file is code: :func:`load_weights` reads it with
    ``allow_pickle=False``."""
    arrays = {f"param/{name}": tensor.detach().cpu().numpy() for name, tensor in model.policy.state_dict().items()}
    text = json.dumps({"format": WEIGHTS_FORMAT, **header}, sort_keys=True, allow_nan=False)
    arrays["header"] = np.frombuffer(text.encode("utf-8"), dtype=np.uint8)
    path = Path(path)
    _atomic_write(path, lambda handle: np.savez(handle, **arrays))
    return file_sha256(path)


def read_weights(path: str | Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The header and the arrays of a weights file; a :class:`~swiptopt.ConfigError` naming
    the file for anything else (it is never unpickled)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except (OSError, ValueError, EOFError, KeyError) as exc:  # zip and npy format errors
        raise ConfigError(f"{path} is not a swiptopt weights file: {type(exc).__name__}: {exc}", "path") from None
    except Exception as exc:  # zipfile.BadZipFile and the like
        raise ConfigError(f"{path} is not a swiptopt weights file: {type(exc).__name__}: {exc}", "path") from None
    raw = arrays.pop("header", None)
    try:
        header = json.loads(bytes(np.asarray(raw, dtype=np.uint8)).decode("utf-8")) if raw is not None else None
    except (ValueError, UnicodeDecodeError, TypeError):
        header = None
    if not isinstance(header, dict) or header.get("format") != WEIGHTS_FORMAT:
        raise ConfigError(f"{path} is not a swiptopt weights file (no {WEIGHTS_FORMAT} header)", "path")
    params = {}
    for name, value in arrays.items():
        if not name.startswith("param/") or value.dtype.kind not in "fiub":
            raise ConfigError(f"{path}: unexpected entry {name!r} ({value.dtype}) in a weights file", "path")
        params[name[len("param/"):]] = value
    return header, params


def load_weights(path: str | Path, config: DeepConfig, scenario: Scenario, *, config_hash: str | None = None) -> Any:
    """The SB3 model of ``config`` with the weights of the file at ``path``.

    The model is built afresh from the configuration (on one copy of its environment) and
    its policy given the file's arrays: a file whose header names another configuration
    (``config_hash``), or whose arrays do not fit the network, is a
    :class:`~swiptopt.ConfigError` naming the file.
    """
    import torch

    header, params = read_weights(path)
    if config_hash is not None and header.get("config_hash") != config_hash:
        raise ConfigError(f"{path} holds a model trained for another configuration than {config_hash[:12]}", "path")
    pin_torch()
    env = _make_one(config, scenario)
    with warnings.catch_warnings():
        # on one copy, a rollout smaller than the batch SB3 warns of: it is never collected here
        warnings.filterwarnings("ignore", message="You have specified a mini-batch size", category=UserWarning)
        model = _new_model(config, env, scenario)
    try:
        model.policy.load_state_dict({name: torch.from_numpy(np.array(value)) for name, value in params.items()},
                                     strict=True)
    except (RuntimeError, ValueError, TypeError) as exc:
        raise ConfigError(f"{path}: its weights do not fit the {config.algorithm} network: {exc}".splitlines()[0],
                          "path") from None
    model.policy.set_training_mode(False)
    return model


# ------------------------------------------------------------------ SB3 zips (user files)


def save_deep(result: DeepResult | Any, path: str | Path) -> Path:
    """Save a model (or a :class:`DeepResult`'s) in SB3's ``.zip`` format at ``path``, atomically.

    A result's configuration hash travels in the file (:data:`HASH_ATTRIBUTE`). SB3's zips
    hold pickles: :func:`load_deep` runs what a zip holds, so share weights files
    (:func:`save_weights`) rather than zips.
    """
    model = result.model if isinstance(result, DeepResult) else result
    if isinstance(result, DeepResult) and result.config_hash is not None:
        setattr(model, HASH_ATTRIBUTE, result.config_hash)
    path = Path(path)
    _atomic_write(path, model.save)
    return path


def load_deep(path: str | Path, algorithm: str, *, config_hash: str | None = None, sha256: str | None = None) -> Any:
    """Load an SB3 model of ``algorithm`` saved in SB3's ``.zip`` format (on the CPU).

    **A zip is code**: SB3's ``load`` unpickles its entries, so loading a zip from elsewhere
    runs whatever it holds. Give ``sha256`` (the digest you recorded when you saved it) and
    a file with other bytes is refused before anything in it is read. A missing file, one
    that is not a saved ``algorithm`` model, or (with ``config_hash``) one saved for another
    configuration is a :class:`~swiptopt.ConfigError` naming the path.
    """
    _check_algorithm(algorithm)
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"no saved model at {path}", "path")
    if sha256 is not None and file_sha256(path) != sha256:
        raise ConfigError(f"{path} is not the file recorded: its SHA-256 differs from {sha256[:12]}", "sha256")
    cls = _algorithm_class(algorithm)
    pin_torch()
    try:
        model = cls.load(path, device="cpu")
    except Exception as exc:  # SB3 raises many types for a corrupt or foreign file
        raise ConfigError(f"{path} is not a saved {algorithm} model: {type(exc).__name__}: {exc}", "path") from None
    if config_hash is not None and getattr(model, HASH_ATTRIBUTE, None) != config_hash:
        raise ConfigError(f"{path} holds a model trained for another configuration than {config_hash[:12]}", "path")
    return model


# ------------------------------------------------------------------ model directories


@contextlib.contextmanager
def _exclusive(path: Path) -> Any:
    """Hold an exclusive lock on ``path`` (created if needed) while the block runs.
    Where ``fcntl`` is missing (Windows) there is no lock: the atomic writes still leave
    whole files, and a model may be trained twice, identically."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    with open(path, "a+b") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)  # released when the file closes or the process dies
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def read_manifest(directory: str | Path) -> dict[str, dict[str, Any]]:
    """File name -> record (``sha256``, ``config_hash``, ...) of a model directory's
    manifest; empty when there is none or it cannot be read (nothing is then trusted)."""
    try:
        data = json.loads((Path(directory) / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return {}
    models = data.get("models") if isinstance(data, dict) else None
    if not isinstance(models, dict):
        return {}
    return {name: rec for name, rec in models.items() if isinstance(rec, dict) and isinstance(rec.get("sha256"), str)}


def record_in_manifest(directory: str | Path, name: str, record: Mapping[str, Any]) -> None:
    """Add ``name``'s record to the directory's manifest (read, update and replace it
    atomically under the directory's manifest lock)."""
    directory = Path(directory)
    with _exclusive(directory / (MANIFEST + ".lock")):
        models = read_manifest(directory)
        models[name] = dict(record)
        text = json.dumps({"format": 1, "models": models}, indent=1, sort_keys=True)
        _atomic_write(directory / MANIFEST, lambda handle: handle.write(text.encode("utf-8")))


def model_path(directory: str | Path, config: DeepConfig, scenario: Scenario) -> Path:
    """Where :func:`train_or_load_deep` keeps the model of ``config`` on ``scenario``:
    ``directory/<algorithm>-<deep_config_hash>.npz``."""
    return Path(directory) / f"{_file_stem(config.algorithm)}-{deep_config_hash(config, scenario)}{WEIGHTS_SUFFIX}"


def _trusted(directory: Path, name: str) -> tuple[Path | None, str]:
    """The file ``name`` of ``directory`` if its bytes are the ones its manifest records,
    else None and why not ("" when there is no such file)."""
    path = directory / name
    if not path.is_file():
        return None, ""
    record = read_manifest(directory).get(name)
    if record is None:
        return None, f"{path} is not recorded in {directory / MANIFEST}"
    if file_sha256(path) != record["sha256"]:
        return None, f"{path} differs from the file recorded in {directory / MANIFEST} (SHA-256)"
    return path, ""


def find_model(directories: Iterable[str | Path], config: DeepConfig, scenario: Scenario) -> tuple[Path | None, str]:
    """The first trusted weights file of ``config`` in ``directories`` (each vouched for by
    its own manifest), and what was wrong with the untrusted ones seen before it."""
    name = model_path(".", config, scenario).name
    notes = []
    for directory in directories:
        path, why = _trusted(Path(directory), name)
        if path is not None:
            return path, "; ".join(notes)
        if why:
            notes.append(why)
    return None, "; ".join(notes)


def train_or_load_deep(
    directory: str | Path,
    algorithm: str,
    scenario: Scenario,
    timesteps: int,
    seed: int = 0,
    *,
    hyperparams: Mapping[str, Any] | None = None,
    policy_kwargs: Mapping[str, Any] | None = None,
    layout_seeds: Sequence[int] | None = None,
    world: str = GRID,
    n_envs: int = 1,
    env_id: str | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    checkpoints: Sequence[int] = (),
    pretrained: Sequence[str | Path] = (),
    keep_state: bool = False,
) -> DeepResult:
    """:func:`train_deep`, reusing a stored model of the same configuration when there is one.

    A model is looked for under its hashed name (:func:`model_path`) in ``directory``, then
    in the ``pretrained`` directories, and loaded only when the directory's manifest
    records that file's SHA-256; otherwise it is trained and saved in ``directory`` with its
    digest recorded, and the result's ``note`` says why a file found was not used. Processes
    asking for the same model at once train it once (a lock file beside it). ``checkpoints``:
    smaller step counts at which the run also saves its model, each under the name of the
    run of that many steps (only counts where that model is the same, bit for bit:
    :func:`checkpoint_exact`; others are refused).

    A run that can go on from a saved state (:func:`resumable`) keeps its state in
    ``directory`` while it trains (:func:`state_path`, every :data:`STATE_INTERVAL_S`
    seconds), so that a run cut short (a crash, the end of a session) goes on from its last
    state when asked again, to the same model; a state of a shorter run of the same lineage
    (kept with ``keep_state``, which keeps the run's state at its end) is gone on from too,
    when every checkpoint it passed is in ``directory``. A state that cannot be used is
    deleted and the run trains from the start, the result's ``note`` saying why.

    A ``directory`` this process cannot write is only read, without a lock: a model missing
    from it and from ``pretrained`` is a :class:`ConfigError` (``models``), not trained.
    """
    if not isinstance(scenario, Scenario):
        raise ConfigError("train_or_load_deep needs a Scenario (its configuration names the model)", "scenario")
    config = DeepConfig(algorithm, timesteps, seed, hyperparams or {}, policy_kwargs or {}, layout_seeds, world,
                        n_envs, env_id, env_kwargs or {})
    key = deep_config_hash(config, scenario)
    directory = Path(directory)
    path = model_path(directory, config, scenario)
    if not can_make_files_in(directory):  # no lock can be made here and no model trained: only read
        found, note = find_model([directory, *pretrained], config, scenario)
        if found is None:
            raise ConfigError(f"the models directory {str(directory)!r} is not writable and holds no trusted "
                              f"{path.name}: make it writable to train it", "models")
        return _loaded(found, note, config, scenario, key)
    directory.mkdir(parents=True, exist_ok=True)
    kwargs = dict(hyperparams=hyperparams, policy_kwargs=policy_kwargs, layout_seeds=layout_seeds, world=world,
                  n_envs=n_envs, env_id=env_id, env_kwargs=env_kwargs)
    savers = {}
    for steps in sorted(set(int(s) for s in checkpoints) - {config.timesteps}):
        if not checkpoint_exact(config, steps, scenario):
            raise ConfigError(
                f"checkpoint at {steps} steps: a {algorithm} run stopped there is not the run of {steps} steps "
                f"(it must end a rollout of {rollout_steps(config, scenario)} steps and the algorithm must not "
                "depend on the total)", "checkpoints")
        savers[steps] = _checkpoint_saver(directory, config.replace(timesteps=steps), scenario)
    with _exclusive(path.with_name(path.name + ".lock")):
        found, note = find_model([directory, *pretrained], config, scenario)
        if found is not None:
            try:
                return _loaded(found, note, config, scenario, key)
            except ConfigError as exc:
                note = "; ".join(filter(None, [note, str(exc)]))
        result, trained_note = _train_resuming(directory, config, scenario, savers, keep_state, kwargs)
        note = "; ".join(filter(None, [note, trained_note]))
        digest = _save_recorded(directory, path, result.model, config, key)
    why = f"retrained: {note}" if note else ""
    return dataclasses.replace(result, config_hash=key, note=why, path=path, sha256=digest)


def _loaded(found: Path, note: str, config: DeepConfig, scenario: Scenario, key: str) -> DeepResult:
    """The trusted model file ``found`` of ``config``, loaded (:func:`load_weights`)."""
    model = load_weights(found, config, scenario, config_hash=key)
    return DeepResult(model, config, key, 0.0, np.zeros(0), loaded=True, path=found, sha256=file_sha256(found),
                      note=note)


def _train_resuming(directory: Path, config: DeepConfig, scenario: Scenario, savers: Mapping[int, Any],
                    keep_state: bool, kwargs: Mapping[str, Any]) -> tuple[DeepResult, str]:
    """:func:`train_deep` for :func:`train_or_load_deep`, keeping the run's state in
    ``directory`` where it can (:func:`resumable`) and going on from a state found there;
    a state it cannot use is deleted and the run trains from the start. Returns the result
    and what happened to an unusable state ("" if nothing did)."""
    state = state_path(directory, config, scenario) if resumable(config, scenario) else None
    note = _check_state(state, directory, config, scenario, savers)

    def train() -> DeepResult:
        return train_deep(config.algorithm, scenario, config.timesteps, config.seed, checkpoints=savers,
                          state_file=state, keep_state=keep_state, **kwargs)

    try:
        result = train()
    except ConfigError as exc:
        if exc.field != "state_file" or state is None:
            raise
        state.unlink(missing_ok=True)
        note = "; ".join(filter(None, [note, f"trained from the start: {exc}"]))
        result = train()
    if state is not None and not keep_state:
        _drop_state(state, config.timesteps)
    return result, note


def state_path(directory: str | Path, config: DeepConfig, scenario: Scenario) -> Path:
    """Where :func:`train_or_load_deep` keeps the state of a run of ``config`` while it
    trains (:mod:`rl.resume`): ``directory/<algorithm>-<lineage_hash>.state.npz``, one file
    for every run of its lineage."""
    from rl.resume import STATE_SUFFIX

    return Path(directory) / f"{_file_stem(config.algorithm)}-{lineage_hash(config, scenario)}{STATE_SUFFIX}"


def _state_steps(state: Path) -> int | None:
    """The step count of the state at ``state``; None when there is none or it is unreadable."""
    from rl.resume import read_state

    if not state.is_file():
        return None
    try:
        steps = read_state(state, header_only=True)[0].get("steps")
    except ConfigError:
        return None
    return steps if isinstance(steps, int) else None


def _check_state(state: Path | None, directory: Path, config: DeepConfig, scenario: Scenario,
                 savers: Mapping[int, Any]) -> str:
    """Delete a state file :func:`train_or_load_deep` must not go on from, saying why ("" if
    it may, or there is none): unreadable, or past checkpoints whose models are not in
    ``directory`` (going on would never save them). Also deletes what a process killed while
    it wrote the state left behind (:func:`_atomic_write`'s temporary file, hundreds of MB
    for SAC)."""
    if state is None:
        return ""
    _drop_orphans(state)
    if not state.is_file():
        return ""
    steps = _state_steps(state)
    if steps is None:
        state.unlink(missing_ok=True)
        return f"{state.name} was not a readable training state: trained from the start"
    missing = [n for n in savers
               if n < steps and find_model([directory], config.replace(timesteps=n), scenario)[0] is None]
    if missing and steps <= config.timesteps:
        state.unlink(missing_ok=True)
        return (f"{state.name} is past the checkpoint at {min(missing)} steps, whose model is not in {directory}: "
                "trained from the start")
    return ""


def _drop_orphans(path: Path) -> None:
    """Delete the temporary files of :func:`_atomic_write` for ``path`` whose writer is no
    longer running (killed before it could rename or delete them)."""
    for tmp in path.parent.glob(f".{path.name}.*.tmp"):
        pid = tmp.name[len(path.name) + 2 : -len(".tmp")]
        if not pid.isdigit():
            continue
        try:
            os.kill(int(pid), 0)  # signal 0: is the process there?
        except ProcessLookupError:
            tmp.unlink(missing_ok=True)
        except PermissionError:  # pragma: no cover - another user's process: leave its file
            pass


def _drop_state(state: Path, timesteps: int) -> None:
    """Delete the state a finished run kept, unless it is a longer run's."""
    steps = _state_steps(state)
    if steps is None or steps <= timesteps:
        state.unlink(missing_ok=True)


def _save_recorded(directory: Path, path: Path, model: Any, config: DeepConfig, key: str) -> str:
    """Save ``model``'s weights at ``path`` and record their digest in the manifest."""
    header = {"algorithm": config.algorithm, "config_hash": key, "config": config.to_dict()}
    digest = save_weights(model, path, json.loads(json.dumps(header, default=_canonical)))
    record_in_manifest(directory, path.name, {"sha256": digest, "config_hash": key, "algorithm": config.algorithm,
                                              "timesteps": config.timesteps})
    return digest


def _checkpoint_saver(directory: Path, config: DeepConfig, scenario: Scenario) -> Callable[[Any], None]:
    key = deep_config_hash(config, scenario)
    path = model_path(directory, config, scenario)

    def save(model: Any) -> None:
        _save_recorded(directory, path, model, config, key)

    return save
