"""What a continuous planner plans: the legs between stops, the OMPL calls made, and the
plan of one layout (:class:`ContinuousPlan`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

#: A waypoint counts as reached within this distance, m. The env's actions are float32, so
#: a step aimed exactly at a waypoint lands within about 1e-6 m of it.
ARRIVAL_TOLERANCE_M = 1e-3


class LegPath(NamedTuple):
    """A way between two points as a leg planner made it."""

    waypoints_m: np.ndarray
    """(k, 3) metres (x, y, depth), from the first point to the second."""
    source: str
    """How it was made: ``"straight"`` (the free straight segment), ``"ompl"`` (OMPL's exact
    path), ``"straight (OMPL <status>)"`` (OMPL found no exact path: the straight segment,
    blocked), or ``"straight (obstacles ignored)"`` (the straight-line planner)."""
    blocked: bool = False
    """Whether the way is known not to be free (OMPL found no exact path around the
    obstacles): the tour avoids it, and the executor keeps it only in the planned order."""

    def reversed(self) -> LegPath:
        """The same way, travelled the other way."""
        return LegPath(self.waypoints_m[::-1].copy(), self.source, self.blocked)


@dataclass(frozen=True, eq=False)
class Leg:
    """The way from one stop (or the start) to the next."""

    waypoints_m: np.ndarray
    """(k, 3) metres (x, y, depth), from the previous stop to this one."""
    energy_j: float
    """AUV energy along it at ground speed under the current (:func:`planners.paths3d.path_energy_j`), J."""
    steps: int
    """Steps the executor takes along it (each segment in steps of at most one step's length)."""
    source: str
    """How it was made (:attr:`LegPath.source`)."""
    blocked: bool = False
    """Whether it is known not to be free (:attr:`LegPath.blocked`)."""


def leg_steps(waypoints_m: np.ndarray, max_step_m: float) -> int:
    """Steps the executor takes along a polyline: each segment in whole steps of at most
    ``max_step_m`` (the last one shorter)."""
    lengths = np.linalg.norm(np.diff(np.asarray(waypoints_m, dtype=float), axis=0), axis=1)
    lengths = lengths[lengths > ARRIVAL_TOLERANCE_M]
    return int(np.ceil(lengths / max_step_m - 1e-9).sum())


@dataclass(frozen=True, eq=False)
class OmplCall:
    """One OMPL plan between two stops (:func:`planners.paths3d.plan_path_3d`)."""

    start_m: np.ndarray
    goal_m: np.ndarray
    status: str
    """``"exact"``, ``"approximate"``, ``"timeout"``, ... (:class:`planners.paths3d.PathResult`)."""
    energy_j: float
    """Energy of OMPL's path, J (``inf`` without one)."""
    used: bool
    """Whether the leg takes OMPL's path (else the straight segment: free and cheaper, or the
    blocked fallback when OMPL found no exact path)."""


@dataclass(frozen=True, eq=False)
class ContinuousPlan:
    """What a continuous planner planned for one layout."""

    k: int
    """Number of k-means groups of the kept plan (before pruning)."""
    hover_points_m: np.ndarray
    """(S, 3) the stops in tour order, m."""
    groups: tuple[np.ndarray, ...]
    """Per stop, the nodes its hover point was placed for."""
    legs: tuple[Leg, ...]
    """Per stop, the leg that reaches it."""
    dwell_steps: np.ndarray
    """(S,) hover steps at each stop after the arrival step."""
    dwell_value: float | None
    """The dwell program's objective (weighted service of the dwells, continuous time)."""
    dwell_status: str
    """The dwell program's status (:class:`planners.power_split.PowerSplitResult`)."""
    model_return: float
    """The planned trajectory's return in the per-step model (module docstring, step 5)."""
    positions_m: np.ndarray
    """(T + 1, 3) the planned position after each step, the start first, m."""
    actions: np.ndarray
    """(T, 3) float32 the planned actions."""
    status: str
    """How the plan was made: the tour's status, the dwell's, what was dropped."""
    candidates: dict[int, float] = field(default_factory=dict)
    """Model return of the best plan for every K tried."""
    ompl_plans: tuple[OmplCall, ...] = ()
    """Every OMPL plan made for this layout (over every K tried), in order."""
    sites_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """(N, 3) the points the executor moves between: the start, then every hover point of
    the plan's K (the stops and those pruned or dropped), m."""
    routes: dict[tuple[int, int], Leg] = field(default_factory=dict)
    """The leg from site i to site j (j >= 1), for every pair: the stops' legs are among them."""
    stop_sites: tuple[int, ...] = ()
    """The site of each stop, in tour order."""
    site_model: Any = None
    """:func:`point_model` of :attr:`sites_m`: what a step at each site earns (the executor's
    estimates)."""

    @property
    def ompl_statuses(self) -> dict[str, int]:
        """How many of :attr:`ompl_plans` ended in each status."""
        counts: dict[str, int] = {}
        for call in self.ompl_plans:
            counts[call.status] = counts.get(call.status, 0) + 1
        return counts

