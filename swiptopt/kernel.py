"""The simulator kernel: the single source of truth for how the world moves (docs/design.md,
'The kernel's contract').

:func:`build_tables` precomputes, once per scenario, everything that does not change within
an episode: for each cell and action the next cell and the AUV's propulsion energy (with
the current), and for each cell the covered nodes with their mean SNR and available power.
:func:`step` then advances an :class:`EpisodeState` by one action, given the step's random
draws. ``step`` is plain Python over numpy arrays and scalars, written so that numba
compiles it unchanged (:func:`compiled_step`): the Gymnasium environment, the fast RL
trainer and the planners' plan executor all call this one function, so an agent and a
planner are scored by the same code.

Randomness never happens in here. The caller passes buffers of uniforms (link failures)
and normals (fading) filled by :func:`refill_noise` from the environment's generator; a
step reads the next few values for each covered node. The same seed and actions give the
same episode bit for bit, whichever path runs it.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from swiptopt import acoustics, auv, harvesting
from swiptopt.coverage import cell_coverage
from swiptopt.jit import compile_family, numba_available  # noqa: F401 (re-exported)
from swiptopt.link import auv_power, harvest_split, link_budget, reward_references, uplink_snr_offset_db
from swiptopt.scenario import Scenario

#: Actions: unit moves +x, -x, +y, -y, +z (deeper), -z, and hover.
N_ACTIONS = 7
HOVER = 6
ACTION_NAMES = ("+x", "-x", "+y", "-y", "+z (deeper)", "-z (shallower)", "hover")
ACTION_DELTAS = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [0, 0, 0]], dtype=np.int64
)

CHANNEL_CODES = {"none": 0, "shadowing": 1, "rician": 2}
LN10_OVER_10 = math.log(10.0) / 10.0

# Indices into the scalar parameter vector ``Tables.params``.
P_DT, P_BW, P_ALPHA, P_LOGISTIC, P_ETA, P_LMAX, P_LA, P_LB = range(8)
P_SNR_TH, P_CHANNEL, P_SIGMA_DB, P_RICIAN_K, P_GAMMA, P_LAMBDA = range(8, 14)
P_DATA_REF, P_ENERGY_REF, P_MOVE_REF, P_PROJECTOR_J, P_HOTEL_J = range(14, 19)
P_DRAIN_J, P_GATE_J, P_BATTERY_J, P_STEPS, P_DATA_TARGET, P_ENERGY_TARGET = range(19, 25)
P_DRAW_UNIFORMS, P_NORMAL_ROWS = range(25, 27)
P_LINK, P_UPLINK_SNR_GAIN, P_NODE_TX_W, P_NODE_CIRCUIT_W, P_PACKET_BITS = range(27, 32)
N_PARAMS = 32

class Params(NamedTuple):
    """The scenario's scalars by name: :func:`named` of a parameter vector (``Tables.params``,
    indexed by the ``P_*`` constants inside the compiled kernel). Callers outside the kernel
    read them here, by name; the values are the vector's own floats."""

    dt_s: float
    bandwidth_hz: float
    split_ratio: float
    """alpha: the share of the received signal sent to decoding (0 with the uplink)."""
    logistic: float
    """1.0 for the logistic harvester, 0.0 for the linear one."""
    efficiency: float
    logistic_max_w: float
    logistic_a_per_w: float
    logistic_b_w: float
    snr_threshold: float
    """Linear."""
    channel: float
    """:data:`CHANNEL_CODES`."""
    shadowing_sigma_db: float
    rician_k: float
    reward_weight: float
    """Gamma."""
    movement_weight: float
    """lambda."""
    data_ref_bits: float
    energy_ref_j: float
    move_ref_j: float
    projector_j: float
    """Projector energy of a step that covers a node, J."""
    hotel_j: float
    """Hotel energy of a step, J."""
    drain_j: float
    """Idle drain of a node per step, J."""
    gate_j: float
    battery_j: float
    steps: float
    """Episode length, steps."""
    data_target_bits: float
    energy_target_j: float
    draw_uniforms: float
    """1.0 when steps draw link-failure uniforms."""
    normal_rows: float
    """Fading normals per node and step."""
    link: float
    """:data:`LINK_CODES`."""
    uplink_snr_gain: float
    """Linear."""
    node_tx_w: float
    node_circuit_w: float
    packet_bits: float


def named(params: np.ndarray) -> Params:
    """The parameter vector ``params`` (N_PARAMS,) by name."""
    return Params._make(float(x) for x in params)


def replace_params(params: np.ndarray, **changes: float) -> np.ndarray:
    """A copy of the parameter vector with the named entries (:class:`Params` fields) changed."""
    out = np.array(params, dtype=float)
    for name, value in changes.items():
        out[Params._fields.index(name)] = value
    return out


#: ``params[P_LINK]`` of each data link.
LINK_CODES = {"downlink_split": 0, "uplink": 1}

