"""The continuous world's tour planners: :class:`OmplTourPlanner` (legs around the obstacles
and against the current by OMPL) and :class:`StraightLinePlanner` (straight legs, obstacles
and current ignored), both on the shared pipeline of :mod:`planners.continuous.tour`."""

from __future__ import annotations

from typing import Any

import numpy as np

from planners.continuous.plan import LegPath, OmplCall
from planners.continuous.tour import TOUR_PARAMETERS, TourPlanner
from planners.paths3d import CRASHING_PLANNERS, NO_PYTHON_OBJECTIVE_PLANNERS, PLANNERS
from swiptopt.validation import Param

#: Which legs the OMPL tour asks OMPL for.
OMPL_LEGS = ("blocked", "all")
#: The OMPL planners the tour can use: those that take the energy objective and run here.
OMPL_TOUR_PLANNERS = tuple(p for p in PLANNERS if p not in CRASHING_PLANNERS and p not in NO_PYTHON_OBJECTIVE_PLANNERS)


class OmplTourPlanner(TourPlanner):
    """Hover points in continuous space, a tour over OMPL energy paths, convex dwells, and an
    executor that follows the paths (:mod:`planners.continuous`).

    A leg is the straight segment when it keeps ``clearance_m`` from everything
    (``ompl_legs="blocked"``, the default: OMPL's own simplifier reduces such a leg to it
    anyway, up to the current's depth shear), else the AUV-energy path from
    :func:`planners.paths3d.plan_path_3d` around the obstacles and against the current,
    stopped after ``ompl_iterations`` iterations (a count, never the wall clock).
    ``ompl_legs="all"`` asks OMPL for every leg and keeps the cheaper of its path and the free
    straight segment. A pair OMPL cannot join exactly (an approximate path, a timeout) falls
    back to the straight segment, blocked.

    OMPL draws from one process-wide generator (:mod:`planners.paths3d`): the planner passes
    ``seed + 1`` (what the benchmark's fresh OMPL process is seeded with) and plans each
    layout once, so the same seed and layouts give the same plans in a fresh process; a
    second planner seed in the same process is refused by ``plan_path_3d``.

    Arguments: ``seed`` and the settings of :attr:`parameters` (each with its unit, bounds and
    meaning: ``swiptopt run --list`` prints them).
    """

    parameters = {
        **TourPlanner.parameters,
        "ompl_iterations": Param(default=150, kind="int", lo=1, hi=10**7,
                                 doc="OMPL planner iterations per leg (a deterministic budget, not a time limit)"),
        "ompl_planner": Param(default="InformedRRTstar", kind="str", choices=OMPL_TOUR_PLANNERS,
                              doc="the OMPL planner (one that takes the energy objective)"),
        "ompl_legs": Param(default="blocked", kind="str", choices=OMPL_LEGS,
                           doc="'blocked': OMPL only for legs whose straight segment is not free; 'all': every leg"),
    }

    def leg_between(self, scenario: Any, a: np.ndarray, b: np.ndarray) -> LegPath:
        from planners.paths3d import path_energy_j, plan_path_3d, segments_free

        straight = np.stack([a, b])
        free = bool(segments_free(a, b, scenario, clearance_m=self.clearance_m)[0])
        if free and self.ompl_legs == "blocked":
            return LegPath(straight, "straight")
        result = plan_path_3d(
            a, b, scenario, planner=self.ompl_planner, objective="energy", seed=self.seed + 1,
            clearance_m=self.clearance_m, iterations=self.ompl_iterations,
        )
        use = result.exact and not (free and path_energy_j(straight, scenario) <= float(result.energy_j))
        self.ompl_calls_.append(OmplCall(a.copy(), b.copy(), result.status, float(result.energy_j), bool(use)))
        if use:
            return LegPath(result.waypoints, "ompl")
        if free:
            return LegPath(straight, "straight")
        return LegPath(straight, f"straight (OMPL {result.status})", blocked=True)


class StraightLinePlanner(TourPlanner):
    """The OMPL tour's pipeline (hover points, dwells, the choice of K) with straight legs
    that ignore obstacles and the current, so its model believes every leg is free: the tour
    minimises Euclidean length, the executor steers straight at each stop and, when a move
    makes no progress (the env stopped it at an obstacle), gives that stop up and heads for
    the next. No OMPL.

    Arguments: ``seed`` and the settings of :attr:`parameters`: the OMPL tour's without the
    OMPL ones. ``clearance_m`` applies to the hover points only. ``adaptive`` is off by
    default: the executor's reactions trust the model's routes, which here cross obstacles
    (the end phase would head for sites behind an obstacle), and on the harbour preset they
    cost this planner more than they earned (``benchmarks/continuous_planners.py`` compares).
    """

    parameters = {**TourPlanner.parameters, "adaptive": Param(
        default=False, kind="bool", doc=TOUR_PARAMETERS["adaptive"].doc + " (off: the routes cross obstacles)")}
    tour_cost = "length"

    def leg_between(self, scenario: Any, a: np.ndarray, b: np.ndarray) -> LegPath:
        return LegPath(np.stack([a, b]), "straight (obstacles ignored)")
