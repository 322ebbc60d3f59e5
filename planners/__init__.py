"""Classical baselines on ``swiptopt``'s model, importable as a library (SPEC 6).

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
  :class:`LawnmowerPlanner`, :class:`GreedyPlanner`.

The solvers (ortools, ompl, cvxpy, scikit-learn) load inside the functions that use them,
so ``import planners`` stays light; a test checks that it imports none of them.
"""

from planners.bounds import ExactOptimum, UpperBound, exact_optimum, exact_state_bound, upper_bound
from planners.clustering import HoverPoints, kmeans_hover_points
from planners.grid import bfs_distances, distance_matrix, path_actions
from planners.paths3d import PathResult, available_planners, path_energy_j, plan_path_3d
from planners.policies import GreedyPlanner, KMeansTspPlanner, LawnmowerPlanner, Plan, Stop
from planners.power_split import (
    DwellSplitProblem,
    PowerSplitResult,
    optimal_split_ratio,
    optimise_dwell_and_split,
)
from planners.tsp import TspResult, held_karp, solve_tsp, tour_length

__all__ = [
    "DwellSplitProblem",
    "ExactOptimum",
    "GreedyPlanner",
    "HoverPoints",
    "KMeansTspPlanner",
    "LawnmowerPlanner",
    "PathResult",
    "Plan",
    "PowerSplitResult",
    "Stop",
    "TspResult",
    "UpperBound",
    "available_planners",
    "bfs_distances",
    "distance_matrix",
    "exact_optimum",
    "exact_state_bound",
    "held_karp",
    "kmeans_hover_points",
    "optimal_split_ratio",
    "optimise_dwell_and_split",
    "path_actions",
    "path_energy_j",
    "plan_path_3d",
    "solve_tsp",
    "tour_length",
    "upper_bound",
]
