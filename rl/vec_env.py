"""Stable-Baselines3's ``VecEnv`` over :class:`swiptopt.vector.AuvSwiptVectorEnv`.

:class:`Sb3VectorEnv` lets SB3 train on N copies stepped in one compiled call. It behaves
as SB3's ``DummyVecEnv`` over N single envs made with the same arguments: ``seed(s)``
then ``reset()`` seeds copy i with ``s + i`` (at that reset only), ``set_options`` gives
each copy its reset options, and ``step_wait`` returns the observations, float32 rewards,
the dones and one info dict per copy, with ``TimeLimit.truncated`` and, at an episode's
end, ``terminal_observation`` (the copy resets in the same step, as DummyVecEnv does:
the vector env runs with ``AutoresetMode.SAME_STEP``) and ``episode_metrics``. The same
seeds and actions give the same numbers as DummyVecEnv, and PPO trained on either with the
same seed the same parameters (tests hold it to that).

``get_attr``, ``set_attr``, ``env_method`` and ``env_is_wrapped`` reach the copies'
controllers (``AuvSwiptVectorEnv.envs``), which are not wrapped; what the compiled step
reads lives in the vector env's own rows, so ``set_attr`` changes the controllers, not the
world the copies step in.

Stable-Baselines3 loads when :class:`Sb3VectorEnv` is first used (the class is built then),
never at ``import rl`` or ``import rl.vec_env``.
"""

from __future__ import annotations

import functools
import warnings
from typing import Any

import numpy as np

from swiptopt.errors import ConfigError
from swiptopt.vector import AuvSwiptVectorEnv
from swiptopt.worlds import GRID


def _split_infos(infos: dict[str, Any], n: int) -> list[dict[str, Any]]:
    """Gymnasium's aggregated vector infos (key -> array over the copies, ``_key`` -> mask)
    back to one dict per copy, values as the single env gives them (Python scalars, an array
    of its own per copy, objects as they are). ``final_obs`` and ``final_info`` are left out."""
    out: list[dict[str, Any]] = [{} for _ in range(n)]
    for key, value in infos.items():
        if key in ("final_obs", "final_info") or (key.startswith("_") and key[1:] in infos):
            continue
        mask = infos[f"_{key}"]
        if isinstance(value, dict):
            values: Any = _split_infos(value, n)
        elif value.dtype == object:
            values = value
        elif value.ndim > 1:
            values = [row.copy() for row in value]
        else:
            values = value.tolist()
        if mask.all():
            for info, v in zip(out, values):
                info[key] = v
        else:
            for i in np.flatnonzero(mask).tolist():
                out[i][key] = values[i]
    return out


def _check_wrappable(venv: Any) -> None:
    """Refuse what :class:`Sb3VectorEnv` cannot wrap: anything but an
    :class:`~swiptopt.vector.AuvSwiptVectorEnv` whose ``autoreset_mode`` is ``SAME_STEP``."""
    from gymnasium.vector import AutoresetMode

    if not isinstance(venv, AuvSwiptVectorEnv):
        raise ConfigError(f"Sb3VectorEnv wraps an AuvSwiptVectorEnv, got {type(venv).__name__}", "venv")
    if venv.autoreset_mode is not AutoresetMode.SAME_STEP:
        raise ConfigError(
            f"Sb3VectorEnv needs autoreset_mode=SAME_STEP (SB3 resets in the step that ends an episode), "
            f"got {venv.autoreset_mode}",
            "autoreset_mode",
        )


def _step_infos(
    infos: dict[str, Any], terminated: np.ndarray, truncated: np.ndarray, reset_infos: list[dict[str, Any]], n: int
) -> tuple[np.ndarray, list[dict[str, Any]]]:
    """SB3's dones and one info dict per copy from a ``SAME_STEP`` vector step's infos, as
    DummyVecEnv gives them: an ended copy's info is its final step's (with
    ``terminal_observation``), and its reset's info goes to ``reset_infos``; ``n`` copies."""
    dones = terminated | truncated
    out = _split_infos(infos, n)  # the step's infos; for ended copies, their reset's
    ended = np.flatnonzero(dones).tolist()
    if ended:
        final = _split_infos(infos["final_info"], n)
        for i in ended:
            reset_infos[i], out[i] = out[i], final[i]
    limited = (truncated & ~terminated).tolist()
    for i in range(n):
        out[i]["TimeLimit.truncated"] = limited[i]
    for i in ended:
        out[i]["terminal_observation"] = infos["final_obs"][i]
    return dones, out


