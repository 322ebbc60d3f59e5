"""Deep-RL contenders: Stable-Baselines3's PPO, DQN and SAC on the ``vector`` observation.

One entry point trains any of them (:func:`train_deep`), or any other SB3 algorithm named by
its class (``"stable_baselines3:A2C"``), in either world (:mod:`swiptopt.worlds`): the
paper's grid (discrete moves: PPO, DQN) or the continuous world (velocity commands in a
``Box``: PPO, SAC). Models are saved in SB3's own ``.zip`` format, with the
hash of their configuration inside, and loaded back (:func:`load_deep`);
:func:`deep_config_hash` names a training configuration, so that :func:`train_or_load_deep`
(and the benchmark) reuse a stored model whose configuration matches instead of training it
again. Processes that want the same model at once train it once (a lock file beside it).

Reproducible on the CPU: the same configuration gives the same trained model, bit for bit,
on any run. :func:`pin_torch` runs torch on one thread (intra- and inter-op) with
deterministic algorithms, the device is always ``"cpu"``, SB3 seeds its generators from the
configuration's seed, and the environment's generator is seeded from it at the first reset.
SB3's seeding also sets Python's ``random``, NumPy's global generator and torch's global
seed (SB3 draws from them): a side effect of training with SB3, not of this project.

Stable-Baselines3 and torch (the ``deeprl`` extra) load inside the functions that use them:
``import rl`` does not import them.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import inspect
import json
import math
import os
import re
import time
from dataclasses import dataclass, field
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from swiptopt.env import INFO_KEY, check_layout_seeds
from swiptopt.errors import ConfigError, did_you_mean
from swiptopt.scenario import Scenario
from swiptopt.worlds import ENV_IDS, GRID, check_world, make_env

#: The algorithms :func:`train_deep` trains, by name, with their SB3 class. Any other SB3
#: algorithm is named by its class as ``"package.module:Class"`` (``"stable_baselines3:A2C"``).
DEEP_ALGORITHMS = {"dqn": "DQN", "ppo": "PPO", "sac": "SAC"}
#: ``"package.module:Class"``: an algorithm class named by where it lives.
CLASS_PATH = re.compile(r"[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*:[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*")
#: The attribute a saved model carries with the :func:`deep_config_hash` it was trained for
#: (SB3 saves a model's plain attributes in its zip): a file under a hashed name that holds
#: another model is recognised as such.
HASH_ATTRIBUTE = "swiptopt_config_hash"

#: SB3 constructor arguments :func:`train_deep` sets itself (never through ``hyperparams``).
_RESERVED = ("policy", "env", "seed", "device", "policy_kwargs", "verbose", "tensorboard_log", "_init_setup_model")

#: The observation the deep agents act on.
OBSERVATION = "vector"


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
    module_name, _, qualname = (
        ("stable_baselines3", "", DEEP_ALGORITHMS[algorithm]) if algorithm in DEEP_ALGORITHMS
        else _check_algorithm(algorithm).partition(":")
    )
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


def _file_stem(algorithm: str) -> str:
    """A file-name-safe form of an algorithm's name (a class path's class, in lower case)."""
    name = algorithm.rpartition(":")[2].rpartition(".")[2].lower() if ":" in algorithm else algorithm
    return re.sub(r"[^A-Za-z0-9_-]+", "_", name)


def _check_int(name: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ConfigError(f"{name} = {value!r} must be an integer >= {low}", name)
    return int(value)


@dataclass(frozen=True)
class DeepConfig:
    """One deep-RL training run, validated at construction."""

    algorithm: str
    """``"ppo"`` or ``"dqn"`` (:data:`DEEP_ALGORITHMS`), or an SB3 algorithm class as
    ``"package.module:Class"``."""
    timesteps: int
    """Environment steps of training."""
    seed: int = 0
    """Seeds SB3 (network initialisation, sampling, exploration) and the environment."""
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

    def __post_init__(self) -> None:
        _check_algorithm(self.algorithm)
        object.__setattr__(self, "world", check_world(self.world))
        object.__setattr__(self, "timesteps", _check_int("timesteps", self.timesteps, 1))
        object.__setattr__(self, "seed", _check_int("seed", self.seed, 0))
        for name in ("hyperparams", "policy_kwargs"):
            value = getattr(self, name)
            if not isinstance(value, Mapping) or not all(isinstance(k, str) for k in value):
                raise ConfigError(f"{name} = {value!r} must be a mapping of argument names to values", name)
            object.__setattr__(self, name, dict(value))
        seeds = check_layout_seeds(self.layout_seeds)
        if seeds is not None and not isinstance(seeds, range):
            seeds = tuple(int(s) for s in seeds)
        object.__setattr__(self, "layout_seeds", seeds)

    def check_hyperparams(self) -> None:
        """Unknown SB3 arguments are errors naming the allowed ones (imports SB3)."""
        cls = _algorithm_class(self.algorithm)
        allowed = sorted(set(inspect.signature(cls.__init__).parameters) - {"self", *_RESERVED})
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

    def to_dict(self) -> dict[str, Any]:
        """The configuration as plain data; the world only when it is not the grid, so the
        grid's configurations (and the hashes of models stored before there were worlds)
        read as before."""
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
    from swiptopt.fpmath import pin_torch_cpu_paths

    pin_torch_cpu_paths()
    import torch

    torch.set_num_threads(1)
    try:
        torch.set_num_interop_threads(1)
    except RuntimeError:
        pass  # already set, or parallel work already ran in this process
    torch.use_deterministic_algorithms(True)


def _versions() -> dict[str, str]:
    out = {}
    for package in ("stable_baselines3", "torch", "gymnasium"):
        try:
            out[package] = version(package)
        except PackageNotFoundError:  # pragma: no cover - depends on the installation
            out[package] = "absent"
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


def deep_config_hash(config: DeepConfig, scenario: Scenario) -> str:
    """A hex SHA-256 naming a training run: the configuration (algorithm, timesteps, seed,
    settings, layouts, world), the scenario, the observation, the environment's id and
    version (the world's), and the versions of Stable-Baselines3, torch and Gymnasium. Equal
    hashes mean the same trained model; a grid model and a continuous one never share one."""
    payload = {
        "config": config.to_dict(),
        "scenario": scenario.to_dict(),
        "observation": OBSERVATION,
        "env": ENV_IDS[config.world],
        "versions": _versions(),
    }
    text = json.dumps(payload, sort_keys=True, default=_canonical, allow_nan=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _episode_log_callback() -> Any:
    from stable_baselines3.common.callbacks import BaseCallback

    class EpisodeLog(BaseCallback):
        """Collects the return of every training episode as it ends."""

        def __init__(self) -> None:
            super().__init__()
            self.returns: list[float] = []

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

    return EpisodeLog()


def _training_env(scenario_or_env: Any, config: DeepConfig) -> tuple[Any, Scenario | None]:
    """The environment to train on, and the scenario it was built from (if it was)."""
    if isinstance(scenario_or_env, Scenario):
        env = make_env(config.world, scenario_or_env, observation=OBSERVATION, layout_seeds=config.layout_seeds)
        return env, scenario_or_env
    if config.layout_seeds is not None:
        raise ConfigError(
            "layout_seeds apply when training on a Scenario; an environment given as such keeps its own layouts",
            "layout_seeds",
        )
    if config.world != GRID:
        raise ConfigError(
            f"world = {config.world!r} applies when training on a Scenario; an environment given as such is its "
            "own world",
            "world",
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
) -> DeepResult:
    """Train ``algorithm`` (``"ppo"``, ``"dqn"``, ``"sac"``) for ``timesteps`` environment steps.

    On a :class:`~swiptopt.Scenario`: the environment of ``world`` (:func:`swiptopt.worlds.make_env`:
    the grid's :class:`~swiptopt.env.AuvSwiptEnv` with the vector observation, or the
    continuous world's env), on the scenario's layout or, with ``layout_seeds``, on one of
    those drawn per episode (a policy for many layouts). DQN needs the grid's discrete
    actions and SAC the continuous world's box; the other pairings are refused in one line.
    On a Gymnasium environment: that environment as it is (any with a Box observation; the
    benchmarks train on CartPole this way). ``hyperparams`` are SB3 constructor arguments,
    ``policy_kwargs`` SB3's. The same arguments give the same model, bit for bit (see the
    module docstring).
    """
    config = DeepConfig(algorithm, timesteps, seed, hyperparams or {}, policy_kwargs or {}, layout_seeds, world)
    config.check_hyperparams()
    env, scenario = _training_env(scenario_or_env, config)
    pin_torch()
    cls = _algorithm_class(config.algorithm)
    try:
        model = cls(
            "MlpPolicy",
            env,
            seed=config.seed,
            device="cpu",
            policy_kwargs=dict(config.policy_kwargs) or None,
            verbose=0,
            **config.hyperparams,
        )
    except (TypeError, ValueError, AssertionError) as exc:
        if "action spaces" in str(exc):  # SB3's check of the algorithm against the env's actions
            whose = f"the {config.world} world's actions" if scenario is not None else "the environment's actions"
            raise ConfigError(f"{config.algorithm} cannot act on {env.action_space} ({whose}): {exc}", "world") from None
        raise ConfigError(f"{config.algorithm} rejected its settings: {exc}", "hyperparams") from None
    log = _episode_log_callback()
    start = time.perf_counter()
    model.learn(total_timesteps=config.timesteps, callback=log, progress_bar=False)
    seconds = time.perf_counter() - start
    return DeepResult(
        model=model,
        config=config,
        config_hash=None if scenario is None else deep_config_hash(config, scenario),
        train_seconds=seconds,
        episode_returns=np.asarray(log.returns, dtype=float),
    )


def save_deep(result: DeepResult | Any, path: str | Path) -> Path:
    """Save a model (or a :class:`DeepResult`'s) in SB3's ``.zip`` format at ``path``.

    Written to a temporary file beside it and renamed, so ``path`` is either absent or whole
    (two processes saving the same model leave one whole file). A result's configuration
    hash travels in the file (:data:`HASH_ATTRIBUTE`), so :func:`load_deep` can check it.
    """
    model = result.model if isinstance(result, DeepResult) else result
    if isinstance(result, DeepResult) and result.config_hash is not None:
        setattr(model, HASH_ATTRIBUTE, result.config_hash)
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as f:
            model.save(f)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def load_deep(path: str | Path, algorithm: str, *, config_hash: str | None = None) -> Any:
    """Load an SB3 model of ``algorithm`` saved by :func:`save_deep` (on the CPU).

    A missing file, one that is not a saved ``algorithm`` model, or (with ``config_hash``)
    one saved for another configuration is a :class:`~swiptopt.ConfigError` naming the path.
    """
    _check_algorithm(algorithm)
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"no saved model at {path}", "path")
    cls = _algorithm_class(algorithm)
    pin_torch()
    try:
        model = cls.load(path, device="cpu")
    except Exception as exc:  # SB3 raises many types for a corrupt or foreign file
        raise ConfigError(f"{path} is not a saved {algorithm} model: {type(exc).__name__}: {exc}", "path") from None
    if config_hash is not None and getattr(model, HASH_ATTRIBUTE, None) != config_hash:
        raise ConfigError(f"{path} holds a model trained for another configuration than {config_hash[:12]}", "path")
    return model


@contextlib.contextmanager
def _exclusive(path: Path) -> Any:
    """Hold an exclusive lock on ``path`` (created if needed) while the block runs, so
    processes that want the same model train it once: the others wait, then load it.
    Where ``fcntl`` is missing (Windows) there is no lock: the atomic save still leaves one
    whole file, and a model may be trained twice, identically."""
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


def model_path(directory: str | Path, config: DeepConfig, scenario: Scenario) -> Path:
    """Where :func:`train_or_load_deep` keeps the model of ``config`` on ``scenario``:
    ``directory/<algorithm>-<deep_config_hash>.zip``."""
    return Path(directory) / f"{_file_stem(config.algorithm)}-{deep_config_hash(config, scenario)}.zip"


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
) -> DeepResult:
    """:func:`train_deep`, reusing ``directory/<algorithm>-<hash>.zip`` when it exists.

    The file is named by :func:`deep_config_hash`, so a stored model is reused only for the
    very configuration (and library versions) it was trained with; a new one is saved there.
    Processes asking for the same model at once train it once (a lock file beside it): the
    first trains and saves, the others wait and load. A file there that cannot be loaded,
    or holds a model of another configuration, is replaced by a fresh training (the result's
    ``note`` says so): the hash names the configuration, so the new model is the right one.
    """
    if not isinstance(scenario, Scenario):
        raise ConfigError("train_or_load_deep needs a Scenario (its configuration names the model)", "scenario")
    config = DeepConfig(algorithm, timesteps, seed, hyperparams or {}, policy_kwargs or {}, layout_seeds, world)
    key = deep_config_hash(config, scenario)
    path = model_path(directory, config, scenario)
    path.parent.mkdir(parents=True, exist_ok=True)
    note = ""
    with _exclusive(path.with_name(path.name + ".lock")):
        if path.is_file():
            try:
                model = load_deep(path, algorithm, config_hash=key)
            except ConfigError as exc:
                note = f"retrained: the stored model could not be used ({exc})"
            else:
                return DeepResult(model, config, key, 0.0, np.zeros(0), loaded=True)
        result = train_deep(
            algorithm,
            scenario,
            timesteps,
            seed,
            hyperparams=hyperparams,
            policy_kwargs=policy_kwargs,
            layout_seeds=layout_seeds,
            world=world,
        )
        save_deep(result, path)
    return dataclasses.replace(result, config_hash=key, note=note)
