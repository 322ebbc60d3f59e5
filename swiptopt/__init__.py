"""swiptopt: RL agents versus classical planners on one model of an AUV serving an
underwater sensor network with acoustic SWIPT.

The model modules (``acoustics``, ``harvesting``, ``auv``, ``scenario``, ``link``,
``coverage``) need only numpy; solvers, plotting and clusters load where they are used, so
``import swiptopt`` stays fast and quiet.
"""

from swiptopt.errors import ConfigError
from swiptopt.scenario import PRESETS, Box, Scenario, ScenarioError, Sphere

__version__ = "0.1.0"

__all__ = ["PRESETS", "Box", "ConfigError", "Scenario", "ScenarioError", "Sphere", "__version__"]
