"""The continuous world (docs/design.md, 'The two worlds'): the paper's model with the AUV at any 3D position.

Beside the paper's grid, the AUV here has a continuous position and each step commands a
move of at most ``speed_mps * step_duration_s`` (= the scenario's ``cell_size_m``, which in
this world is a step's reach, not a lattice) in any direction. A step moves along the
straight segment and stops just short of its first contact with an obstacle (boxes,
spheres), the seabed or the volume's boundary; a blocked move still costs the whole attempt,
as on the grid. Coverage, the link budget, data and energy for each node are computed from
the actual position every step, with the grid's rules (cone, range, SNR threshold, fading,
failures); propulsion energy comes from the speed through the water against the current at
the AUV's depth.

One step function, :func:`step`, serves the environment
(:class:`swiptopt.env_continuous.AuvSwiptContinuousEnv`) and every planner's executor: it
does the motion, finds the covered nodes, and hands them to :func:`swiptopt.kernel.serve`,
the very code that ends a grid step (serving, draws, idle drain, reward parts, episode end).
So with no obstacles and no current, from the grid's cell centres, an episode of grid moves
scores exactly what the grid scores (a test holds it to that, bit for bit). Like the grid
kernel, ``step`` is plain Python over numpy arrays that numba compiles unchanged
(:func:`compiled`).

Contact is exact for the boundary, boxes and spheres (slab and quadratic intersection). A
seabed height map is bilinear: along a segment its depth is piecewise quadratic, so contact
is found by sampling the segment every :data:`SEABED_SAMPLE_M` metres and bisecting the
first sample below the seabed. The AUV stops :data:`STOP_SHORT_M` before the contact point,
so it never touches a (closed) obstacle.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from swiptopt import acoustics
from swiptopt import kernel as K
from swiptopt.kernel import P_DT, P_NORMAL_ROWS, W_T, needs_refill, observation_at, serve
from swiptopt.link import noise_level_db, service_range_m, source_level_db
from swiptopt.scenario import Box, Scenario, Sphere

#: The action is a 3D command (x, y, depth) in [-1, 1]^3.
ACTION_DIM = 3
#: The AUV stops this far before the point where a move first touches something, m.
STOP_SHORT_M = 1e-6
#: Sample spacing of the seabed contact search along a move, m.
SEABED_SAMPLE_M = 0.25
#: Bisection steps after the first sample below the seabed (resolution 0.25 m / 2**40).
SEABED_BISECTIONS = 40


def describe_array(value: Any) -> str:
    """A short description of what was given where an array was expected (its dtype and
    shape, not its elements: an error message stays one short line)."""
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as exc:
        return f"{type(value).__name__} that is not an array ({type(exc).__name__})"
    if a.size <= 8 and a.dtype.kind in "biuf":
        return repr(a.tolist())
    return f"an array of dtype {a.dtype} and shape {a.shape}"


def real_actions(actions: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``actions`` as float64 of ``shape`` (each row x, y, depth); a one-line ValueError for
    anything else. Complex numbers are refused, never truncated to their real part. A
    one-dimensional ``shape`` takes any array of as many numbers (one env's action)."""
    try:
        a = np.asarray(actions)
    except (TypeError, ValueError):
        a = None
    fits = a is not None and (a.shape == shape or (len(shape) == 1 and a.size == shape[0]))
    if not fits or a.dtype.kind not in "biuf":
        raise ValueError(f"actions must be {shape} real numbers (x, y, depth) in [-1, 1], "
                         f"got {describe_array(actions)}")
    return a.astype(np.float64).reshape(shape)

# Indices into ``World.world``, the continuous world's scalar parameters.
(
    Q_EXT_X, Q_EXT_Y, Q_EXT_Z, Q_STEP_M, Q_SPEED, Q_DRAG, Q_BETA, Q_STATION_W,
    Q_CUR_TOP_X, Q_CUR_TOP_Y, Q_CUR_TOP_Z, Q_CUR_BOT_X, Q_CUR_BOT_Y, Q_CUR_BOT_Z,
    Q_TAN_CONE, Q_RANGE, Q_SL, Q_NL, Q_K10, Q_ABSORPTION, Q_DI_RX, Q_SNR_TH_DB, Q_SENSITIVITY,
    Q_LOAD, Q_ELEMENTS,
) = range(25)
N_WORLD = 25