# Indices into ``EpisodeState.acc``, the episode's running totals.
A_PROPULSION_J, A_HOTEL_J, A_PROJECTOR_J, A_BITS, A_JOULES, A_RETURN = range(6)
A_STEPS_DATA_TARGET, A_STEPS_ENERGY_TARGET, A_PROJECTOR_STEPS = range(6, 9)
A_COVERED_NODE_STEPS, A_NODE_TX_J = range(9, 11)
N_ACC = 11

# Indices into the reward-parts output of ``step``.
R_THROUGHPUT, R_HARVEST, R_MOVEMENT = range(3)
REWARD_PART_NAMES = ("throughput", "harvest", "movement")

# Indices into ``EpisodeState.where``.
W_CELL, W_T, W_UPTR, W_ZPTR = range(4)

# Return codes of ``step``.
RUNNING, TERMINATED, TRUNCATED = 0, 1, 2


@dataclass(frozen=True, eq=False)
class Tables:
    """Per-scenario arrays the kernel reads; built once by :func:`build_tables`."""

    next_cell: np.ndarray
    """(n_cells, 7) int64: cell after each action; the same cell when the move is blocked."""
    moved: np.ndarray
    """(n_cells, 7) bool: whether the action changes the cell."""
    propulsion_j: np.ndarray
    """(n_cells, 7): propulsion (moves) or station-keeping (hover) energy of each action, J."""
    cov_ptr: np.ndarray
    """(n_cells + 1,) int64: covered nodes of cell c are ``cov_node[cov_ptr[c]:cov_ptr[c+1]]``."""
    cov_node: np.ndarray
    """(nnz,) int64 node indices."""
    cov_snr: np.ndarray
    """(nnz,) mean link SNR (linear, before splitting) of each covered pair."""
    cov_pav: np.ndarray
    """(nnz,) mean available power at the node of each covered pair, W."""
    data0: np.ndarray
    """(n_nodes,) bits each node holds at the start."""
    energy0: np.ndarray
    """(n_nodes,) stored energy at the start, J."""
    capacity: np.ndarray
    """(n_nodes,) storage capacity, J."""
    fail_prob: np.ndarray
    """(n_nodes,) per-step link failure probability."""
    params: np.ndarray
    """(N_PARAMS,) float64 scalars, indexed by the ``P_*`` constants."""
    start_cell: int
    n_cells: int
    n_nodes: int
    draws_uniforms: bool
    """Whether a step needs link-failure draws (some failure probability > 0)."""
    normal_rows: int
    """Fading draws per node and step: 0 (no fading), 1 (shadowing) or 2 (Rician)."""

    @functools.cached_property
    def named(self) -> Params:
        """:attr:`params` by name."""
        return named(self.params)

    def covered(self, cell: int) -> np.ndarray:
        """Indices of the nodes covered from ``cell``."""
        return self.cov_node[self.cov_ptr[cell] : self.cov_ptr[cell + 1]]


def build_tables(scenario: Scenario) -> Tables:
    """Precompute the scenario's kernel tables (geometry, energies, coverage, constants)."""
    shape = scenario.grid_shape
    n_cells = scenario.n_cells
    cells = scenario.cell_of_index(np.arange(n_cells))  # (n_cells, 3)
    targets = cells[:, None, :] + ACTION_DELTAS[None, :, :]  # (n_cells, 7, 3)
    inside = np.all((targets >= 0) & (targets < np.asarray(shape)), axis=-1)
    clipped = np.clip(targets, 0, np.asarray(shape) - 1)
    target_index = np.where(inside, np.ravel_multi_index(tuple(clipped.transpose(2, 0, 1)), shape), 0)
    free = inside & ~scenario.blocked_cells[target_index]
    next_cell = np.where(free, target_index, np.arange(n_cells)[:, None]).astype(np.int64)
    moved = next_cell != np.arange(n_cells)[:, None]

    # Propulsion: the water-relative speed needed to hold the ground velocity in the current
    # at the cell's depth (a blocked move still costs the attempt). Hover holds
    # station against the current, plus any fixed station-keeping power.
    dt = scenario.step_duration_s
    current = scenario.current_at_mps(scenario.cell_centers_m[:, 2])  # (n_cells, 3)
    ground_velocity = ACTION_DELTAS[None, :, :] * scenario.speed_mps  # (1, 7, 3)
    water_speed = auv.water_relative_speed_mps(ground_velocity, current[:, None, :])
    prop_w = auv.propulsion_power_w(
        water_speed,
        scenario.drag_coefficient,
        scenario.frontal_area_m2,
        scenario.water_density_kg_m3,
        scenario.propulsion_efficiency,
    )
    prop_w[:, HOVER] += scenario.station_keeping_power_w
    propulsion_j = prop_w * dt

    params = scalar_params(scenario)

    return Tables(
        next_cell=next_cell,
        moved=moved,
        propulsion_j=propulsion_j,
        start_cell=scenario.start_cell_index,
        n_cells=n_cells,
        n_nodes=scenario.n_nodes,
        normal_rows=int(params[P_NORMAL_ROWS]),
        **layout_tables(scenario, params),
    )


