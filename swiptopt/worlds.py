"""The worlds an AUV moves in, by name, and the environment of each.

``"grid"`` is the paper's: unit moves between the cells of a 3D lattice
(:class:`swiptopt.env.AuvSwiptEnv`, discrete actions, a ``tabular`` or ``vector``
observation). ``"continuous"`` is the continuous world on the same physics: a continuous
position, bounded 3D velocity commands, motion stopped by obstacles
(:class:`swiptopt.env_continuous.AuvSwiptContinuousEnv`, a ``Box`` action, the ``vector``
observation only). Trainers and the benchmark build either through :func:`make_env`, so
one name says which.
"""

from __future__ import annotations

from typing import Any

from swiptopt import CONTINUOUS_ENV_ID, ENV_ID
from swiptopt.env import OBSERVATIONS as GRID_OBSERVATIONS
from swiptopt.errors import ConfigError, did_you_mean

GRID = "grid"
CONTINUOUS = "continuous"
#: Every world, the paper's first.
WORLDS = (GRID, CONTINUOUS)
#: The Gymnasium id of each world's environment.
ENV_IDS = {GRID: ENV_ID, CONTINUOUS: CONTINUOUS_ENV_ID}
#: The observations each world's environment offers (its default first).
OBSERVATIONS = {GRID: GRID_OBSERVATIONS, CONTINUOUS: ("vector",)}


def check_world(value: Any, where: str = "world") -> str:
    """``value`` if it names a world; a :class:`ConfigError` naming ``where`` otherwise."""
    if isinstance(value, str) and value in WORLDS:
        return value
    raise ConfigError(
        f"{where} = {value!r} is not a world{did_you_mean(value, WORLDS)}: choose one of "
        f"{', '.join(map(repr, WORLDS))}",
        "world",
    )


def make_env(world: str, scenario: Any, *, observation: str | None = None, **kwargs: Any) -> Any:
    """The environment of ``world`` on ``scenario`` (a :class:`~swiptopt.Scenario`).

    ``observation`` is one of the world's :data:`OBSERVATIONS` (``None``: its default);
    ``kwargs`` go to the environment (``layout_seeds``, ``render_mode``, ``backend``).
    """
    world = check_world(world)
    observation = OBSERVATIONS[world][0] if observation is None else observation
    if observation not in OBSERVATIONS[world]:
        raise ConfigError(
            f"observation = {observation!r} is not offered in the {world} world: choose one of "
            f"{', '.join(map(repr, OBSERVATIONS[world]))}",
            "observation",
        )
    if world == GRID:
        from swiptopt.env import AuvSwiptEnv

        return AuvSwiptEnv(scenario, observation=observation, **kwargs)
    from swiptopt.env_continuous import AuvSwiptContinuousEnv

    return AuvSwiptContinuousEnv(scenario, **kwargs)


__all__ = ["CONTINUOUS", "ENV_IDS", "GRID", "OBSERVATIONS", "WORLDS", "check_world", "make_env"]