@dataclass(frozen=True, eq=False)
class World:
    """Per-scenario arrays of the continuous world; built by :func:`build_world`.

    It has the fields of :class:`swiptopt.kernel.Tables` that the shared code reads
    (``params``, ``data0``, ``energy0``, ``capacity``, ``fail_prob``, ``n_nodes``,
    ``draws_uniforms``, ``normal_rows``), so the kernel's state, noise buffers and metrics
    serve both worlds.
    """

    world: np.ndarray
    """(N_WORLD,) float64 scalars, indexed by the ``Q_*`` constants."""
    boxes: np.ndarray
    """(n_boxes, 6): min corner, max corner (x, y, depth), m."""
    spheres: np.ndarray
    """(n_spheres, 4): centre (x, y, depth) and radius, m."""
    seabed: np.ndarray
    """(hx, hy) seabed height above the bottom on a regular grid over the area (bilinear), m;
    (0, 0) when flat."""
    nodes_m: np.ndarray
    """(n_nodes, 3) node positions, m."""
    data0: np.ndarray
    energy0: np.ndarray
    capacity: np.ndarray
    fail_prob: np.ndarray
    params: np.ndarray
    """(N_PARAMS,) the grid kernel's scalars (``swiptopt.kernel.P_*``), the same values."""
    start_m: np.ndarray
    """(3,) where episodes start: the centre of the scenario's start cell, m."""
    n_nodes: int
    draws_uniforms: bool
    normal_rows: int
    start_cell: int = 0
    """Unused (the kernel's state keeps a cell index; this world keeps a position)."""

    @property
    def extent_m(self) -> np.ndarray:
        return self.world[Q_EXT_X : Q_EXT_Z + 1].copy()

    @property
    def max_step_m(self) -> float:
        """The longest move of one step, m (``speed_mps * step_duration_s``)."""
        return float(self.world[Q_STEP_M])

    @property
    def speed_mps(self) -> float:
        return float(self.world[Q_SPEED])

    @property
    def step_duration_s(self) -> float:
        return float(self.params[K.P_DT])

    @functools.cached_property
    def named(self) -> K.Params:
        """:attr:`params` by name."""
        return K.named(self.params)