def scalar_params(scenario: Scenario) -> np.ndarray:
    """The scenario's scalar parameters (``P_*``) that do not depend on the layout; the
    layout's entries (targets, whether steps draw failures) are set by :func:`layout_tables`.
    Both worlds read this one vector."""
    dt = scenario.step_duration_s
    refs = reward_references(scenario)
    power = auv_power(scenario)
    params = np.zeros(N_PARAMS)
    params[P_DT] = dt
    params[P_BW] = scenario.bandwidth_hz
    params[P_ALPHA] = harvest_split(scenario)
    params[P_LOGISTIC] = float(scenario.harvester == "logistic")
    params[P_ETA] = scenario.harvest_efficiency
    params[P_LMAX] = scenario.logistic_max_w
    params[P_LA] = scenario.logistic_a_per_w
    params[P_LB] = scenario.logistic_b_w
    params[P_SNR_TH] = float(acoustics.db_to_linear(scenario.snr_threshold_db))
    params[P_CHANNEL] = CHANNEL_CODES[scenario.channel]
    params[P_SIGMA_DB] = scenario.shadowing_sigma_db
    params[P_RICIAN_K] = scenario.rician_k
    params[P_GAMMA] = scenario.reward_weight
    params[P_LAMBDA] = scenario.movement_weight
    params[P_DATA_REF] = refs.data_ref_bits
    params[P_ENERGY_REF] = refs.energy_ref_j
    params[P_MOVE_REF] = refs.move_energy_ref_j
    params[P_PROJECTOR_J] = power.projector_energy_j
    params[P_HOTEL_J] = scenario.hotel_power_w * dt
    params[P_DRAIN_J] = scenario.idle_drain_w * dt
    params[P_GATE_J] = scenario.energy_gate_j
    params[P_BATTERY_J] = scenario.battery_j
    params[P_STEPS] = scenario.episode_steps
    params[P_NORMAL_ROWS] = {"none": 0, "shadowing": 1, "rician": 2}[scenario.channel]
    params[P_LINK] = LINK_CODES[scenario.link]
    params[P_UPLINK_SNR_GAIN] = float(acoustics.db_to_linear(uplink_snr_offset_db(scenario)))
    params[P_NODE_TX_W] = scenario.node_transmit_power_w
    params[P_NODE_CIRCUIT_W] = scenario.node_circuit_power_w
    params[P_PACKET_BITS] = scenario.packet_bits
    return params


#: The fields of :class:`Tables` that depend on the node layout (positions, charges, failure
#: probabilities); :func:`layout_tables` computes them.
LAYOUT_FIELDS = (
    "cov_ptr", "cov_node", "cov_snr", "cov_pav", "data0", "energy0", "capacity", "fail_prob", "params",
    "draws_uniforms",
)


def layout_tables(scenario: Scenario, params: np.ndarray) -> dict:
    """The layout-dependent fields of :class:`Tables` (:data:`LAYOUT_FIELDS`) for
    ``scenario.layout``: the coverage of every cell, the per-node arrays, and a copy of
    ``params`` with its layout-dependent entries (the data and energy targets, whether a step
    draws link failures) set.

    :func:`build_tables` calls it once; :func:`with_layout` calls it alone when only the layout
    changes (the grid, the moves and their energies stay).
    """
    n_cells = scenario.n_cells
    layout = scenario.layout
    # Coverage: cone, range and mean SNR threshold from each free cell's centre, as the
    # covered pairs only (memory grows with them, not with cells x nodes).
    pairs = cell_coverage(scenario)
    rows, nodes = pairs.rows, pairs.nodes
    budget = link_budget(scenario, pairs.distance_m)
    cov_ptr = np.zeros(n_cells + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=n_cells), out=cov_ptr[1:])

    params = params.copy()
    # targets are fractions of what can be collected at all: nodes no cell covers never count
    coverable = np.zeros(scenario.n_nodes, dtype=bool)
    coverable[nodes] = True
    params[P_DATA_TARGET] = scenario.target_fraction * layout.data_bits[coverable].sum()
    params[P_ENERGY_TARGET] = scenario.target_fraction * (layout.capacity_j - layout.initial_energy_j)[coverable].sum()
    params[P_DRAW_UNIFORMS] = float(np.any(layout.failure_prob > 0))
    return {
        "cov_ptr": cov_ptr,
        "cov_node": nodes.astype(np.int64),
        "cov_snr": acoustics.db_to_linear(budget.snr_db),
        "cov_pav": np.asarray(budget.available_power_w, dtype=float),
        "data0": layout.data_bits.astype(float),
        "energy0": layout.initial_energy_j.astype(float),
        "capacity": layout.capacity_j.astype(float),
        "fail_prob": layout.failure_prob.astype(float),
        "params": params,
        "draws_uniforms": bool(params[P_DRAW_UNIFORMS]),
    }