def make_sb3_vec_env(num_envs: int, world: str = GRID, scenario: Any = None, **kwargs: Any) -> Any:
    """An :class:`Sb3VectorEnv` over a new ``AuvSwiptVectorEnv(num_envs, world, scenario,
    autoreset_mode=SAME_STEP, **kwargs)`` (``preset``, ``observation``, ``layout_seeds``,
    ``backend`` and scenario overrides, as the vector env takes them)."""
    from gymnasium.vector import AutoresetMode

    if "autoreset_mode" in kwargs:
        raise ConfigError("autoreset_mode: SB3's vector envs reset in the step that ends an episode (SAME_STEP)",
                          "autoreset_mode")
    venv = AuvSwiptVectorEnv(num_envs, world, scenario, autoreset_mode=AutoresetMode.SAME_STEP, **kwargs)
    return _sb3_vector_env_class()(venv)


@functools.lru_cache(maxsize=1)
def _sb3_vector_env_class() -> type:
    """Build :class:`Sb3VectorEnv` (this imports Stable-Baselines3)."""
    from stable_baselines3.common import env_util
    from stable_baselines3.common.vec_env import VecEnv

    class Sb3VectorEnv(VecEnv):
        """SB3's ``VecEnv`` over an :class:`~swiptopt.vector.AuvSwiptVectorEnv` whose
        ``autoreset_mode`` is ``SAME_STEP`` (:func:`make_sb3_vec_env` makes both); see the
        module docstring."""

        def __init__(self, venv: AuvSwiptVectorEnv):
            _check_wrappable(venv)
            self.venv = venv
            self.envs = venv.envs
            super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
            self._actions: Any = None

        def reset(self) -> np.ndarray:
            options = [o if o else None for o in self._options]
            obs, self.reset_infos = self.venv.reset_copies(list(self._seeds), options)
            self._reset_seeds()  # seeds and options serve one reset
            self._reset_options()
            return obs

        def step_async(self, actions: np.ndarray) -> None:
            self._actions = actions

        def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
            obs, rewards, terminated, truncated, infos = self.venv.step(self._actions)
            dones, out = _step_infos(infos, terminated, truncated, self.reset_infos, self.num_envs)
            return obs, rewards.astype(np.float32), dones, out

        def close(self) -> None:
            self.venv.close()

        def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
            return [self.envs[i].get_wrapper_attr(attr_name) for i in self._get_indices(indices)]

        def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
            for i in self._get_indices(indices):
                setattr(self.envs[i], attr_name, value)

        def env_method(
            self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any
        ) -> list[Any]:
            return [
                self.envs[i].get_wrapper_attr(method_name)(*method_args, **method_kwargs)
                for i in self._get_indices(indices)
            ]

        def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
            return [env_util.is_wrapped(self.envs[i], wrapper_class) for i in self._get_indices(indices)]

        def get_images(self) -> list[None]:
            warnings.warn("the vector env does not render: no images", stacklevel=2)
            return [None] * self.num_envs

    Sb3VectorEnv.__module__ = __name__
    Sb3VectorEnv.__qualname__ = "Sb3VectorEnv"
    return Sb3VectorEnv


def __getattr__(name: str) -> Any:
    if name == "Sb3VectorEnv":
        return _sb3_vector_env_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# Sb3VectorEnv is built on first use (so that Stable-Baselines3 loads only then) and reached
# through the module's __getattr__, which pyflakes cannot see
__all__ = ["Sb3VectorEnv", "make_sb3_vec_env"]  # noqa: F822