def build_world(scenario: Scenario) -> World:
    """The continuous world's arrays for ``scenario`` (its layout included)."""
    if scenario.technology != "acoustic":
        from swiptopt.errors import ConfigError

        raise ConfigError(
            f"technology = {scenario.technology!r} runs in the grid world only: the continuous world's "
            "compiled link is the acoustic one", "technology",
        )
    tables_params = K.scalar_params(scenario)
    top = np.asarray(scenario.current_mps, dtype=float)
    bottom = top if scenario.current_bottom_mps is None else np.asarray(scenario.current_bottom_mps, dtype=float)
    w = np.zeros(N_WORLD)
    w[Q_EXT_X : Q_EXT_Z + 1] = scenario.extent_m
    w[Q_STEP_M] = scenario.cell_size_m
    w[Q_SPEED] = scenario.speed_mps
    # the drag factor of auv.drag_force_n, in its order of operations: 0.5 C_D A rho_w
    w[Q_DRAG] = 0.5 * scenario.drag_coefficient * scenario.frontal_area_m2 * scenario.water_density_kg_m3
    w[Q_BETA] = scenario.propulsion_efficiency
    w[Q_STATION_W] = scenario.station_keeping_power_w
    w[Q_CUR_TOP_X : Q_CUR_TOP_Z + 1] = top
    w[Q_CUR_BOT_X : Q_CUR_BOT_Z + 1] = bottom
    w[Q_TAN_CONE] = math.tan(math.radians(scenario.cone_half_angle_deg))
    w[Q_RANGE] = scenario.cone_range_m
    w[Q_SL] = source_level_db(scenario)
    w[Q_NL] = noise_level_db(scenario)
    w[Q_K10] = float(np.asarray(scenario.spreading_k, dtype=float) * 10.0)
    w[Q_ABSORPTION] = float(acoustics.thorp_absorption_db_per_km(scenario.frequency_khz))
    w[Q_DI_RX] = scenario.directivity_rx_db
    w[Q_SNR_TH_DB] = scenario.snr_threshold_db
    w[Q_SENSITIVITY] = scenario.sensitivity_db
    w[Q_LOAD] = scenario.load_ohm
    w[Q_ELEMENTS] = float(scenario.n_elements)
    boxes = np.array(
        [[*o.min_m, *o.max_m] for o in scenario.obstacles if isinstance(o, Box)], dtype=float
    ).reshape(-1, 6)
    spheres = np.array(
        [[*o.center_m, o.radius_m] for o in scenario.obstacles if isinstance(o, Sphere)], dtype=float
    ).reshape(-1, 4)
    seabed = np.zeros((0, 0)) if scenario.seabed_height_m is None else np.asarray(scenario.seabed_height_m, dtype=float)
    start = np.asarray(scenario.cell_centers_m[scenario.start_cell_index], dtype=float).copy()
    return World(
        world=w,
        boxes=np.ascontiguousarray(boxes),
        spheres=np.ascontiguousarray(spheres),
        seabed=np.ascontiguousarray(seabed),
        start_m=start,
        normal_rows=int(tables_params[K.P_NORMAL_ROWS]),
        **_layout_fields(scenario, tables_params),
    )


def _layout_fields(scenario: Scenario, params: np.ndarray) -> dict:
    """The layout-dependent fields of :class:`World`, with the layout's targets in a copy of
    ``params``: fractions of what the coverable nodes hold, a node being coverable when some
    free position above it is within reach (:func:`coverable_nodes`)."""
    layout = scenario.layout
    params = params.copy()
    coverable = coverable_nodes(scenario)
    params[K.P_DATA_TARGET] = scenario.target_fraction * layout.data_bits[coverable].sum()
    storable_j = layout.capacity_j - layout.initial_energy_j
    params[K.P_ENERGY_TARGET] = scenario.target_fraction * storable_j[coverable].sum()
    params[K.P_DRAW_UNIFORMS] = float(np.any(layout.failure_prob > 0))
    return {
        "nodes_m": np.ascontiguousarray(layout.positions_m, dtype=float),
        "data0": layout.data_bits.astype(float),
        "energy0": layout.initial_energy_j.astype(float),
        "capacity": layout.capacity_j.astype(float),
        "fail_prob": layout.failure_prob.astype(float),
        "params": params,
        "n_nodes": scenario.n_nodes,
        "draws_uniforms": bool(params[K.P_DRAW_UNIFORMS]),
    }


#: Positions tested above each node by :func:`coverable_nodes`.
COVERABLE_SAMPLES = 64


def coverable_nodes(scenario: Scenario) -> np.ndarray:
    """(n_nodes,) bool: whether some free position covers the node. The best position for a
    node is straight above it (inside the cone, nearest for its depth), so a node is
    coverable when a free point above it lies within the reach min(cone range, service range)
    (tested at :data:`COVERABLE_SAMPLES` heights)."""
    nodes = np.asarray(scenario.layout.positions_m, dtype=float)
    reach = min(scenario.cone_range_m, service_range_m(scenario))
    if not reach > 0:
        return np.zeros(len(nodes), dtype=bool)
    rise = reach * np.arange(1, COVERABLE_SAMPLES + 1) / COVERABLE_SAMPLES  # (S,)
    points = np.repeat(nodes[:, None, :], COVERABLE_SAMPLES, axis=1)
    points[..., 2] = nodes[:, None, 2] - rise[None, :]
    ok = (points[..., 2] >= 0.0) & ~scenario.is_blocked(points)
    return ok.any(axis=1)