def with_layout(tables: Tables, scenario: Scenario) -> Tables:
    """``tables`` for ``scenario``'s layout, rebuilding only :data:`LAYOUT_FIELDS`.

    ``scenario`` must differ from the one ``tables`` were built for only in its layout
    (``layout_seed`` or ``node_positions_m``, with the same ``n_nodes``).
    """
    if scenario.n_nodes != tables.n_nodes:
        raise ValueError(f"with_layout keeps n_nodes = {tables.n_nodes}, got a scenario with {scenario.n_nodes}")
    return dataclasses.replace(tables, **layout_tables(scenario, tables.params))


@dataclass(eq=False)
class EpisodeState:
    """The mutable state of one episode; :func:`new_state` makes a fresh one."""

    where: np.ndarray
    """(4,) int64: current cell, step count t, and the read positions in the uniform and
    normal draw buffers (``W_*`` constants)."""
    data_left: np.ndarray
    """(n_nodes,) bits still to deliver."""
    energy: np.ndarray
    """(n_nodes,) stored energy, J."""
    delivered: np.ndarray
    """(n_nodes,) energy delivered to each node so far, J."""
    collected: np.ndarray
    """(n_nodes,) bits collected from each node so far."""
    acc: np.ndarray
    """(N_ACC,) running totals, indexed by the ``A_*`` constants."""
    parts: np.ndarray = field(default_factory=lambda: np.zeros(3))
    """(3,) the last step's reward parts (throughput, harvest, movement)."""

    @property
    def cell(self) -> int:
        return int(self.where[0])

    @property
    def t(self) -> int:
        return int(self.where[1])

    def copy(self) -> EpisodeState:
        fields = ("where", "data_left", "energy", "delivered", "collected", "acc", "parts")
        return EpisodeState(*(np.copy(getattr(self, f)) for f in fields))


def new_state(tables: Tables) -> EpisodeState:
    """The state at the start of an episode (the AUV in its start cell, t = 0)."""
    state = EpisodeState(
        where=np.zeros(4, dtype=np.int64),
        data_left=np.empty(tables.n_nodes),
        energy=np.empty(tables.n_nodes),
        delivered=np.empty(tables.n_nodes),
        collected=np.empty(tables.n_nodes),
        acc=np.empty(N_ACC),
    )
    reset_state(tables.start_cell, tables.data0, tables.energy0, tables.params, *_state_arrays(state))
    state.where[W_UPTR] = state.where[W_ZPTR] = 2**62  # no draws yet: the first step refills
    return state


def _state_arrays(state: EpisodeState) -> tuple:
    return (state.where, state.data_left, state.energy, state.delivered, state.collected, state.acc, state.parts)


def reset_state(start_cell, data0, energy0, params, where, data_left, energy, delivered, collected, acc, parts):  # type: ignore[no-untyped-def]
    """Rewrite the state arrays in place to the start of an episode.

    The draw positions are kept: an unseeded reset goes on reading the same buffers (a
    seeded one starts from :func:`new_state`, with fresh draws).
    """
    where[W_CELL] = start_cell
    where[W_T] = 0
    data_left[:] = data0
    energy[:] = energy0
    delivered[:] = 0.0
    collected[:] = 0.0
    acc[:] = 0.0
    parts[:] = 0.0
    acc[A_STEPS_DATA_TARGET] = 0.0 if params[P_DATA_TARGET] <= 0 else -1.0
    acc[A_STEPS_ENERGY_TARGET] = 0.0 if params[P_ENERGY_TARGET] <= 0 else -1.0


def buffer_sizes(tables: Tables, n_auvs: int = 1) -> tuple[int, int]:
    """Lengths of the uniform and the normal draw buffers of a scenario, with room for
    ``n_auvs`` AUVs (a fleet, :mod:`swiptopt.fleet`) to cover every node in one step."""
    n = max(1024, 8 * tables.n_nodes * n_auvs)
    return n, n * max(1, tables.normal_rows)


