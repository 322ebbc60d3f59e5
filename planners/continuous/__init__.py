"""Planners in the continuous world: hover points anywhere in the water, a tour over them,
dwells from the convex program, and an executor of velocity actions.

:class:`OmplTourPlanner` and :class:`StraightLinePlanner` are policies for
:class:`swiptopt.env_continuous.AuvSwiptContinuousEnv` (``begin_episode`` + ``predict``), so
:func:`swiptopt.evaluate` scores them like any agent. They share every step but the legs.
The package is split by job:

- :mod:`planners.continuous.plan`: what a plan holds (:class:`ContinuousPlan`, its legs);
- :mod:`planners.continuous.model`: the per-step model that prices positions and trajectories;
- :mod:`planners.continuous.executor`: the plan turned into actions, reacting to the nodes' state;
- :mod:`planners.continuous.tour`: the shared pipeline (hover points, legs, tour, dwells, K);
- :mod:`planners.continuous.planners`: the two planners, which differ in their legs.
"""

from planners.continuous.executor import NO_PROGRESS_M, Executor
from planners.continuous.model import PointService, hover_values, point_model, step_functions, trajectory_return
from planners.continuous.plan import ARRIVAL_TOLERANCE_M, ContinuousPlan, Leg, LegPath, OmplCall, leg_steps
from planners.continuous.planners import OMPL_LEGS, OMPL_TOUR_PLANNERS, OmplTourPlanner, StraightLinePlanner
from planners.continuous.tour import MAX_SEED, TOUR_PARAMETERS, TourPlanner

__all__ = [
    "ARRIVAL_TOLERANCE_M", "ContinuousPlan", "Executor", "Leg", "LegPath", "MAX_SEED", "NO_PROGRESS_M", "OMPL_LEGS",
    "OMPL_TOUR_PLANNERS", "OmplCall", "OmplTourPlanner", "PointService", "StraightLinePlanner", "TOUR_PARAMETERS",
    "TourPlanner", "hover_values", "leg_steps", "point_model", "step_functions", "trajectory_return",
]