def with_layout(world: World, scenario: Scenario) -> World:
    """``world`` for ``scenario``'s layout (the same scenario otherwise)."""
    if scenario.n_nodes != world.n_nodes:
        raise ValueError(f"with_layout keeps n_nodes = {world.n_nodes}, got a scenario with {scenario.n_nodes}")
    return replace(world, **_layout_fields(scenario, world.params))


# ------------------------------------------------------------------ the compiled functions


def command(action, out):  # type: ignore[no-untyped-def]
    """The move an action commands, written to ``out`` (3,) as a fraction of the step's
    reach: each component clipped to [-1, 1], the vector scaled down to norm 1 if longer.
    Returns its norm (0: hover)."""
    for axis in range(3):
        a = float(action[axis])
        if a > 1.0:
            a = 1.0
        elif a < -1.0:
            a = -1.0
        elif not a == a:  # NaN: no command on this axis
            a = 0.0
        out[axis] = a
    norm = math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2])
    if norm > 1.0:
        for axis in range(3):
            out[axis] = out[axis] / norm
        norm = 1.0
    return norm


def propulsion_j(world, params, z, unit, norm):  # type: ignore[no-untyped-def]
    """Propulsion energy of one step commanding the ground velocity ``speed * unit`` from
    depth ``z``: the power of auv.propulsion_power_w at the speed through the water (against
    the current at that depth), plus station keeping when hovering, times the step's
    duration (the grid's propulsion table, for any velocity)."""
    speed = world[Q_SPEED]
    share = z / world[Q_EXT_Z]
    rel2 = 0.0
    for axis in range(3):
        top = world[Q_CUR_TOP_X + axis]
        current = top + (world[Q_CUR_BOT_X + axis] - top) * share
        rel = unit[axis] * speed - current
        rel2 += rel * rel
    v = math.sqrt(rel2)
    power = world[Q_DRAG] * (v * v) / world[Q_BETA] * v
    if norm == 0.0:
        power += world[Q_STATION_W]
    return power * params[P_DT]


def _seabed_depth(world, seabed, x, y):  # type: ignore[no-untyped-def]
    """Scenario.seabed_depth_m at one point (bilinear over the height map)."""
    hx = seabed.shape[0]
    hy = seabed.shape[1]
    if hx == 0:
        return world[Q_EXT_Z]
    gx = min(max(x / world[Q_EXT_X] * (hx - 1), 0.0), hx - 1.0)
    gy = min(max(y / world[Q_EXT_Y] * (hy - 1), 0.0), hy - 1.0)
    i0 = min(int(math.floor(gx)), hx - 2)
    j0 = min(int(math.floor(gy)), hy - 2)
    tx = gx - i0
    ty = gy - j0
    height = (
        seabed[i0, j0] * (1 - tx) * (1 - ty)
        + seabed[i0 + 1, j0] * tx * (1 - ty)
        + seabed[i0, j0 + 1] * (1 - tx) * ty
        + seabed[i0 + 1, j0 + 1] * tx * ty
    )
    return world[Q_EXT_Z] - height


