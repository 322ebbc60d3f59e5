"""The RL counterpart of a tour planner: environments whose action is the next stop and how
long to dwell there, with impossible and pointless choices masked, so that
``sb3_contrib.MaskablePPO`` can learn a tour policy on the simulator's own kernel.

- :class:`StopChoiceEnv` (grid world, over :class:`swiptopt.env.AuvSwiptEnv`) and
  :class:`ContinuousStopChoiceEnv` (continuous world, over
  :class:`swiptopt.env_continuous.AuvSwiptContinuousEnv`): one action = one stop and one
  dwell, carried out as kernel steps by the planners' executors (shortest grid paths; the
  continuous tours' legs followed with :func:`swiptopt.continuous.action_towards`); the reward
  is the sum of those steps' kernel rewards. Their docstrings give the contract.
- :class:`FleetStopChoiceEnv` (grid world, over :class:`swiptopt.env_fleet.AuvFleetEnv`): one
  policy decides every AUV's stops, one decision at a time (the AUVs whose assignment is done,
  in AUV order); :class:`FleetStopChoicePolicy` plays a model trained on it as a fleet policy
  (``begin_episode`` + ``act``, for :func:`swiptopt.evaluation.evaluate_fleet`).
- :func:`make_stop_env`: either single-AUV environment, by world name.
- :class:`StopChoicePolicy`: a trained model as a policy on the plain kernel env
  (``begin_episode`` + ``predict``), for :func:`swiptopt.evaluate` and the benchmark; it plays
  the very episodes the model plays in the stop environment.

``import planners.stops`` loads no solver: OMPL loads in the child process that plans the
continuous world's legs, scikit-learn not at all.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from gymnasium.envs.registration import register, registry

from planners.stops.base import CANDIDATE_FEATURES, DWELLS, MASKED_ACTIONS, Dwell, StopChoicePolicy, StopEpisode
from planners.stops.continuous import ContinuousStopChoiceEnv, ContinuousStops, ContinuousStopSettings
from planners.stops.fleet import FleetStopChoiceEnv, FleetStopChoicePolicy, FleetStopSettings
from planners.stops.grid import CANDIDATES, GridStops, GridStopSettings, StopChoiceEnv, build_grid_stops
from swiptopt.scenario import Scenario

#: The registered ids of the stop-choice environments, by world (``import planners``
#: registers them: ``gymnasium.make(STOP_ENV_IDS["grid"], scenario=..., layout_seeds=...)``).
STOP_ENV_IDS = {"grid": "swiptopt/AuvSwiptStops-v0", "continuous": "swiptopt/AuvSwiptContinuousStops-v0"}
#: The fleet's (:class:`FleetStopChoiceEnv`; the scenario's ``n_auvs`` sets the fleet).
FLEET_STOP_ENV_ID = "swiptopt/AuvSwiptFleetStops-v0"
for _id, _cls in ((STOP_ENV_IDS["grid"], "StopChoiceEnv"), (STOP_ENV_IDS["continuous"], "ContinuousStopChoiceEnv"),
                  (FLEET_STOP_ENV_ID, "FleetStopChoiceEnv")):
    if _id not in registry:
        register(id=_id, entry_point=f"planners.stops:{_cls}")


def make_stop_env(world: str, scenario: Scenario | str, *, layout_seeds: Sequence[int] | None = None,
                  **options: Any) -> StopChoiceEnv | ContinuousStopChoiceEnv:
    """The stop-choice environment of ``world`` (``"grid"`` or ``"continuous"``) on
    ``scenario`` (a :class:`~swiptopt.Scenario`, or a preset name).

    ``options`` go to the environment: its settings (``dwells``, ``masked_action``, and per
    world ``candidates``/``shared_fraction`` or ``legs``/``clearance_m``/...), ``backend``,
    ``render_mode`` and :class:`~swiptopt.Scenario` field overrides.
    """
    from swiptopt.worlds import GRID, check_world

    world = check_world(world)
    if isinstance(scenario, str):
        scenario = Scenario.preset(scenario)
    cls = StopChoiceEnv if world == GRID else ContinuousStopChoiceEnv
    return cls(scenario, layout_seeds=layout_seeds, **options)


__all__ = [
    "CANDIDATES",
    "CANDIDATE_FEATURES",
    "DWELLS",
    "FLEET_STOP_ENV_ID",
    "MASKED_ACTIONS",
    "STOP_ENV_IDS",
    "ContinuousStopChoiceEnv",
    "ContinuousStopSettings",
    "ContinuousStops",
    "Dwell",
    "FleetStopChoiceEnv",
    "FleetStopChoicePolicy",
    "FleetStopSettings",
    "GridStopSettings",
    "GridStops",
    "StopChoiceEnv",
    "StopChoicePolicy",
    "StopEpisode",
    "build_grid_stops",
    "make_stop_env",
]
