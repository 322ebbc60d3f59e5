"""Classical baselines on ``swiptopt``'s model, importable as a library.

Everything a user needs is importable from here::

    from planners import solve_tsp, plan_path_3d, kmeans_hover_points, optimise_dwell_and_split

- hover points: :func:`kmeans_hover_points` (k-means of the node positions, scikit-learn);
- tours: :func:`solve_tsp` (OR-Tools CP-SAT or routing), :func:`held_karp` (reference);
- 3D paths: :func:`plan_path_3d` (OMPL around obstacles, length or AUV energy);
- power split and dwell: :func:`optimal_split_ratio` (closed form),
  :func:`optimise_dwell_and_split` (convex program, cvxpy);
- bounds: :func:`upper_bound`, :func:`exact_optimum` (dynamic programming on tiny scenarios)
  and :func:`exact_state_bound` (its size, known before running it);
- planners that run in the environment: :class:`KMeansTspPlanner`,
  :class:`LawnmowerPlanner`, :class:`GreedyPlanner`, :class:`RateGreedyPlanner`,
  :class:`RewardKMeansTspPlanner` (k-means + TSP with its choices scored by the reward);
- in the continuous world (``swiptopt/AuvSwiptContinuous-v0``): :class:`OmplTourPlanner`
  (hover points anywhere, a tour over OMPL energy paths, convex dwells) and
  :class:`StraightLinePlanner` (the same with straight legs that ignore obstacles and current);
- the RL counterpart of a tour planner: :class:`StopChoiceEnv` and
  :class:`ContinuousStopChoiceEnv` (:mod:`planners.stops`: the action is the next stop and its
  dwell, masked for MaskablePPO, executed by the planners' executors; registered as
  :data:`STOP_ENV_IDS`), :func:`make_stop_env`, and :class:`StopChoicePolicy`, which plays a
  trained model on the kernel env;
- the optimum as the reference: :func:`solve_optimum` (the episode as a mixed-integer
  program, HiGHS: best walk, proven bound, gap) and its policy :class:`MilpPlanner`; the
  per-step model both use, :func:`step_model`; the walk polish :func:`polish_walk`;
  :func:`policy_bounds` (which of its bounds holds for which class of policy),
  :func:`hindsight_bound` (perfect information) and :func:`adaptive_optimum` (the exact
  optimal adaptive policy of a small instance): docs/optimum.md;
- fleets of AUVs (``swiptopt.env_fleet.AuvFleetEnv``, docs/fleet.md): :class:`FleetRoutingPlanner`
  (k-means hover points shared out by OR-Tools vehicle routing), :func:`solve_fleet_optimum`
  and :class:`FleetMilpPlanner` (the MILP with a walk per AUV), :class:`FleetStopChoiceEnv`
  and :class:`FleetStopChoicePolicy` (the stop-choosing agent for a fleet).

The solvers (ortools, ompl, cvxpy, highspy, scikit-learn, scipy) load inside the functions that use them,
so ``import planners`` stays light; a test checks that it imports none of them.
"""

from planners.adaptive import AdaptiveOptimum, AdaptivePolicy, adaptive_optimum
from planners.bounds import ExactOptimum, PolicyBound, UpperBound, exact_optimum, exact_state_bound, upper_bound
from planners.clustering import HoverPoints, kmeans_hover_points
from planners.continuous import ContinuousPlan, OmplTourPlanner, StraightLinePlanner
from planners.fleet import FleetRoutingPlanner
from planners.fleet_optimal import FleetMilpPlanner, solve_fleet_optimum
from planners.grid import bfs_distances, distance_matrix, path_actions
from planners.hindsight import HindsightBudget, HindsightResult, hindsight_bound
from planners.optimal import BUDGETS, MilpBudget, MilpPlanner, OptimumResult, policy_bounds, solve_optimum
from planners.paths3d import PathResult, available_planners, path_energy_j, plan_path_3d, segments_free
from planners.policies import GreedyPlanner, KMeansTspPlanner, LawnmowerPlanner, Plan, Stop
from planners.power_split import (
    DwellSplitProblem,
    PowerSplitResult,
    optimal_split_ratio,
    optimise_dwell_and_split,
)
from planners.rate_greedy import RateGreedyPlanner, rate_greedy_actions
from planners.reward_tour import RewardKMeansTspPlanner
from planners.service import StepModel, step_model
from planners.stops import (
    STOP_ENV_IDS,
    ContinuousStopChoiceEnv,
    FleetStopChoiceEnv,
    FleetStopChoicePolicy,
    StopChoiceEnv,
    StopChoicePolicy,
    make_stop_env,
)
from planners.tsp import TspResult, held_karp, solve_tsp, tour_length
from planners.walk_search import polish_walk

__all__ = [
    "AdaptiveOptimum",
    "AdaptivePolicy",
    "BUDGETS",
    "ContinuousPlan",
    "ContinuousStopChoiceEnv",
    "DwellSplitProblem",
    "ExactOptimum",
    "FleetMilpPlanner",
    "FleetRoutingPlanner",
    "FleetStopChoiceEnv",
    "FleetStopChoicePolicy",
    "GreedyPlanner",
    "HindsightBudget",
    "HindsightResult",
    "HoverPoints",
    "KMeansTspPlanner",
    "LawnmowerPlanner",
    "MilpBudget",
    "MilpPlanner",
    "OmplTourPlanner",
    "OptimumResult",
    "PathResult",
    "Plan",
    "PolicyBound",
    "PowerSplitResult",
    "RateGreedyPlanner",
    "RewardKMeansTspPlanner",
    "STOP_ENV_IDS",
    "StepModel",
    "Stop",
    "StopChoiceEnv",
    "StopChoicePolicy",
    "StraightLinePlanner",
    "TspResult",
    "UpperBound",
    "adaptive_optimum",
    "available_planners",
    "bfs_distances",
    "distance_matrix",
    "exact_optimum",
    "exact_state_bound",
    "held_karp",
    "hindsight_bound",
    "kmeans_hover_points",
    "make_stop_env",
    "optimal_split_ratio",
    "optimise_dwell_and_split",
    "path_actions",
    "path_energy_j",
    "plan_path_3d",
    "policy_bounds",
    "polish_walk",
    "rate_greedy_actions",
    "segments_free",
    "solve_fleet_optimum",
    "solve_optimum",
    "solve_tsp",
    "step_model",
    "tour_length",
    "upper_bound",
]