# One function, not four: the continuous step's contact test, compiled with the step (_FUNCTIONS)
# and inlined into it, whose four tests narrow one ``hit`` in order (the seabed is sampled only
# up to the contact found so far); it reads best as one pass, and the continuous trace's
# reference digest (tests/swiptopt/test_cpu_paths.py) holds its operations as they are.
def first_contact(world, boxes, spheres, seabed, p, d):  # type: ignore[no-untyped-def]  # noqa: C901
    """The fraction t in [0, 1] of the move p -> p + d at which it first touches the
    volume's boundary, a box, a sphere or the seabed (1.0: it touches nothing on the way;
    0.0: it cannot start)."""
    hit = 1.0
    # leaving the volume [0, extent] on some axis
    for axis in range(3):
        if d[axis] > 0.0:
            hit = min(hit, (world[Q_EXT_X + axis] - p[axis]) / d[axis])
        elif d[axis] < 0.0:
            hit = min(hit, (0.0 - p[axis]) / d[axis])
    # boxes (closed): the slab method
    for b in range(boxes.shape[0]):
        enter = -math.inf
        leave = math.inf
        miss = False
        for axis in range(3):
            lo = boxes[b, axis]
            hi = boxes[b, 3 + axis]
            if d[axis] == 0.0:
                if p[axis] < lo or p[axis] > hi:
                    miss = True
            else:
                t1 = (lo - p[axis]) / d[axis]
                t2 = (hi - p[axis]) / d[axis]
                enter = max(enter, min(t1, t2))
                leave = min(leave, max(t1, t2))
        if not miss and enter <= leave and leave >= 0.0 and enter < hit:
            hit = max(enter, 0.0)
    # spheres (closed): the smaller root of |p + t d - c|^2 = r^2
    for s in range(spheres.shape[0]):
        a = 0.0
        half_b = 0.0
        c = -spheres[s, 3] * spheres[s, 3]
        for axis in range(3):
            rel = p[axis] - spheres[s, axis]
            a += d[axis] * d[axis]
            half_b += d[axis] * rel
            c += rel * rel
        if c <= 0.0:
            hit = 0.0
        elif a > 0.0:
            disc = half_b * half_b - a * c
            if disc >= 0.0:
                t = (-half_b - math.sqrt(disc)) / a
                if 0.0 <= t < hit:
                    hit = t
    # the seabed: first sample below it, then bisection
    if seabed.shape[0] > 0:
        length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        samples = max(1, int(math.ceil(length / SEABED_SAMPLE_M)))
        free_t = 0.0
        for k in range(1, samples + 1):
            t = hit * k / samples
            if p[2] + t * d[2] > _seabed_depth(world, seabed, p[0] + t * d[0], p[1] + t * d[1]):
                lo = free_t
                hi = t
                for _ in range(SEABED_BISECTIONS):
                    mid = 0.5 * (lo + hi)
                    if p[2] + mid * d[2] > _seabed_depth(world, seabed, p[0] + mid * d[0], p[1] + mid * d[1]):
                        hi = mid
                    else:
                        lo = mid
                hit = lo
                break
            free_t = t
    return hit


def move(world, boxes, spheres, seabed, pos, unit):  # type: ignore[no-untyped-def]
    """Move ``pos`` in place by the step's reach times ``unit``, stopping short of the first
    contact; returns whether the move was stopped short."""
    reach = world[Q_STEP_M]
    d = np.empty(3)
    for axis in range(3):
        d[axis] = unit[axis] * reach
    hit = first_contact(world, boxes, spheres, seabed, pos, d)
    if hit >= 1.0:
        for axis in range(3):
            pos[axis] = pos[axis] + d[axis]
        return False
    length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    t = max(0.0, hit - STOP_SHORT_M / length) if length > 0.0 else 0.0
    for axis in range(3):
        pos[axis] = pos[axis] + t * d[axis]
    return True


def cover(world, nodes_m, pos, cov_node, cov_snr, cov_pav):  # type: ignore[no-untyped-def]
    """The nodes covered from ``pos`` (ascending), their mean link SNR (linear) and available
    power (W), written to the first entries of the scratch arrays; returns how many.

    The grid's rule from the actual position, in the arithmetic of coverage._in_cone and
    link.link_budget: below the AUV inside the cone, within the cone's range, SNR at least
    the threshold (passive sonar equation, Thorp absorption; paper eqs. 1-4, 10-11).
    """
    count = 0
    for i in range(nodes_m.shape[0]):
        rx = nodes_m[i, 0] - pos[0]
        ry = nodes_m[i, 1] - pos[1]
        dz = nodes_m[i, 2] - pos[2]
        horizontal = np.hypot(rx, ry)
        slant = np.sqrt(horizontal * horizontal + dz * dz)
        if not (dz > 0.0 and horizontal <= dz * world[Q_TAN_CONE] and slant <= world[Q_RANGE]):
            continue
        distance = np.sqrt(rx * rx + ry * ry + dz * dz)
        r = max(distance, 1.0)
        tl = world[Q_K10] * math.log10(r) + (r / 1000.0) * world[Q_ABSORPTION]
        snr_db = world[Q_SL] - tl - world[Q_NL] + world[Q_DI_RX]
        if not snr_db >= world[Q_SNR_TH_DB]:
            continue
        volts = math.pow(10.0, (world[Q_SL] - tl + world[Q_SENSITIVITY]) / 20.0)
        cov_node[count] = i
        cov_snr[count] = math.pow(10.0, snr_db / 10.0)
        cov_pav[count] = world[Q_ELEMENTS] * (volts * volts) / (4.0 * world[Q_LOAD])
        count += 1
    return count


