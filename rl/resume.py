"""Exact resume of a Stable-Baselines3 training run, from a state file that is data.

A run of many hours (SAC in the harbour: about two CPU-hours per 4,194,304 steps) must
survive the end of a session or a crash without changing its result. A weights file
(:func:`rl.deep.save_weights`) is not enough to go on from: SB3's next steps also read the
optimisers' moments, an off-policy algorithm's replay buffer, the global random generators
SB3 draws from (torch's, NumPy's legacy one, Python's), the counters its schedules read and
the environments' state in the middle of their episodes.

:func:`save_state` writes all of it as a ``.npz`` of arrays with a JSON header, atomically,
and :func:`restore_state` puts it back into a model built afresh from the same
configuration, so that training on from there gives the model of the uninterrupted run,
bit for bit (a test holds it to that). The environments are not serialised: the file keeps
every action the run sent to them, and :func:`restore_state` replays those from the seeded
reset (the compiled worlds replay millions of steps in seconds), then checks that the
replayed observation is, to the bit, the one the run had; a state that does not replay is
refused. Nothing in a state file is code: it is read with ``allow_pickle=False`` and every
value is an array or plain JSON.

The states are taken where a run may stop (the start of a rollout: what
:func:`rl.deep.checkpoint_exact` calls the end of the previous one), and only for runs whose
state there does not depend on their total (:func:`rl.deep.checkpoint_exact`), so that the
state of a run of 4,194,304 steps at 2,097,152 is also the state of a run of 8,388,608 at
that count: a curve extended by one more doubling goes on from where the last one ended.
"""

from __future__ import annotations

import json
import random
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from swiptopt.errors import ConfigError

#: The format named in a state file's header.
STATE_FORMAT = "swiptopt-training-state-1"
#: The suffix of state files (beside the weights files of a model directory).
STATE_SUFFIX = ".state.npz"
#: The field that errors about a state file name (``train_deep``'s argument).
FIELD = "state_file"
#: The model's counters that SB3's training reads (those the algorithm has).
_COUNTERS = ("num_timesteps", "_episode_num", "_n_updates", "_n_calls", "exploration_rate",
             "_current_progress_remaining", "_total_timesteps")


# ------------------------------------------------------------------ nested values as arrays + JSON


def _encode(value: Any, arrays: dict[str, np.ndarray], path: str) -> Any:
    """``value`` (tensors, arrays, dicts, lists, tuples and plain scalars, nested) as JSON,
    its tensors and arrays moved into ``arrays`` under keys made from ``path``."""
    import torch

    if isinstance(value, torch.Tensor):
        arrays[path] = value.detach().cpu().numpy().copy()
        return {"tensor": path}
    if isinstance(value, np.ndarray):
        arrays[path] = value.copy()
        return {"array": path}
    if isinstance(value, Mapping):
        return {"dict": [[_encode(k, arrays, f"{path}/k{i}"), _encode(v, arrays, f"{path}/{i}")]
                         for i, (k, v) in enumerate(value.items())]}
    if isinstance(value, (list, tuple)):
        kind = "list" if isinstance(value, list) else "tuple"
        return {kind: [_encode(v, arrays, f"{path}/{i}") for i, v in enumerate(value)]}
    if isinstance(value, np.generic):
        return {"value": value.item()}
    if value is None or isinstance(value, (bool, int, float, str)):
        return {"value": value}
    raise TypeError(f"cannot keep a training state value of type {type(value).__name__} at {path}")


def _decode(node: Any, arrays: Mapping[str, np.ndarray]) -> Any:
    """The value :func:`_encode` turned into ``node``; a ``ValueError`` for anything else."""
    import torch

    if not isinstance(node, dict) or len(node) != 1:
        raise ValueError(f"malformed state entry {node!r:.80}")
    ((kind, body),) = node.items()
    if kind in ("tensor", "array"):
        if not isinstance(body, str) or body not in arrays:
            raise ValueError(f"state entry names a missing array {body!r:.80}")
        array = np.array(arrays[body])
        return torch.from_numpy(array) if kind == "tensor" else array
    if kind == "dict" and isinstance(body, list):
        return {_decode(k, arrays): _decode(v, arrays) for k, v in body}
    if kind in ("list", "tuple") and isinstance(body, list):
        items = [_decode(v, arrays) for v in body]
        return items if kind == "list" else tuple(items)
    if kind == "value" and (body is None or isinstance(body, (bool, int, float, str))):
        return body
    raise ValueError(f"malformed state entry {node!r:.80}")


# ------------------------------------------------------------------ what a model's state is


def _attribute(model: Any, dotted: str) -> Any:
    obj = model
    for part in dotted.split("."):
        obj = getattr(obj, part)
    return obj


