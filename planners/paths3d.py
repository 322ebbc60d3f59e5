"""3D paths for the AUV: OMPL geometric planning around boxes, spheres and the seabed.

The idiom stays visible: a 3D ``RealVectorStateSpace`` over the volume, a Python validity
checker, ``SimpleSetup`` -> objective -> planner -> ``solve(time limit)`` -> simplify, and a
:class:`PathResult` that reports what OMPL actually delivered (exact, approximate or
nothing) instead of assuming success.

Speed. OMPL calls back into Python for every state it checks, every motion and every motion
cost. The checks (:func:`_point_free`, :func:`_segment_free`) and the energy
(:func:`_segment_energy`) are plain Python that numba compiles (reusing the continuous
world's compiled seabed lookup), and a motion is checked by one compiled call
(:func:`_motion_validator_type`: the states OMPL's own discrete validator would test, the
same answers) instead of one Python call per state. ``python benchmarks/continuous_planners.py``
prints what a harbour layout's tour costs to plan. Without numba the same functions run as
Python.

Motion checking. OMPL checks a straight motion by testing states spaced at most ``g``
apart along it (the space's longest valid segment). On its own that can cut a corner or
jump a thin wall between two tested states. Here the validity checker tests the
obstacles *grown by g/2* (plus any requested clearance): the distance to an obstacle is
1-Lipschitz along a segment and every point of a checked motion is within g/2 of a
tested state, so every point of an accepted motion lies outside the true obstacles, however
thin they are. ``g`` is the smaller of 0.5 % of the volume's diagonal and a quarter of the
smallest obstacle dimension (box edge or sphere diameter), so the growth stays below 1/8
of any obstacle; it shrinks further when the start or goal sits closer to an obstacle
than g/2. The cost is a slightly conservative path (and gaps narrower than g close).

Seeding. OMPL draws from one process-wide seed generator that seeds every RNG as it is
created; ``ompl.util.RNG.setSeed`` is meant to be called once, before the first planner
exists. So :func:`plan_path_3d` sets its ``seed`` once per process, on the first call that
passes one, and that call must come before any unseeded call (which would have drawn numbers
already). Later calls with the same seed continue the random stream (they do not replay the
first plan); a different seed, or a seed after an unseeded call, raises ``ConfigError``
instead of reseeding. (Checked on ompl 2.0.1: a late ``RNG.setSeed`` logs "Random number
generation already started" yet does reseed the RNGs created afterwards, while
``RNG.getSeed()`` keeps reporting the first seed; OMPL documents late seeding as
unsupported, so this module does not rely on it.) A seed fixes the sample sequence of a
fresh process; planners that stop at the first solution (RRTConnect) then repeat their path
exactly. Anytime planners stop at a wall-clock limit, so their iteration count depends on
the machine's speed and load: in fresh processes with the same seed they repeated their
paths on an idle machine and differed under CPU load.

Iteration budgets. With ``iterations``, OMPL's solve stops after that many evaluations of
its termination condition (the tree planners evaluate it once per iteration: one sample,
extension and rewiring), and the simplification after ``SIMPLIFY_ITERATION_SHARE`` of as
many (at least one round). In one process, a seed and the same sequence of calls give the
same paths on any machine and under any load (no thread is involved: the condition is a
counting Python callable evaluated by the planner's own loop).

``ompl`` is imported inside the functions, so ``import planners.paths3d`` stays light.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from swiptopt import auv, fpmath
from swiptopt.continuous import _seabed_depth
from swiptopt.errors import ConfigError
from swiptopt.scenario import Box, Scenario, Sphere
from swiptopt.validation import Spec, check_value

#: Planner names this module knows, in the order they are listed; which of them exist
#: depends on the installed OMPL (see :func:`available_planners`).
PLANNERS: tuple[str, ...] = (
    "AORRTC",
    "RRTstar",
    "InformedRRTstar",
    "SORRTstar",
    "BITstar",
    "FMT",
    "BFMT",
    "PRMstar",
    "PRM",
    "RRTConnect",
    "RRT",
    "KPIECE1",
    "BKPIECE1",
    "LBKPIECE1",
)
OBJECTIVES: tuple[str, ...] = ("length", "energy")
#: What the scalar arguments of :func:`plan_path_3d` may hold (``clearance_m`` also that of
#: :func:`segments_free`), checked by :func:`swiptopt.validation.check_value`.
ARGUMENTS = {
    "time_limit_s": Spec(lo=0, lo_open=True, unit="s", doc="the wall-clock limit of OMPL's solve"),
    "clearance_m": Spec(lo=0, unit="m", doc="the distance kept from every obstacle"),
    "objective": Spec(kind="str", choices=OBJECTIVES, doc="what the path minimises"),
    "iterations": Spec(kind="int", lo=1, hi=2**31, hi_open=True, strict=True, optional=True,
                       doc="a deterministic budget of planner iterations (None: the wall-clock limit)"),
    "seed": Spec(kind="int", lo=1, hi=2**32, hi_open=True, strict=True, optional=True,
                 doc="OMPL's process-wide seed (OMPL replaces 0 by 1)"),
}
#: The planner used when ``planner=None``: Informed RRT* for both objectives. On path length
#: it matches RRT*, SORRT* and BIT* round a sphere and round the harbour's pier, close to the
#: optimum at short time limits (``python benchmarks/bench_paths3d.py`` prints the
#: comparison); for energy, with the objective's admissible heuristic, it does as well as
#: RRT*/SORRT* and better than BIT*.
DEFAULT_PLANNER: dict[str, str] = {"length": "InformedRRTstar", "energy": "InformedRRTstar"}
#: Planners OMPL provides that this module refuses, with the reason. AORRTC (OMPL 2.0's
#: ``AOXRRTConnect::findNeighbour``) walks its list of neighbours within a radius until one
#: passes a cost test, with no bound on the index: when none passes it reads past the end of
#: the list, and the process dies (SIGSEGV). ``plan_path_3d((5, 165, 15), (185, 25, 5),
#: Scenario.preset("harbour"), planner="AORRTC", time_limit_s=0.2)`` does so every time; our
#: validity checker and state space play no part (the fault is inside the planner's own
#: nearest-neighbour search; VAMP's AORRTC had the same fault and fixed it with a bound).
CRASHING_PLANNERS: dict[str, str] = {
    "AORRTC": (
        "it crashes the process (a segmentation fault in OMPL's AOXRRTConnect::findNeighbour, "
        "an unbounded index over the neighbour list)"
    ),
}
#: With a Python objective these never return (seen with ompl 2.0.1). PRM grows its
#: roadmap and searches it for a solution in two threads; the solution thread calls the
#: objective, needing the GIL that the thread running ``solve`` holds while it waits.
NO_PYTHON_OBJECTIVE_PLANNERS = frozenset({"PRM", "PRMstar"})
#: These ask the motion validator where a motion stops being valid (OMPL's ``checkMotion``
#: with ``lastValid``), which a validator written in Python cannot answer through the
#: bindings (their trampoline drops ``lastValid``): they keep OMPL's own discrete validator,
#: calling the compiled validity checker state by state. Every other planner gets
#: :func:`_motion_validator_type`'s validator: one compiled call per motion.
LAST_VALID_PLANNERS = frozenset({"KPIECE1", "BKPIECE1", "LBKPIECE1"})

CHECK_SPACING_FRACTION = 0.005
"""Motion-check spacing as a fraction of the volume's diagonal (OMPL's default is 0.01)."""
SMALLEST_OBSTACLE_SHARE = 0.25
"""The spacing is at most this share of the smallest obstacle dimension."""
MIN_SPACING_SHARE = 0.01
"""Spacing floor, as a share of the default spacing; a start or goal nearer an obstacle
than half of it is refused."""
SIMPLIFY_TIME_SHARE = 0.5
"""Simplification may take at most this share of ``time_limit_s`` on top of the solve."""
SIMPLIFY_ITERATION_SHARE = 0.01
"""With an iteration budget, simplification may run this share of ``iterations`` rounds (each
round tries many shortcuts: a share of the planner's count of single iterations is plenty)."""

# 3-point Gauss-Legendre on [0, 1]: exact for polynomials up to degree 5 and for a uniform
# current; the propulsion power along a segment in a depth-linear current is smooth.
_GAUSS_T = (0.5 - 0.5 * math.sqrt(0.6), 0.5, 0.5 + 0.5 * math.sqrt(0.6))
_GAUSS_W = (5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0)

_STATUS_NAMES = {
    "EXACT_SOLUTION": "exact",
    "APPROXIMATE_SOLUTION": "approximate",
    "TIMEOUT": "timeout",
    "INFEASIBLE": "infeasible",
    "INVALID_START": "invalid_start",
    "INVALID_GOAL": "invalid_goal",
    "UNRECOGNIZED_GOAL_TYPE": "unrecognized_goal_type",
    "CRASH": "crash",
    "ABORT": "abort",
    "UNKNOWN": "unknown",
}


@dataclass(frozen=True, eq=False)
class PathResult:
    """What one call of :func:`plan_path_3d` delivered."""

    waypoints: np.ndarray
    """(k, 3) metres (x, y, depth). First row = start; last row = goal when ``exact``; an
    approximate path ends where the planner got closest; (0, 3) when there is no path."""
    length_m: float
    """Length of the polyline, m (``inf`` when there is no path)."""
    exact: bool
    """True when the path reaches the goal exactly."""
    status: str
    """``"exact"``, ``"approximate"`` (a path towards the goal that does not reach it),
    ``"timeout"`` (no path within the time limit), or OMPL's other outcomes in lower case
    (``"infeasible"``, ``"invalid_start"``, ``"invalid_goal"``, ``"crash"``, ...)."""
    planner: str
    """OMPL planner name used."""
    objective: str
    """``"length"`` or ``"energy"``."""
    solve_time_s: float
    """Wall-clock time of OMPL's solve, s."""
    simplify_time_s: float
    """Wall-clock time of the simplification, s (0 when not simplified)."""
    energy_j: float | None
    """AUV energy along the path (see :func:`segment_energy_j`), J, when a Scenario was
    given (``inf`` when there is no path), else None."""
    check_spacing_m: float
    """Largest gap between checked states along a motion; obstacles were grown by half of
    it (plus ``clearance_m``) for the check."""


# --------------------------------------------------------------------------- energy


def segment_energy_j(waypoints_m: np.ndarray, scenario: Scenario) -> np.ndarray:
    """AUV energy of each straight segment of a polyline under the scenario's current, J.

    ``waypoints_m``: (k, 3); returns (k - 1,). The AUV holds ground speed ``speed_mps``
    along each segment (as the simulator kernel does), so it needs the water-relative
    speed ``|v u - c(depth)|`` (``auv.water_relative_speed_mps``), whose propulsion power
    (paper eq. 18, ``auv.propulsion_power_w``) is averaged along the segment by 3-point
    Gauss-Legendre quadrature over depth; the move costs ``(P_mean + H) d / v`` (eq. 16,
    ``auv.move_energy_j``). With no current this is ``(P(v) + H) / v`` per metre.
    """
    p = np.asarray(waypoints_m, dtype=float)
    delta = np.diff(p, axis=0)  # (k-1, 3)
    dist = np.linalg.norm(delta, axis=1)
    direction = np.divide(delta, dist[:, None], out=np.zeros_like(delta), where=dist[:, None] > 0)
    depths = p[:-1, 2, None] + delta[:, 2, None] * np.asarray(_GAUSS_T)  # (k-1, 3 nodes)
    water_mps = auv.water_relative_speed_mps(
        direction[:, None, :] * scenario.speed_mps, scenario.current_at_mps(depths)
    )
    power_w = auv.propulsion_power_w(
        water_mps,
        scenario.drag_coefficient,
        scenario.frontal_area_m2,
        scenario.water_density_kg_m3,
        scenario.propulsion_efficiency,
    )
    mean_power_w = fpmath.dot(power_w, np.asarray(_GAUSS_W))
    return auv.move_energy_j(dist, scenario.speed_mps, mean_power_w, scenario.hotel_power_w)


def path_energy_j(waypoints_m: np.ndarray, scenario: Scenario) -> float:
    """Total AUV energy along a polyline (k, 3), J (sum of :func:`segment_energy_j`)."""
    return float(segment_energy_j(waypoints_m, scenario).sum())


def _min_energy_per_m(scenario: Scenario) -> float:
    """A lower bound on the energy per metre of ground track over all directions and
    depths, J/m: the water-relative speed is at least min over depth of |v - |c(z)||."""
    c_top = scenario.current_at_mps(0.0)
    c_bottom = scenario.current_at_mps(scenario.depth_m)
    span = c_bottom - c_top
    t = 0.0 if not span.any() else float(np.clip(-fpmath.dot(c_top, span) / fpmath.dot(span, span), 0.0, 1.0))
    slowest = math.sqrt(fpmath.dot(c_top + t * span, c_top + t * span))  # |c| is convex in depth
    fastest = math.sqrt(max(fpmath.dot(c_top, c_top), fpmath.dot(c_bottom, c_bottom)))
    v = scenario.speed_mps
    water_min = max(slowest - v, v - fastest, 0.0)
    power = auv.propulsion_power_w(
        water_min,
        scenario.drag_coefficient,
        scenario.frontal_area_m2,
        scenario.water_density_kg_m3,
        scenario.propulsion_efficiency,
    )
    return float(auv.move_energy_j(1.0, v, power, scenario.hotel_power_w))


def _segment_energy(ax, ay, az, bx, by, bz, coef):  # type: ignore[no-untyped-def]
    """A scalar twin of :func:`segment_energy_j` for OMPL's hot loop: one segment, J.

    ``coef`` (:func:`_energy_coefficients`): speed, hotel power, the cubic coefficient of
    eq. 18, the current at the surface and its gradient with depth. Plain Python on floats,
    compiled by numba (:func:`_energy_function`): numpy's overhead per call outweighs one
    segment's arithmetic, and the planners ask for hundreds of thousands of motion costs. A test pins it to
    :func:`segment_energy_j`.
    """
    dx = bx - ax
    dy = by - ay
    dz = bz - az
    d = math.sqrt(dx * dx + dy * dy + dz * dz)
    if d == 0.0:
        return 0.0
    v = coef[0]
    s = v / d
    ux = dx * s - coef[3]
    uy = dy * s - coef[4]
    uz = dz * s - coef[5]
    cube = 0.0
    for n in range(3):
        z = az + _GAUSS_T[n] * dz
        wx = ux - coef[6] * z
        wy = uy - coef[7] * z
        wz = uz - coef[8] * z
        w2 = wx * wx + wy * wy + wz * wz
        cube += _GAUSS_W[n] * w2 * math.sqrt(w2)
    return (coef[2] * cube + coef[1]) * d / v


def _energy_coefficients(scenario: Scenario) -> np.ndarray:
    """The constants of :func:`_segment_energy`, from the shared functions: the cubic
    coefficient of eq. 18 is ``propulsion_power_w(1 m/s)`` and the current is the
    scenario's (linear in depth) at the surface and the bottom."""
    k_w = float(
        auv.propulsion_power_w(
            1.0,
            scenario.drag_coefficient,
            scenario.frontal_area_m2,
            scenario.water_density_kg_m3,
            scenario.propulsion_efficiency,
        )
    )
    top = np.asarray(scenario.current_at_mps(0.0), dtype=float)
    gradient = (np.asarray(scenario.current_at_mps(scenario.depth_m), dtype=float) - top) / scenario.depth_m
    return np.array([scenario.speed_mps, scenario.hotel_power_w, k_w, *top, *gradient], dtype=float)


@functools.lru_cache(maxsize=1)
def _energy_function() -> Callable[..., float]:
    """:func:`_segment_energy`, numba-compiled when numba is installed."""
    from swiptopt.jit import compile_family, numba_available

    if not numba_available():
        return _segment_energy
    compiled = compile_family({"_segment_energy": _segment_energy})["_segment_energy"]
    compiled(0.0, 0.0, 0.0, 1.0, 1.0, 1.0, np.ones(9))  # compile now, not in a planner's time limit
    return compiled


def _segment_energy_fn(scenario: Scenario) -> Callable[[float, float, float, float, float, float], float]:
    """:func:`_segment_energy` for ``scenario``'s AUV and current, as f(ax, ay, az, bx, by, bz)."""
    energy, coef = _energy_function(), _energy_coefficients(scenario)
    return lambda ax, ay, az, bx, by, bz: float(energy(ax, ay, az, bx, by, bz, coef))


@functools.cache
def _motion_validator_type() -> type:
    """The OMPL motion validator class (built once, on first use, so ompl loads lazily)."""
    from ompl import base as ob

    class CompiledMotionValidator(ob.MotionValidator):
        """OMPL's discrete motion check (the states ``validSegmentCount`` apart, each tested
        like the validity checker, the end first) as one compiled call per motion
        (:func:`_segment_free`) instead of one Python call per state: the same answers."""

        def __init__(self, si: Any, space: Any, geom: np.ndarray, heights: np.ndarray):
            super().__init__(si)
            self._count = space.validSegmentCount
            self._segment_free = _checks()[1]
            self._geom, self._heights = geom, heights

        def checkMotion(self, s1: Any, s2: Any) -> bool:
            return self._segment_free(
                s1[0], s1[1], s1[2], s2[0], s2[1], s2[2], 1, self._count(s1, s2), self._geom, self._heights
            )

    return CompiledMotionValidator


@functools.cache
def _energy_objective_type() -> type:
    """The OMPL objective class (built once, on first use, so ompl loads lazily)."""
    from ompl import base as ob

    class AuvEnergyObjective(ob.OptimizationObjective):
        """Sum over motions of the AUV's energy (:func:`segment_energy_j`), J."""

        def __init__(self, si: Any, scenario: Scenario):
            super().__init__(si)
            self._segment_j = _energy_function()
            self._coef = _energy_coefficients(scenario)
            self._floor_j_per_m = _min_energy_per_m(scenario)
            currents = np.stack([scenario.current_at_mps(0.0), scenario.current_at_mps(scenario.depth_m)])
            self._symmetric = not currents.any()
            self._zero = ob.Cost(0.0)
            self.setCostThreshold(ob.Cost(0.0))  # never "good enough": optimise until the limit

        def stateCost(self, state: Any) -> Any:
            return self._zero

        def motionCost(self, s1: Any, s2: Any) -> Any:
            return ob.Cost(self._segment_j(s1[0], s1[1], s1[2], s2[0], s2[1], s2[2], self._coef))

        def motionCostHeuristic(self, s1: Any, s2: Any) -> Any:
            # admissible: no metre of ground track costs less than the floor
            dx, dy, dz = s2[0] - s1[0], s2[1] - s1[1], s2[2] - s1[2]
            return ob.Cost(self._floor_j_per_m * math.sqrt(dx * dx + dy * dy + dz * dz))

        def isSymmetric(self) -> bool:
            # with a current, a->b and b->a cost differently; planners must not reuse costs
            return self._symmetric

    return AuvEnergyObjective


# ------------------------------------------------------------------------- geometry

# The packed geometry the compiled checks read (:meth:`_World.geometry`): the volume's far
# corner first (where swiptopt.continuous._seabed_depth reads the extent), then the growth,
# the obstacle counts, and the obstacles (spheres as centre and squared grown radius, boxes
# as min and max corners).
G_GROW, G_LIFT, G_HAS_SEABED, G_SPHERES, G_BOXES, G_DATA = 3, 4, 5, 6, 7, 8


def _point_free(x, y, z, geom, seabed):  # type: ignore[no-untyped-def]
    """Whether (x, y, z) lies outside every obstacle grown by ``geom[G_GROW]`` (closed) and
    above the seabed raised by ``geom[G_LIFT]`` (:meth:`_World.geometry`). Plain Python over
    numpy arrays, compiled by numba (:func:`_checks`)."""
    grow = geom[G_GROW]
    k = G_DATA
    for _ in range(int(geom[G_SPHERES])):
        dx = x - geom[k]
        dy = y - geom[k + 1]
        dz = z - geom[k + 2]
        if dx * dx + dy * dy + dz * dz <= geom[k + 3]:
            return False
        k += 4
    grow2 = grow * grow
    for _ in range(int(geom[G_BOXES])):
        x0, y0, z0, x1, y1, z1 = geom[k], geom[k + 1], geom[k + 2], geom[k + 3], geom[k + 4], geom[k + 5]
        k += 6
        dx = x0 - x if x < x0 else (x - x1 if x > x1 else 0.0)
        if dx > grow:
            continue
        dy = y0 - y if y < y0 else (y - y1 if y > y1 else 0.0)
        dz = z0 - z if z < z0 else (z - z1 if z > z1 else 0.0)
        if dx * dx + dy * dy + dz * dz <= grow2:
            return False
    if geom[G_HAS_SEABED] == 1.0 and z >= _seabed_depth(geom, seabed, x, y) - geom[G_LIFT]:
        return False
    return True


def _segment_free(ax, ay, az, bx, by, bz, first, count, geom, seabed):  # type: ignore[no-untyped-def]
    """Whether the states ``a + (b - a) * (j / count)`` for j = ``first`` .. ``count`` are all
    free (:func:`_point_free`): OMPL's discrete motion check (``first = 1``: the start is
    known valid) in one call. The end is tested first, then the others coarse to fine (every
    2^m-th, then the odd multiples of each smaller power of two), so that a blocked motion
    is usually rejected after a few tests, as OMPL's bisection order does."""
    if not _point_free(bx, by, bz, geom, seabed):
        return False
    if first == 0 and not _point_free(ax, ay, az, geom, seabed):
        return False
    stride = 1
    while stride * 2 < count:
        stride *= 2
    step = stride
    while stride >= 1:
        j = stride
        while j < count:
            t = j / count
            if not _point_free(ax + (bx - ax) * t, ay + (by - ay) * t, az + (bz - az) * t, geom, seabed):
                return False
            j += step
        stride //= 2
        step = 2 * stride
    return True


_CHECKS: dict[str, Callable[..., bool]] = {}


def _checks() -> tuple[Callable[..., bool], Callable[..., bool]]:
    """(:func:`_point_free`, :func:`_segment_free`), compiled by numba when it is installed
    (against the continuous world's compiled seabed lookup), else the Python originals."""
    if not _CHECKS:
        from swiptopt.jit import numba_available

        functions = {"_point_free": _point_free, "_segment_free": _segment_free}
        if numba_available():
            from swiptopt import continuous
            from swiptopt.jit import compile_family

            functions = compile_family(functions, {"_seabed_depth": continuous.compiled("_seabed_depth")})
            # compile now, with the argument types of every call, not in a planner's time limit
            functions["_point_free"](0.0, 0.0, 0.0, np.zeros(G_DATA), np.zeros((0, 0)))
            functions["_segment_free"](0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0, 2, np.zeros(G_DATA), np.zeros((0, 0)))
        _CHECKS.update(functions)
    return _CHECKS["_point_free"], _CHECKS["_segment_free"]


@dataclass(frozen=True, eq=False)
class _Seabed:
    """A scenario's bilinear seabed: its height map and its depth function."""

    heights_m: np.ndarray
    """(hx, hy) height above the bottom on a regular grid over the area, m."""
    depth_m: Callable[[np.ndarray, np.ndarray], np.ndarray]
    """The scenario's own :meth:`Scenario.seabed_depth_m` (vectorised)."""
    stretch: float
    """sqrt(1 + slope^2) for a bound on the slope: a point delta above the seabed is at least
    delta / stretch away from it."""


def _seabed_of(scenario: Scenario) -> _Seabed | None:
    if scenario.seabed_height_m is None:
        return None
    h = np.asarray(scenario.seabed_height_m, dtype=float)
    nx, ny = h.shape
    dx, dy = scenario.length_m / (nx - 1), scenario.width_m / (ny - 1)
    gx, gy = np.meshgrid(np.arange(nx) * dx, np.arange(ny) * dy, indexing="ij")
    d = scenario.seabed_depth_m(gx, gy)  # depths at the grid nodes
    # |grad depth| <= slope inside every cell (bilinear: each partial is bounded by its edge
    # differences)
    slope = math.hypot(float(np.abs(np.diff(d, axis=0)).max()) / dx, float(np.abs(np.diff(d, axis=1)).max()) / dy)
    return _Seabed(np.ascontiguousarray(h), scenario.seabed_depth_m, math.sqrt(1.0 + slope * slope))


@dataclass(frozen=True)
class _World:
    """Bounds, obstacles and seabed: what the validity checks need."""

    low: tuple[float, float, float]
    high: tuple[float, float, float]
    obstacles: tuple[Box | Sphere, ...]
    seabed: _Seabed | None

    @property
    def diagonal_m(self) -> float:
        return math.dist(self.low, self.high)

    def smallest_obstacle_m(self) -> float:
        sizes = [
            2.0 * o.radius_m if isinstance(o, Sphere) else min(hi - lo for lo, hi in zip(o.min_m, o.max_m))
            for o in self.obstacles
        ]
        return min(sizes, default=math.inf)

    def names(self) -> list[str]:
        """What each column of :meth:`distances_m` measures the distance to."""
        names = [f"obstacles[{i}] = {o!r}" for i, o in enumerate(self.obstacles)]
        return names + (["the seabed"] if self.seabed is not None else [])

    def distances_m(self, points_m: np.ndarray) -> np.ndarray:
        """(m, len(names())) a lower bound on the distance from each point (m, 3) to each
        obstacle and the seabed, m; <= 0 means inside (or below the seabed)."""
        p = np.asarray(points_m, dtype=float).reshape(-1, 3)
        columns = []
        for o in self.obstacles:
            if isinstance(o, Sphere):
                columns.append(np.linalg.norm(p - np.asarray(o.center_m), axis=1) - o.radius_m)
                continue
            lo, hi = np.asarray(o.min_m, dtype=float), np.asarray(o.max_m, dtype=float)
            outside = np.maximum(np.maximum(lo - p, p - hi), 0.0)
            inside = np.minimum(p - lo, hi - p).min(axis=1)
            columns.append(np.where(outside.any(axis=1), np.linalg.norm(outside, axis=1), -inside))
        if self.seabed is not None:
            columns.append((self.seabed.depth_m(p[:, 0], p[:, 1]) - p[:, 2]) / self.seabed.stretch)
        return np.stack(columns, axis=1) if columns else np.zeros((len(p), 0))

    def geometry(self, grow_m: float) -> tuple[np.ndarray, np.ndarray]:
        """The packed arrays (geom, seabed heights) of the compiled checks, for the obstacles
        grown by ``grow_m`` and the seabed raised by ``grow_m`` times its stretch."""
        head = [*self.high, grow_m, 0.0, 0.0, 0.0, 0.0]
        spheres = [
            (*map(float, o.center_m), (o.radius_m + grow_m) ** 2) for o in self.obstacles if isinstance(o, Sphere)
        ]
        boxes = [(*map(float, o.min_m), *map(float, o.max_m)) for o in self.obstacles if isinstance(o, Box)]
        head[G_SPHERES], head[G_BOXES] = float(len(spheres)), float(len(boxes))
        heights = np.zeros((0, 0))
        if self.seabed is not None:
            head[G_LIFT], head[G_HAS_SEABED] = grow_m * self.seabed.stretch, 1.0
            heights = self.seabed.heights_m
        geom = np.array(head + [v for s in spheres for v in s] + [v for b in boxes for v in b], dtype=float)
        return geom, heights

    def free_fn(self, grow_m: float) -> Callable[[float, float, float], bool]:
        """A fast test of one point against the obstacles grown by ``grow_m`` (closed)."""
        point_free, _ = _checks()
        geom, heights = self.geometry(grow_m)

        def free(x: float, y: float, z: float) -> bool:
            return bool(point_free(float(x), float(y), float(z), geom, heights))

        return free


def _world_from(scenario_or_obstacles: Any, bounds: Any) -> tuple[_World, Scenario | None]:
    if isinstance(scenario_or_obstacles, Scenario):
        sc = scenario_or_obstacles
        if bounds is not None:
            raise ConfigError("bounds must be None with a Scenario: its volume gives the bounds", "bounds")
        return _World((0.0, 0.0, 0.0), (sc.length_m, sc.width_m, sc.depth_m), tuple(sc.obstacles), _seabed_of(sc)), sc
    try:
        obstacles = tuple(scenario_or_obstacles)
    except TypeError:
        kind = type(scenario_or_obstacles).__name__
        raise ConfigError(
            f"scenario_or_obstacles must be a Scenario or a sequence of Box/Sphere, got {kind}",
            "scenario_or_obstacles",
        ) from None
    for i, o in enumerate(obstacles):
        if not isinstance(o, (Box, Sphere)):
            raise ConfigError(f"obstacles[{i}] = {o!r} is not a Box or a Sphere", "scenario_or_obstacles")
    if bounds is None:
        raise ConfigError(
            "bounds=((xmin, ymin, zmin), (xmax, ymax, zmax)) is required with a list of obstacles", "bounds"
        )
    try:
        low, high = (tuple(float(v) for v in corner) for corner in bounds)
    except (TypeError, ValueError):
        raise ConfigError(f"bounds = {bounds!r} must be ((xmin, ymin, zmin), (xmax, ymax, zmax))", "bounds") from None
    well_formed = len(low) == 3 and len(high) == 3 and all(math.isfinite(v) for v in low + high)
    if not well_formed or not all(lo < hi for lo, hi in zip(low, high)):
        raise ConfigError(f"bounds = {bounds!r} must be two finite corners with min < max on every axis", "bounds")
    return _World(low, high, obstacles, None), None  # type: ignore[arg-type]


def _checked_point(name: str, point: Any, world: _World, clearance_m: float) -> tuple[float, float, float]:
    try:
        p = np.asarray(point, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} = {point!r} must be three numbers (x, y, depth)", name) from None
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ConfigError(f"{name} = {point!r} must be three finite numbers (x, y, depth)", name)
    xyz = (float(p[0]), float(p[1]), float(p[2]))
    if not all(lo <= v <= hi for v, lo, hi in zip(xyz, world.low, world.high)):
        raise ConfigError(f"{name} = {xyz} lies outside the bounds {world.low} .. {world.high}", name)
    for dist, what in zip(world.distances_m(p)[0], world.names()):
        if dist <= clearance_m:
            where = "inside" if dist <= 0 else f"within clearance_m = {clearance_m:g} m of"
            raise ConfigError(f"{name} = {xyz} lies {where} {what}", name)
    return xyz


def _check_spacing_m(world: _World, ends: dict[str, tuple[float, float, float]], clearance_m: float) -> float:
    """The motion-check spacing g (see the module docstring)."""
    default = CHECK_SPACING_FRACTION * world.diagonal_m
    spacing = min(default, SMALLEST_OBSTACLE_SHARE * world.smallest_obstacle_m())
    floor = MIN_SPACING_SHARE * default
    for name, point in ends.items():
        for dist, what in zip(world.distances_m(np.asarray(point))[0], world.names()):
            room = float(dist) - clearance_m  # > 0 after _checked_point
            if spacing / 2.0 >= room:
                if 1.8 * room < floor:
                    raise ConfigError(
                        f"{name} = {point} lies {room:.3g} m from {what}, closer than the smallest "
                        f"motion-check margin ({floor / 2:.3g} m); move it away",
                        name,
                    )
                spacing = 1.8 * room
    return spacing


def clearance_of_m(points_m: Any, scenario: Scenario, *, faces: bool = True) -> np.ndarray:
    """A lower bound on the distance from each point (..., 3) (x, y, depth) to the scenario's
    obstacles, its seabed and (with ``faces``) the faces of its volume, m (<= 0: inside an
    obstacle, below the seabed or outside the volume). Obstacles and seabed as
    :func:`plan_path_3d` sees them."""
    world, _ = _world_from(scenario, None)
    p = np.asarray(points_m, dtype=float)
    flat = p.reshape(-1, 3)
    out = np.full(len(flat), math.inf)
    if faces:
        out = np.minimum(flat - np.asarray(world.low), np.asarray(world.high) - flat).min(axis=1)
    distances = world.distances_m(flat)
    if distances.shape[1]:
        out = np.minimum(out, distances.min(axis=1))
    return out.reshape(p.shape[:-1])


def segments_free(starts_m: Any, ends_m: Any, scenario: Scenario, *, clearance_m: float = 0.0) -> np.ndarray:
    """Whether each straight segment (starts (m, 3) to ends (m, 3), metres) keeps at least
    ``clearance_m`` from every obstacle and the seabed and stays in the volume, (m,) bool.

    Checked as :func:`plan_path_3d` checks a motion (module docstring): states at most ``g``
    apart, tested against the obstacles grown by ``clearance_m + g / 2``, so no point between
    two tested states is missed, however thin the obstacle (``g`` is the planner's default
    spacing for the scenario). Both ends inside the volume keep the whole segment in it.
    """
    clearance_m = check_value("clearance_m", clearance_m, ARGUMENTS["clearance_m"])
    world, _ = _world_from(scenario, None)
    a = np.asarray(starts_m, dtype=float).reshape(-1, 3)
    b = np.asarray(ends_m, dtype=float).reshape(-1, 3)
    spacing = min(CHECK_SPACING_FRACTION * world.diagonal_m, SMALLEST_OBSTACLE_SHARE * world.smallest_obstacle_m())
    _, segment_free = _checks()
    geom, heights = world.geometry(clearance_m + spacing / 2.0)
    low, high = np.asarray(world.low), np.asarray(world.high)
    inside = np.all((a >= low) & (a <= high) & (b >= low) & (b <= high), axis=1)
    samples = np.maximum(1, np.ceil(np.linalg.norm(b - a, axis=1) / spacing)).astype(np.int64)
    out = np.zeros(len(a), dtype=bool)
    for n in np.flatnonzero(inside):
        out[n] = segment_free(*map(float, a[n]), *map(float, b[n]), 0, int(samples[n]), geom, heights)
    return out


# ------------------------------------------------------------------------- planning

_process_seed: int | None = None
_planned_unseeded = False


def _apply_seed(seed: int | None) -> None:
    """Set OMPL's process-wide seed once; refuse any other seed afterwards."""
    global _process_seed, _planned_unseeded
    if seed is None:
        if _process_seed is None:
            _planned_unseeded = True
        return
    if seed == _process_seed:
        return
    if _process_seed is not None:
        raise ConfigError(
            f"seed = {seed}: OMPL's seed is process-wide and was already set to {_process_seed} in this "
            "process; use the same seed, or a new process for another seed",
            "seed",
        )
    if _planned_unseeded:
        raise ConfigError(
            f"seed = {seed}: this process already planned without a seed, so OMPL has drawn random "
            "numbers and a seed set now would not make runs reproducible; pass the seed on the first call",
            "seed",
        )
    from ompl import util as ou

    ou.RNG.setSeed(seed)
    _process_seed = seed


def available_planners() -> tuple[str, ...]:
    """The names of :data:`PLANNERS` that the installed OMPL's Python bindings provide,
    less the :data:`CRASHING_PLANNERS`."""
    from ompl import geometric as og

    return tuple(name for name in PLANNERS if hasattr(og, name) and name not in CRASHING_PLANNERS)


def _choose_planner(planner: str | None, objective: str) -> str:
    name = DEFAULT_PLANNER[objective] if planner is None else planner
    available = available_planners()
    if name in CRASHING_PLANNERS:
        raise ConfigError(
            f"planner = {name!r} is refused: {CRASHING_PLANNERS[name]}; choose one of {', '.join(available)}",
            "planner",
        )
    if name not in available:
        raise ConfigError(f"planner = {name!r} is not available: choose one of {', '.join(available)}", "planner")
    if objective == "energy" and name in NO_PYTHON_OBJECTIVE_PLANNERS:
        raise ConfigError(
            f"planner = {name!r} cannot use objective='energy': it calls the (Python) objective from a "
            "second thread and deadlocks in OMPL's Python bindings; use e.g. InformedRRTstar or BITstar",
            "planner",
        )
    return name


def _counting_condition(budget: int) -> Any:
    """An OMPL termination condition that becomes true on its ``budget + 1``-th evaluation.

    OMPL's C++ ``IterationTerminationCondition`` is not in the Python bindings; a plain
    ``PlannerTerminationCondition`` over a counting callable is the same thing. It is built
    without a period, so OMPL evaluates it in the planner's thread at each check (a period
    would evaluate it from a timer thread, on the wall clock).
    """
    from ompl import base as ob

    calls = 0

    def spent() -> bool:
        nonlocal calls
        calls += 1
        return calls > budget

    return ob.PlannerTerminationCondition(spent)


def plan_path_3d(
    start: Sequence[float],
    goal: Sequence[float],
    scenario_or_obstacles: Scenario | Sequence[Box | Sphere],
    *,
    planner: str | None = None,
    time_limit_s: float = 0.5,
    objective: str = "length",
    seed: int | None = None,
    bounds: tuple[Sequence[float], Sequence[float]] | None = None,
    clearance_m: float = 0.0,
    simplify: bool = True,
    iterations: int | None = None,
) -> PathResult:
    """Plan a collision-free 3D path from ``start`` to ``goal`` with OMPL.

    Arguments:
        start, goal: (x, y, depth) in metres, inside the bounds and at least
            ``clearance_m`` outside every obstacle (else :class:`ConfigError` naming
            ``start``/``goal`` and the obstacle).
        scenario_or_obstacles: a :class:`Scenario` (its volume is the bounds; its boxes,
            spheres and seabed are obstacles) or a sequence of ``Box``/``Sphere`` with
            ``bounds``.
        planner: an OMPL planner name from :func:`available_planners`; ``None`` picks
            :data:`DEFAULT_PLANNER` (Informed RRT*). AORRTC is refused (it crashes the
            process, :data:`CRASHING_PLANNERS`) and PRM/PRM* cannot take the energy objective;
            RRTConnect, RRT and the KPIECEs ignore the objective except in simplification.
        time_limit_s: wall-clock limit of OMPL's solve, s (always set). Simplification may
            add at most ``SIMPLIFY_TIME_SHARE`` of it.
        objective: ``"length"``: OMPL's path length. ``"energy"`` (needs a Scenario): the
            sum over straight motions of :func:`segment_energy_j` (AUV at ground speed
            ``speed_mps``; propulsion power at the water-relative speed in the depth-varying
            current, Gauss-Legendre-averaged along the motion, plus hotel load, times
            travel time), as a Python ``OptimizationObjective`` with an admissible
            per-metre lower bound as its heuristic. With no current it is the length
            times a constant.
        seed: OMPL's random seed, set once per process, on the first call that passes one,
            before any unseeded call; a different seed, or a seed after an unseeded call,
            raises :class:`ConfigError` instead of reseeding (module docstring, Seeding).
        bounds: ((xmin, ymin, zmin), (xmax, ymax, zmax)) for an obstacle list; None with a
            Scenario.
        clearance_m: keep at least this distance from every obstacle, m.
        simplify: shortcut and smooth the path with OMPL's PathSimplifier (objective-aware);
            the result is kept only if it is valid and no worse under the objective.
        iterations: a deterministic budget instead of the wall clock (module docstring,
            Iteration budgets): the solve stops after this many planner iterations, the
            simplification after ``SIMPLIFY_ITERATION_SHARE`` of as many (at least one
            round), and ``time_limit_s`` is not used. ``None``: the wall-clock limit.

    Returns a :class:`PathResult`; no path within the limit is a status, not an exception.
    Sets OMPL's log level to ``LOG_NONE`` (process-wide) so that nothing prints.
    """
    time_limit_s = check_value("time_limit_s", time_limit_s, ARGUMENTS["time_limit_s"])
    clearance_m = check_value("clearance_m", clearance_m, ARGUMENTS["clearance_m"])
    iterations = check_value("iterations", iterations, ARGUMENTS["iterations"])
    seed = check_value("seed", seed, ARGUMENTS["seed"])
    objective = check_value("objective", objective, ARGUMENTS["objective"])
    name = _choose_planner(planner, objective)
    world, scenario = _world_from(scenario_or_obstacles, bounds)
    if objective == "energy" and scenario is None:
        raise ConfigError("objective='energy' needs a Scenario (the AUV and the current)", "objective")
    a = _checked_point("start", start, world, clearance_m)
    b = _checked_point("goal", goal, world, clearance_m)
    spacing = _check_spacing_m(world, {"start": a, "goal": b}, clearance_m)

    if a == b:
        waypoints = np.array([a])
        energy = 0.0 if scenario is not None else None
        return PathResult(waypoints, 0.0, True, "exact", name, objective, 0.0, 0.0, energy, spacing)

    from ompl import util as ou

    ou.setLogLevel(ou.LOG_NONE)
    _apply_seed(seed)
    ompl = _ompl_setup(world, scenario, name, objective, a, b, spacing, clearance_m)
    outcome, path, solve_time_s, simplify_time_s = _solve_and_simplify(ompl, a, time_limit_s, iterations, simplify)
    return _path_result(ompl, outcome, path, b, scenario, name, objective, solve_time_s, simplify_time_s, spacing)


@dataclass(eq=False)
class _OmplSetup:
    """An OMPL ``SimpleSetup`` ready to solve and its objective, with every Python object OMPL
    holds or calls back into (the space, the validity checker, the motion validator, the
    states), kept here so that they live as long as the setup is in use."""

    setup: Any
    cost: Any
    """The setup's ``OptimizationObjective``."""
    keep_alive: tuple[Any, ...]


def _ompl_setup(
    world: _World, scenario: Scenario | None, name: str, objective: str, a: tuple[float, float, float],
    b: tuple[float, float, float], spacing: float, clearance_m: float,
) -> _OmplSetup:
    """OMPL's idiom: a 3D ``RealVectorStateSpace`` over the bounds checking motions every
    ``spacing`` m, ``SimpleSetup`` with the validity checker (obstacles grown by
    ``clearance_m`` plus half the spacing), the compiled motion validator (except for
    :data:`LAST_VALID_PLANNERS`), start and goal, the objective and the planner."""
    from ompl import base as ob
    from ompl import geometric as og

    space = ob.RealVectorStateSpace(3)
    ompl_bounds = ob.RealVectorBounds(3)
    for axis in range(3):
        ompl_bounds.setLow(axis, world.low[axis])
        ompl_bounds.setHigh(axis, world.high[axis])
    space.setBounds(ompl_bounds)
    space.setLongestValidSegmentFraction(spacing / space.getMaximumExtent())

    setup = og.SimpleSetup(space)
    point_free, _ = _checks()
    geom, heights = world.geometry(clearance_m + spacing / 2.0)

    def is_valid(state: Any) -> bool:
        return point_free(state[0], state[1], state[2], geom, heights)

    setup.setStateValidityChecker(is_valid)
    si = setup.getSpaceInformation()
    validator = None
    if name not in LAST_VALID_PLANNERS:
        validator = _motion_validator_type()(si, space, geom, heights)
        si.setMotionValidator(validator)
    start_state, goal_state = space.allocState(), space.allocState()
    for axis in range(3):
        start_state[axis] = a[axis]
        goal_state[axis] = b[axis]
    setup.setStartAndGoalStates(start_state, goal_state)
    if objective == "energy":
        cost = _energy_objective_type()(si, scenario)
    else:
        cost = ob.PathLengthOptimizationObjective(si)
    setup.setOptimizationObjective(cost)
    setup.setPlanner(getattr(og, name)(si))
    return _OmplSetup(setup, cost, (space, ompl_bounds, is_valid, si, validator, start_state, goal_state))


def _solve_and_simplify(
    ompl: _OmplSetup, start: tuple[float, float, float], time_limit_s: float, iterations: int | None, simplify: bool
) -> tuple[Any, Any, float, float]:
    """Solve within the time limit or the iteration budget, then (with ``simplify``) keep the
    simplified path if it is usable and no worse: (OMPL's outcome, the usable path or None,
    the solve's and the simplification's wall-clock times, s)."""
    from ompl import geometric as og

    setup, cost = ompl.setup, ompl.cost
    t0 = time.perf_counter()
    outcome = setup.solve(time_limit_s if iterations is None else _counting_condition(iterations))
    solve_time_s = time.perf_counter() - t0
    path = _usable_path(setup, start)
    simplify_time_s = 0.0
    if path is not None and simplify:
        before = og.PathGeometric(path)
        t0 = time.perf_counter()
        if iterations is None:
            setup.simplifySolution(SIMPLIFY_TIME_SHARE * time_limit_s)
        else:
            setup.simplifySolution(_counting_condition(max(1, int(SIMPLIFY_ITERATION_SHARE * iterations))))
        simplify_time_s = time.perf_counter() - t0
        after = _usable_path(setup, start)
        if after is None or cost.isCostBetterThan(before.cost(cost), after.cost(cost)):
            path = before
        else:
            path = after
    return outcome, path, solve_time_s, simplify_time_s


def _path_result(
    ompl: _OmplSetup, outcome: Any, path: Any, goal: tuple[float, float, float], scenario: Scenario | None,
    name: str, objective: str, solve_time_s: float, simplify_time_s: float, spacing: float,
) -> PathResult:
    """The :class:`PathResult` of a solve: the path's waypoints, length and energy, or the
    status OMPL gave when there is no usable path."""
    if path is None:
        status = _STATUS_NAMES.get(outcome.getStatus().name, outcome.getStatus().name.lower())
        if status in ("exact", "approximate"):  # OMPL said so, but left no usable path
            status = "timeout"
        energy = math.inf if scenario is not None else None
        return PathResult(
            np.empty((0, 3)), math.inf, False, status, name, objective, solve_time_s, simplify_time_s, energy, spacing
        )

    waypoints = np.array([[s[0], s[1], s[2]] for s in path.getStates()])
    exact = bool(ompl.setup.haveExactSolutionPath()) and bool(np.array_equal(waypoints[-1], goal))
    length_m = float(np.linalg.norm(np.diff(waypoints, axis=0), axis=1).sum())
    energy = path_energy_j(waypoints, scenario) if scenario is not None else None
    return PathResult(
        waypoints, length_m, exact, "exact" if exact else "approximate", name, objective,
        solve_time_s, simplify_time_s, energy, spacing,
    )


def _usable_path(setup: Any, start: tuple[float, float, float]) -> Any:
    """The setup's solution path if it is a real path from the start that passes OMPL's own
    motion checks, else None. (A planner may leave a one-state "approximate" path holding only
    the goal on timeout; such paths are not reported as solutions.)"""
    if not setup.haveSolutionPath():
        return None
    path = setup.getSolutionPath()
    if path.getStateCount() < 2:
        return None
    first = path.getState(0)
    if (first[0], first[1], first[2]) != start or not path.check():
        return None
    return path