def step(  # type: ignore[no-untyped-def]
    action, uniforms, normals, world, boxes, spheres, seabed, nodes_m, cov_node, cov_snr, cov_pav,
    capacity, fail_prob, params, pos, where, data_left, energy, delivered, collected, acc, parts,
):
    """Advance the episode by one action (a (3,) command); returns (code, blocked).

    Command -> propulsion energy at the start depth -> straight move, stopped short of the
    first contact -> covered nodes from the new position -> :func:`swiptopt.kernel.serve`
    (serving with the step's draws, idle drain, reward parts, t += 1, episode end).
    """
    code, blocked, _ = advance(
        action, uniforms, normals, world, boxes, spheres, seabed, nodes_m, cov_node, cov_snr, cov_pav,
        capacity, fail_prob, params, pos, where, data_left, energy, delivered, collected, acc, parts,
    )
    return code, blocked


def advance(  # type: ignore[no-untyped-def]
    action, uniforms, normals, world, boxes, spheres, seabed, nodes_m, cov_node, cov_snr, cov_pav,
    capacity, fail_prob, params, pos, where, data_left, energy, delivered, collected, acc, parts,
):
    """:func:`step`, also returning how many nodes the new position covers (their indices
    first in ``cov_node``): (code, blocked, count)."""
    unit = np.empty(3)
    norm = command(action, unit)
    energy_j = propulsion_j(world, params, pos[2], unit, norm)
    blocked = False
    if norm > 0.0:
        blocked = move(world, boxes, spheres, seabed, pos, unit)
    count = cover(world, nodes_m, pos, cov_node, cov_snr, cov_pav)
    code = serve(
        energy_j, 0, count, uniforms, normals, cov_node, cov_snr, cov_pav, capacity, fail_prob, params, where,
        data_left, energy, delivered, collected, acc, parts,
    )
    return code, blocked, count


def step_observe(  # type: ignore[no-untyped-def]
    action, uniforms, normals, world, boxes, spheres, seabed, nodes_m, cov_node, cov_snr, cov_pav,
    capacity, fail_prob, params, pos, where, data_left, energy, delivered, collected, acc, parts,
    data0, nodes_norm, out,
):
    """:func:`step`, then the vector observation into ``out`` and whether the draw buffers
    need a refill; returns (code, blocked, refill), in one compiled call."""
    code, blocked, count = advance(
        action, uniforms, normals, world, boxes, spheres, seabed, nodes_m, cov_node, cov_snr, cov_pav,
        capacity, fail_prob, params, pos, where, data_left, energy, delivered, collected, acc, parts,
    )
    # the step's own coverage: the nodes served this step are those the observation flags
    observe_covered(world, pos, where, count, cov_node, data_left, energy, data0, capacity, params, nodes_norm, out)
    refill = needs_refill(where, capacity.shape[0], uniforms.shape[0], normals.shape[0], int(params[P_NORMAL_ROWS]))
    return code, blocked, refill