def _space_generators(model: Any) -> dict[str, Any]:
    """The bit-generator states of the model's spaces (SB3 samples the action space for
    its random start); ``None`` for a space never seeded."""
    out = {}
    for name in ("action_space", "observation_space"):
        generator = getattr(getattr(model, name, None), "_np_random", None)
        out[name] = None if generator is None else generator.bit_generator.state
    return out


def capture(model: Any, actions: list[np.ndarray], extra: Mapping[str, Any],
            extra_arrays: Mapping[str, np.ndarray] | None = None) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The state of ``model`` between two rollouts as a JSON-able header and arrays:
    ``actions`` are the actions the run has sent to its environments, one array per
    vector step; ``extra`` goes into the header as it is (plain data), ``extra_arrays``
    among the arrays under ``extra/<name>``."""
    import torch

    if isinstance(model._last_obs, dict):
        raise ConfigError("a training state keeps array observations, not dict observations", "observation")
    arrays: dict[str, np.ndarray] = {}
    state_dicts, variables = model._get_torch_save_params()
    torch_state = {name: _encode(_attribute(model, name).state_dict(), arrays, f"sd/{name}") for name in state_dicts}
    torch_vars = {name: _encode(_attribute(model, name), arrays, f"var/{name}") for name in variables}
    counters = {name: _encode(getattr(model, name), arrays, f"n/{name}") for name in _COUNTERS if hasattr(model, name)}
    arrays["last_obs"] = np.array(model._last_obs)
    if model._last_episode_starts is not None:
        arrays["last_episode_starts"] = np.array(model._last_episode_starts)
    buffer = getattr(model, "replay_buffer", None)
    buffer_meta = None
    if buffer is not None:
        for name, value in vars(buffer).items():
            if isinstance(value, np.ndarray):
                arrays[f"buffer/{name}"] = value
        buffer_meta = {"pos": int(buffer.pos), "full": bool(buffer.full)}
    numpy_global = np.random.get_state(legacy=False)
    arrays["rng/torch"] = torch.get_rng_state().numpy().copy()
    arrays["rng/numpy_key"] = np.asarray(numpy_global["state"]["key"])
    arrays["actions"] = (np.stack(actions) if actions else np.zeros((0, model.n_envs)))
    for name, value in (extra_arrays or {}).items():
        arrays[f"extra/{name}"] = np.asarray(value)
    header = {
        "format": STATE_FORMAT,
        "algorithm_class": f"{type(model).__module__}:{type(model).__qualname__}",
        "torch": torch_state,
        "variables": torch_vars,
        "counters": counters,
        "buffer": buffer_meta,
        "rng": {
            "numpy": {k: v for k, v in numpy_global.items() if k != "state"} | {"pos": numpy_global["state"]["pos"]},
            "python": list(_python_state()),
            "spaces": _space_generators(model),
        },
        **extra,
    }
    return header, arrays


def _python_state() -> tuple[Any, ...]:
    version, internal, gauss = random.getstate()
    return version, list(internal), gauss


def save_state(path: str | Path, model: Any, actions: list[np.ndarray], extra: Mapping[str, Any],
               extra_arrays: Mapping[str, np.ndarray] | None = None) -> None:
    """Write the state of ``model`` (:func:`capture`) at ``path``, atomically: the file is
    either the previous state or this one, whole."""
    from rl.deep import _atomic_write

    header, arrays = capture(model, actions, extra, extra_arrays)
    text = json.dumps(header, sort_keys=True, allow_nan=False)
    arrays["header"] = np.frombuffer(text.encode("utf-8"), dtype=np.uint8)
    _atomic_write(Path(path), lambda handle: np.savez(handle, **arrays))


def read_state(path: str | Path, header_only: bool = False) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The header and arrays of a state file (with ``header_only``, no arrays: the rest of
    the file is not read); a :class:`~swiptopt.ConfigError` naming the file for anything
    else (it is never unpickled)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            names = ["header"] if header_only else data.files
            arrays = {name: data[name] for name in names}
        raw = arrays.pop("header")
        header = json.loads(bytes(np.asarray(raw, dtype=np.uint8)).decode("utf-8"))
    except Exception as exc:  # zip, npy, JSON and UTF-8 errors alike: the file is not a state
        raise ConfigError(f"{path} is not a swiptopt training state: {type(exc).__name__}: {exc}", FIELD) from None
    if not isinstance(header, dict) or header.get("format") != STATE_FORMAT:
        raise ConfigError(f"{path} is not a swiptopt training state (no {STATE_FORMAT} header)", FIELD)
    if any(value.dtype.kind not in "fiub" for value in arrays.values()):
        raise ConfigError(f"{path}: a training state holds numeric arrays only", FIELD)
    return header, arrays


def restore_state(model: Any, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray], path: str | Path) -> None:
    """Put the state read from ``path`` into ``model``, a model built afresh (seeded, never
    trained) from the configuration the state was taken from: weights, optimisers, counters,
    replay buffer and random generators, and the environments by replaying the state's
    actions from their seeded reset. Anything that does not fit (another algorithm, other
    shapes, a replay that does not reach the state's observation to the bit) is a
    :class:`~swiptopt.ConfigError` naming the file; the model is then not to be used."""

    def refuse(why: str) -> ConfigError:
        return ConfigError(f"{path}: cannot resume from this training state: {why}", FIELD)

    cls = f"{type(model).__module__}:{type(model).__qualname__}"
    if header.get("algorithm_class") != cls:
        raise refuse(f"it is a state of {header.get('algorithm_class')}, not of {cls}")
    try:
        _restore_torch(model, header, arrays)
        _restore_buffer(getattr(model, "replay_buffer", None), header["buffer"], arrays)
        actions = arrays["actions"]
        last_obs = _replay(model.env, actions)
        saved_obs = arrays["last_obs"]
        if (last_obs.shape, last_obs.dtype, last_obs.tobytes()) != (saved_obs.shape, saved_obs.dtype,
                                                                    saved_obs.tobytes()):
            raise ValueError(f"replaying its {len(actions)} vector steps does not reach its observation")
        model._last_obs = last_obs
        if "last_episode_starts" in arrays:
            model._last_episode_starts = np.array(arrays["last_episode_starts"])
        for name, node in header["counters"].items():
            if name not in _COUNTERS:
                raise ValueError(f"unknown counter {name!r}")
            setattr(model, name, _decode(node, arrays))
        _restore_generators(model, header["rng"], arrays)
    except (KeyError, ValueError, TypeError, RuntimeError, IndexError) as exc:
        raise refuse(f"{type(exc).__name__}: {exc}") from None


def _restore_torch(model: Any, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> None:
    """The networks, optimisers and loose tensors (SAC's entropy coefficient) of a state."""
    import torch

    state_dicts, variables = model._get_torch_save_params()
    if sorted(header["torch"]) != sorted(state_dicts) or sorted(header["variables"]) != sorted(variables):
        raise ValueError("other networks or optimisers than the model's")
    for name in state_dicts:
        _attribute(model, name).load_state_dict(_decode(header["torch"][name], arrays))
    with torch.no_grad():
        for name in variables:
            _attribute(model, name).copy_(_decode(header["variables"][name], arrays))


def _restore_buffer(buffer: Any, meta: Mapping[str, Any] | None, arrays: Mapping[str, np.ndarray]) -> None:
    """An off-policy algorithm's replay buffer, copied into the one the model made."""
    if (buffer is None) != (meta is None):
        raise ValueError("a replay buffer where the model has none, or none where it has one")
    if buffer is None or meta is None:
        return
    for name, value in vars(buffer).items():
        if isinstance(value, np.ndarray):
            saved = arrays[f"buffer/{name}"]
            if saved.shape != value.shape or saved.dtype != value.dtype:
                raise ValueError(f"replay buffer {name} is {saved.shape} {saved.dtype}, the model's "
                                 f"{value.shape} {value.dtype}")
            value[...] = saved
    buffer.pos, buffer.full = int(meta["pos"]), bool(meta["full"])


def _restore_generators(model: Any, rng: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> None:
    """The generators SB3 draws from: torch's, NumPy's legacy global one, Python's, and
    those of the model's spaces."""
    import torch

    torch.set_rng_state(torch.from_numpy(np.array(arrays["rng/torch"], dtype=np.uint8)))
    numpy_state = dict(rng["numpy"])
    key = np.array(arrays["rng/numpy_key"], dtype=np.uint32)
    numpy_state["state"] = {"key": key, "pos": numpy_state.pop("pos")}
    np.random.set_state(numpy_state)
    version, internal, gauss = rng["python"]
    random.setstate((version, tuple(internal), gauss))
    for name, state in rng["spaces"].items():
        space = getattr(model, name)
        if state is not None:
            space.seed(0)  # makes its generator, whose state is then set
            space._np_random.bit_generator.state = state


def _replay(env: Any, actions: np.ndarray) -> np.ndarray:
    """The observation the SB3 ``VecEnv`` gives after its seeded reset and ``actions``."""
    obs = env.reset()
    for action in actions:
        obs, _, _, _ = env.step(action)
    return np.asarray(obs)
