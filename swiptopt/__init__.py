"""swiptopt: RL agents versus classical planners on one model of an AUV serving an
underwater sensor network with acoustic SWIPT.

The model modules need only numpy; importing the package also registers the Gymnasium
environments ``swiptopt/AuvSwipt-v1`` (the paper's grid; its versions are in the env's Version
History) and ``swiptopt/AuvSwiptContinuous-v0`` (the continuous world; docs/design.md, 'The two
worlds'). Solvers,
plotting, numba and clusters load where they are used, so ``import swiptopt`` stays fast
and quiet.
"""

from gymnasium.envs.registration import register, registry

from swiptopt.errors import ConfigError
from swiptopt.evaluation import EvaluationResult, Policy, Summary, evaluate
from swiptopt.scenario import PRESETS, Box, Scenario, ScenarioError, Sphere

__version__ = "0.1.0"

ENV_ID = "swiptopt/AuvSwipt-v1"
if ENV_ID not in registry:
    # no max_episode_steps here: the scenario sets the episode length, and the env reports it
    # in its spec (AuvSwiptEnv.spec)
    register(id=ENV_ID, entry_point="swiptopt.env:AuvSwiptEnv", vector_entry_point="swiptopt.vector:grid_vector_env")
CONTINUOUS_ENV_ID = "swiptopt/AuvSwiptContinuous-v0"
if CONTINUOUS_ENV_ID not in registry:
    register(
        id=CONTINUOUS_ENV_ID,
        entry_point="swiptopt.env_continuous:AuvSwiptContinuousEnv",
        vector_entry_point="swiptopt.vector:continuous_vector_env",
    )

__all__ = [
    "CONTINUOUS_ENV_ID",
    "ENV_ID",
    "PRESETS",
    "Box",
    "ConfigError",
    "EvaluationResult",
    "Policy",
    "Scenario",
    "ScenarioError",
    "Sphere",
    "Summary",
    "evaluate",
    "__version__",
]