def observe(  # type: ignore[no-untyped-def]
    world, nodes_m, pos, where, cov_node, cov_snr, cov_pav, data_left, energy, data0, capacity, params, nodes_norm, out
):
    """The grid's vector observation (:func:`swiptopt.kernel.observation_at`) at the AUV's
    actual position, into ``out``."""
    count = cover(world, nodes_m, pos, cov_node, cov_snr, cov_pav)
    observe_covered(world, pos, where, count, cov_node, data_left, energy, data0, capacity, params, nodes_norm, out)


def observe_covered(  # type: ignore[no-untyped-def]
    world, pos, where, count, cov_node, data_left, energy, data0, capacity, params, nodes_norm, out
):
    """:func:`observe` given the covered nodes ``cov_node[:count]``."""
    auv_norm = np.empty(3)
    for axis in range(3):
        auv_norm[axis] = pos[axis] / world[Q_EXT_X + axis]
    observation_at(auv_norm, where[W_T], 0, count, cov_node, data_left, energy, data0, capacity, params,
                   nodes_norm, out)


_FUNCTIONS = ("command", "propulsion_j", "_seabed_depth", "first_contact", "move", "cover", "advance", "step",
              "observe_covered", "observe", "step_observe")
_COMPILED: dict[str, Callable] = {}


def compiled(name: str) -> Callable:
    """The numba-compiled version of one of this module's step functions (``"step"``,
    ``"step_observe"``, ...), compiled from the same source against the grid kernel's
    compiled ``serve`` and ``observation_at``."""
    if not _COMPILED:
        from swiptopt.jit import compile_family

        shared = {name: K.compiled(name) for name in ("serve", "observation_at", "needs_refill")}
        _COMPILED.update(compile_family({n: globals()[n] for n in _FUNCTIONS}, shared))
    return _COMPILED[name]


# ------------------------------------------------------------------ helpers for planners


def velocity_of(action: np.ndarray, speed_mps: float) -> np.ndarray:
    """The ground velocity (3,) m/s an action commands: ``speed_mps * a / max(1, |a|)``,
    each component of ``a`` clipped to [-1, 1] first."""
    unit = np.empty(3)
    command(np.asarray(action, dtype=float), unit)
    return unit * speed_mps


def action_towards(position_m: np.ndarray, target_m: np.ndarray, max_step_m: float) -> np.ndarray:
    """The action (float32 (3,)) that moves straight towards ``target_m``, arriving this step
    when it is within ``max_step_m``."""
    delta = (np.asarray(target_m, dtype=float) - np.asarray(position_m, dtype=float)) / max_step_m
    norm = math.sqrt(delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2])
    if norm > 1.0:
        delta = delta / norm
    return delta.astype(np.float32)


def travel_fraction(world: World, start_m: np.ndarray, end_m: np.ndarray) -> float:
    """How far along the straight segment start -> end a move gets before first touching the
    volume's boundary, an obstacle or the seabed, as a fraction (1.0: the whole way)."""
    p = np.asarray(start_m, dtype=float)
    d = np.asarray(end_m, dtype=float) - p
    return float(first_contact(world.world, world.boxes, world.spheres, world.seabed, p, d))


def coverage_at(world: World, position_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nodes covered from ``position_m`` (ascending indices), their mean link SNR
    (linear, before splitting) and available power (W), by the step's own rule."""
    n = world.n_nodes
    nodes, snr, pav = np.empty(n, dtype=np.int64), np.empty(n), np.empty(n)
    count = cover(world.world, world.nodes_m, np.asarray(position_m, dtype=float), nodes, snr, pav)
    return nodes[:count].copy(), snr[:count].copy(), pav[:count].copy()


def propulsion_energy_j(world: World, position_m: np.ndarray, velocity_mps: np.ndarray) -> float:
    """Propulsion energy of one step at ground velocity ``velocity_mps`` (its norm at most
    the cruise speed) from ``position_m``, J; hovering (velocity 0) adds station keeping.
    The hotel load, ``hotel_power_w * step_duration_s``, comes on top of every step."""
    v = np.asarray(velocity_mps, dtype=float)
    norm = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    unit = v / world.speed_mps
    return float(propulsion_j(world.world, world.params, float(position_m[2]), unit, norm))