def noise_buffers(tables: Tables, n_auvs: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Empty draw buffers (uniforms, normals) for ``n_auvs`` AUVs; :func:`new_state` marks
    them as used up."""
    n_u, n_z = buffer_sizes(tables, n_auvs)
    return np.ones(n_u), np.zeros(n_z)


def refill_noise(
    rng: np.random.Generator, tables: Tables, uniforms: np.ndarray, normals: np.ndarray, where: np.ndarray
) -> None:
    """Refill both draw buffers from ``rng`` (all uniforms, then all normals) and rewind.

    A step consumes, for each covered node in order, one uniform (link failure; only when
    some failure probability is positive) and ``normal_rows`` normals (fading; only for a
    stochastic channel). The caller refills whenever :func:`step` returned
    a refill flag (see :func:`needs_refill`). Draws left at the end of an episode serve the
    next one; a seeded reset starts afresh. The compiled trainer draws the same numbers in the same order from the same
    generator (numba's Generator matches numpy's bit for bit), so the same seed and actions
    give the same episode, bit for bit, on either path.
    """
    if tables.draws_uniforms:
        rng.random(out=uniforms)
    if tables.normal_rows:
        rng.standard_normal(out=normals)
    where[W_UPTR] = 0
    where[W_ZPTR] = 0


def needs_refill(where, n_nodes, n_uniforms, n_normals, normal_rows):  # type: ignore[no-untyped-def]
    """Whether fewer draws are left than the next step could use (every node covered)."""
    return where[W_UPTR] + n_nodes > n_uniforms or where[W_ZPTR] + n_nodes * normal_rows > n_normals


def is_served(data_left, energy, capacity, gamma, i):  # type: ignore[no-untyped-def]
    """Node i needs nothing more: data delivered, and storage full unless Gamma = 1."""
    if data_left[i] > 0.0:
        return False
    return gamma >= 1.0 or energy[i] >= capacity[i] * (1.0 - 1e-12)


def served_mask(data_left, energy, capacity, gamma):  # type: ignore[no-untyped-def]
    """:func:`is_served` for every node at once, (n_nodes,) bool (numpy; for metrics and
    planners, which look at all nodes; a test holds it to :func:`is_served`)."""
    return ~(data_left > 0.0) & ((gamma >= 1.0) | (energy >= capacity * (1.0 - 1e-12)))


def unserved_covered(cell, cov_ptr, cov_node, data_left, energy, capacity, gamma):  # type: ignore[no-untyped-def]
    """Number of nodes covered from ``cell`` that still need data or energy."""
    count = 0
    for p in range(cov_ptr[cell], cov_ptr[cell + 1]):
        if not is_served(data_left, energy, capacity, gamma, cov_node[p]):
            count += 1
    return count


def all_served(data_left, energy, capacity, gamma):  # type: ignore[no-untyped-def]
    for i in range(data_left.shape[0]):
        if not is_served(data_left, energy, capacity, gamma, i):
            return False
    return True


#: The tabular observation caps the count of covered nodes still to serve at this value.
TABULAR_COUNT_CAP = 3


def tabular_observation(cell, cov_ptr, cov_node, data_left, energy, capacity, gamma):  # type: ignore[no-untyped-def]
    """The tabular state, the paper's (Section III-B) made finite: cell * 4 + min(covered nodes still to serve, 3)."""
    count = unserved_covered(cell, cov_ptr, cov_node, data_left, energy, capacity, gamma)
    return cell * (TABULAR_COUNT_CAP + 1) + min(count, TABULAR_COUNT_CAP)


#: Features per node in the vector observation: position relative to the AUV (x, y, depth),
#: data left, state of charge, covered now.
VECTOR_NODE_FEATURES = 6


def vector_observation(  # type: ignore[no-untyped-def]
    cell, t, cov_ptr, cov_node, data_left, energy, data0, capacity, params, cells_norm, nodes_norm, out
):
    """The vector observation, written into ``out`` ((4 + 6 n_nodes,) float32).

    The AUV's cell centre over the volume's extent (``cells_norm`` (n_cells, 3)), the
    fraction of the episode left, then per node: its position minus the AUV's over the
    extent (``nodes_norm`` (n_nodes, 3)), the fraction of its data left, its state of charge
    and 1.0 if covered from ``cell`` (:func:`observation_at`, which the continuous world
    calls with the AUV's actual position).
    """
    observation_at(
        cells_norm[cell], t, cov_ptr[cell], cov_ptr[cell + 1], cov_node, data_left, energy, data0, capacity, params,
        nodes_norm, out,
    )


def observation_at(  # type: ignore[no-untyped-def]
    auv_norm, t, start, stop, cov_node, data_left, energy, data0, capacity, params, nodes_norm, out
):
    """The vector observation of an AUV at ``auv_norm`` (its position over the extent, (3,))
    covering the nodes ``cov_node[start:stop]``, written into ``out``. Whole-array ufuncs
    writing straight into ``out`` (no temporaries), so that numpy runs it fast in Python and
    numba compiles it unchanged."""
    n = data_left.shape[0]
    for axis in range(3):
        out[axis] = auv_norm[axis]
    out[3] = 1.0 - t / params[P_STEPS]
    per_node = out[4:].reshape((n, VECTOR_NODE_FEATURES))
    for axis in range(3):
        np.subtract(nodes_norm[:, axis], auv_norm[axis], per_node[:, axis])
    np.divide(data_left, data0, per_node[:, 3])
    np.divide(energy, capacity, per_node[:, 4])
    per_node[:, 5] = 0.0
    for p in range(start, stop):
        per_node[cov_node[p], 5] = 1.0


def step_tabular(action, uniforms, normals, arrays):  # type: ignore[no-untyped-def]
    """:func:`step`, then the tabular observation and whether the draw buffers need a
    refill before the next step; returns (code, observation, refill)."""
    code = step(action, uniforms, normals, arrays)
    obs = tabular_observation(
        arrays.where[W_CELL], arrays.cov_ptr, arrays.cov_node, arrays.data_left, arrays.energy, arrays.capacity,
        arrays.params[P_GAMMA],
    )
    refill = needs_refill(
        arrays.where, arrays.capacity.shape[0], uniforms.shape[0], normals.shape[0], int(arrays.params[P_NORMAL_ROWS])
    )
    return code, obs, refill


def step_vector(action, uniforms, normals, arrays, data0, cells_norm, nodes_norm, out):  # type: ignore[no-untyped-def]
    """:func:`step`, then the vector observation into ``out`` (:func:`vector_observation`);
    returns (code, refill) as :func:`step_tabular` does, in one compiled call."""
    code = step(action, uniforms, normals, arrays)
    where = arrays.where
    vector_observation(
        where[W_CELL], where[W_T], arrays.cov_ptr, arrays.cov_node, arrays.data_left, arrays.energy, data0,
        arrays.capacity, arrays.params, cells_norm, nodes_norm, out,
    )
    refill = needs_refill(
        where, arrays.capacity.shape[0], uniforms.shape[0], normals.shape[0], int(arrays.params[P_NORMAL_ROWS])
    )
    return code, refill


def step(action, uniforms, normals, arrays):  # type: ignore[no-untyped-def]
    """Advance the episode by one action on ``arrays`` (:class:`StepArrays`) with the
    step's draws ``uniforms`` and ``normals``; returns RUNNING, TERMINATED or TRUNCATED.

    Move (blocked moves stay put and still cost the attempt) -> nodes covered from the new
    cell -> per covered node, with its next draws from the buffers (a failure uniform, the
    fading normals) giving this step's fading gain g, by the scenario's data link:

    - ``downlink_split``: data min(D_left, dt B log2(1 + alpha g SNR)) unless the link
      fails, the instantaneous SNR is under the threshold, or the node's energy is under
      the gate; then energy min(E_cap - E, dt P_h((1 - alpha) g P_av));
    - ``uplink``: first energy min(E_cap - E, dt P_h(g P_av)) (alpha = 0: all of the AUV's
      signal charges the node), then, unless the link fails or the node is under the gate,
      the node sends at its own SNR g SNR_up (the same fading draw: reciprocity) whole
      packets of L bits, each taking L / R s on air and (P_i + P_C) L / R J from its
      storage: as many as fit the step, its stored energy pays for and its data needs
      (the last packet padded); none when SNR_up is under the threshold;

    -> idle drain -> reward parts -> t += 1.
    The reward's movement part counts propulsion and hotel energy; the projector's energy
    (on in any step with a covered node) is counted in the totals, not the reward.
    """
    a = arrays
    cell = a.where[W_CELL]
    new_cell = a.next_cell[cell, action]
    a.where[W_CELL] = new_cell
    return serve(
        a.propulsion_j[cell, action], a.cov_ptr[new_cell], a.cov_ptr[new_cell + 1], uniforms, normals, a.cov_node,
        a.cov_snr, a.cov_pav, a.capacity, a.fail_prob, a.params, a.where, a.data_left, a.energy, a.delivered,
        a.collected, a.acc, a.parts,
    )


def serve(  # type: ignore[no-untyped-def]
    propulsion_j, start, stop, uniforms, normals, cov_node, cov_snr, cov_pav, capacity, fail_prob, params,
    where, data_left, energy, delivered, collected, acc, parts,
):
    """The rest of a step once the AUV has moved, whichever world it moves in: the
    propulsion energy ``propulsion_j`` of the move (plus the hotel load) is counted, the
    covered pairs ``cov_node[start:stop]`` (with their mean SNR and available power) are
    served with the step's draws (:func:`serve_pairs`), then idle drain, reward parts,
    t += 1 and the end of the episode (:func:`finish_step`), as :func:`step` documents. The
    grid's :func:`step` and the continuous world's step (:mod:`swiptopt.continuous`) both end
    here, so the two worlds share every rule after the motion; a fleet's step
    (:mod:`swiptopt.fleet`) calls the same two parts, once per AUV and once per step."""
    bits_total, joules_total = serve_pairs(
        propulsion_j, start, stop, uniforms, normals, cov_node, cov_snr, cov_pav, capacity, fail_prob, params,
        where, data_left, energy, delivered, collected, acc,
    )
    exhausted = acc[A_PROPULSION_J] + acc[A_HOTEL_J] + acc[A_PROJECTOR_J] >= params[P_BATTERY_J]
    return finish_step(
        bits_total, joules_total, propulsion_j + params[P_HOTEL_J], exhausted, params, where, data_left, energy,
        capacity, acc, parts,
    )


# One function on purpose, over its complexity and length limits: one AUV's part of a step,
# which numba compiles with the step (_KERNEL_FUNCTIONS) and which the Python reference runs
# from the same source. One pass over the covered pairs applies the model's rules in their
# order (fading, decoding, harvesting, the uplink); helpers would scatter that order, which
# the kernel traces' reference digests (tests/swiptopt/test_cpu_paths.py) hold to the last
# bit, across the grid and the continuous worlds that both end here.
def serve_pairs(  # type: ignore[no-untyped-def]  # noqa: C901
    propulsion_j, start, stop, uniforms, normals, cov_node, cov_snr, cov_pav, capacity, fail_prob, params,
    where, data_left, energy, delivered, collected, acc,
):
    """One AUV's share of a step: its move's propulsion energy ``propulsion_j`` and the
    hotel load are counted in ``acc``, then the pairs it covers, ``cov_node[start:stop]``, are
    served with the next draws of the buffers (read at ``where``'s positions), as
    :func:`step` documents; returns (bits collected, joules delivered) in the step."""
    dt = params[P_DT]
    acc[A_PROPULSION_J] += propulsion_j
    acc[A_HOTEL_J] += params[P_HOTEL_J]

    channel = params[P_CHANNEL]
    alpha = params[P_ALPHA]
    uplink = params[P_LINK] == 1.0
    draw_u = params[P_DRAW_UNIFORMS] == 1.0
    rows = int(params[P_NORMAL_ROWS])
    bits_total = 0.0
    joules_total = 0.0
    if stop > start:
        acc[A_PROJECTOR_J] += params[P_PROJECTOR_J]
        acc[A_PROJECTOR_STEPS] += 1.0
        acc[A_COVERED_NODE_STEPS] += stop - start
    for p in range(start, stop):
        i = cov_node[p]
        u = 1.0  # never fails
        if draw_u:
            u = uniforms[where[W_UPTR]]
            where[W_UPTR] += 1
        z = where[W_ZPTR]
        where[W_ZPTR] += rows
        if channel == 1.0:
            # 10^(sigma z / 10) as exp(): libm's exp is much cheaper than pow
            gain = math.exp(params[P_SIGMA_DB] * LN10_OVER_10 * normals[z])
        elif channel == 2.0:
            k = params[P_RICIAN_K]
            los = np.sqrt(k / (k + 1.0))
            scatter = np.sqrt(0.5 / (k + 1.0))
            re = los + scatter * normals[z]
            im = scatter * normals[z + 1]
            gain = re * re + im * im
        else:
            gain = 1.0
        snr = gain * cov_snr[p]
        if (
            not uplink
            and data_left[i] > 0.0
            and u >= fail_prob[i]
            and snr >= params[P_SNR_TH]
            and energy[i] >= params[P_GATE_J]
        ):
            bits = min(data_left[i], dt * _shannon_rate_bps(params[P_BW], alpha * snr))
            data_left[i] -= bits
            collected[i] += bits
            bits_total += bits
        room = capacity[i] - energy[i]
        if room > 0.0:
            p_h = _harvest_from_input_w(
                (1.0 - alpha) * gain * cov_pav[p],
                params[P_LOGISTIC] == 1.0,
                params[P_ETA],
                params[P_LMAX],
                params[P_LA],
                params[P_LB],
            )
            joules = min(room, dt * p_h)
            energy[i] += joules
            delivered[i] += joules
            joules_total += joules
        if (
            uplink
            and data_left[i] > 0.0
            and u >= fail_prob[i]
            and energy[i] >= params[P_GATE_J]
        ):
            snr_up = snr * params[P_UPLINK_SNR_GAIN]
            if snr_up >= params[P_SNR_TH]:
                packet = params[P_PACKET_BITS]
                airtime = packet / _shannon_rate_bps(params[P_BW], snr_up)
                cost = (params[P_NODE_TX_W] + params[P_NODE_CIRCUIT_W]) * airtime
                packets = min(
                    math.floor(dt / airtime), math.floor(energy[i] / cost), math.ceil(data_left[i] / packet)
                )
                if packets > 0:
                    bits = min(data_left[i], packets * packet)
                    spent = packets * cost
                    energy[i] = max(0.0, energy[i] - spent)
                    acc[A_NODE_TX_J] += spent
                    data_left[i] -= bits
                    collected[i] += bits
                    bits_total += bits
    return bits_total, joules_total


def reward_parts(bits, joules, move_j, params, parts):  # type: ignore[no-untyped-def]
    """Write the reward's three weighted parts (paper eq. 23, normalised) of ``bits``
    collected, ``joules`` delivered and ``move_j`` of propulsion and hotel energy into
    ``parts`` (throughput, harvest, movement)."""
    gamma = params[P_GAMMA]
    parts[R_THROUGHPUT] = gamma * bits / params[P_DATA_REF]
    parts[R_HARVEST] = (1.0 - gamma) * joules / params[P_ENERGY_REF]
    parts[R_MOVEMENT] = -params[P_LAMBDA] * move_j / params[P_MOVE_REF]


def finish_step(  # type: ignore[no-untyped-def]
    bits_total, joules_total, move_j, exhausted, params, where, data_left, energy, capacity, acc, parts
):
    """The end of a step, after every AUV has served (:func:`serve_pairs`): idle drain, the
    reward parts of ``bits_total`` collected, ``joules_total`` delivered and ``move_j`` of
    propulsion and hotel energy, the running totals, t += 1; returns TERMINATED when
    ``exhausted`` (no battery left to go on) or every node is served, TRUNCATED at the
    episode's length, else RUNNING."""
    gamma = params[P_GAMMA]
    if params[P_DRAIN_J] > 0.0:
        for i in range(energy.shape[0]):
            energy[i] = max(0.0, energy[i] - params[P_DRAIN_J])

    reward_parts(bits_total, joules_total, move_j, params, parts)
    acc[A_BITS] += bits_total
    acc[A_JOULES] += joules_total
    acc[A_RETURN] += parts[R_THROUGHPUT] + parts[R_HARVEST] + parts[R_MOVEMENT]
    where[W_T] += 1
    t = where[W_T]
    if acc[A_STEPS_DATA_TARGET] < 0.0 and acc[A_BITS] >= params[P_DATA_TARGET]:
        acc[A_STEPS_DATA_TARGET] = t
    if acc[A_STEPS_ENERGY_TARGET] < 0.0 and acc[A_JOULES] >= params[P_ENERGY_TARGET] * (1.0 - 1e-12):
        acc[A_STEPS_ENERGY_TARGET] = t

    if exhausted:
        return TERMINATED
    # the served set can only have grown in a step that delivered something
    if (bits_total > 0.0 or joules_total > 0.0) and all_served(data_left, energy, capacity, gamma):
        return TERMINATED
    if t >= params[P_STEPS]:
        return TRUNCATED
    return RUNNING


class StepArrays(NamedTuple):
    """The arrays one :func:`step` reads and writes, by name: the layout's tables (their
    per-copy rows in a vector env), then the episode's state. numba takes it as one typed
    argument (:func:`step_args` makes it from a :class:`Tables` and an :class:`EpisodeState`)."""

    next_cell: np.ndarray
    propulsion_j: np.ndarray
    cov_ptr: np.ndarray
    cov_node: np.ndarray
    cov_snr: np.ndarray
    cov_pav: np.ndarray
    capacity: np.ndarray
    fail_prob: np.ndarray
    params: np.ndarray
    where: np.ndarray
    data_left: np.ndarray
    energy: np.ndarray
    delivered: np.ndarray
    collected: np.ndarray
    acc: np.ndarray
    parts: np.ndarray


def step_args(tables: Tables, state: EpisodeState) -> StepArrays:
    """The arrays :func:`step` takes after (action, uniforms, normals)."""
    return StepArrays(
        tables.next_cell, tables.propulsion_j, tables.cov_ptr, tables.cov_node, tables.cov_snr, tables.cov_pav,
        tables.capacity, tables.fail_prob, tables.params,
        state.where, state.data_left, state.energy, state.delivered, state.collected, state.acc, state.parts,
    )


_COMPILED: dict[str, Callable] = {}
_KERNEL_FUNCTIONS = (
    "is_served",
    "unserved_covered",
    "all_served",
    "tabular_observation",
    "needs_refill",
    "reset_state",
    "serve_pairs",
    "reward_parts",
    "finish_step",
    "serve",
    "step",
    "step_tabular",
    "observation_at",
    "vector_observation",
    "step_vector",
)

# The physics the step uses, by plain name: the compiled kernel rebinds these two names to
# compiled versions of the very same functions (see ``compiled``).
_shannon_rate_bps = acoustics.link_rate_bps
_harvest_from_input_w = harvesting.harvest_from_input_w


def compiled(name: str) -> Callable:
    """The numba-compiled version of a kernel function, e.g. ``compiled("step")``.

    Compiled from the same source as the Python function, against compiled versions of the
    shared physics helpers; compiled once per process and cached on disk by numba.
    """
    if not _COMPILED:
        physics = compile_family({"_sigmoid": harvesting._sigmoid})
        physics.update(compile_family({"_harvest_from_input_w": harvesting.harvest_from_input_w}, physics))
        physics.update(compile_family({"_shannon_rate_bps": acoustics.link_rate_bps}))
        _COMPILED.update(
            compile_family({name: globals()[name] for name in _KERNEL_FUNCTIONS}, {
                "_shannon_rate_bps": physics["_shannon_rate_bps"],
                "_harvest_from_input_w": physics["_harvest_from_input_w"],
            })
        )
    return _COMPILED[name]
