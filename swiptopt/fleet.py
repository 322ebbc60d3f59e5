"""Fleets: several AUVs serving one network (docs/fleet.md).

A fleet's step moves every AUV that still has battery, in index order, then lets each serve
the nodes it covers with the kernel's own :func:`~swiptopt.kernel.serve_pairs` (reading
the step's draws in that order), then ends the step once with
:func:`~swiptopt.kernel.finish_step`: one idle drain, the fleet's reward parts, t += 1. So
a fleet obeys exactly the single AUV's rules, per AUV:

- a node covered by two AUVs in one step gets both transfers, each capped as for one AUV
  (data never beyond what the node holds, energy never beyond its storage);
- unless the scenario's ``share_cells`` is set, an AUV never enters a cell another AUV is
  in (after the AUVs before it moved, before the AUVs after it): the move is blocked and
  costs its attempt, as a move into an obstacle does;
- an AUV whose battery is spent (``auv_batteries_j``) leaves the fleet at the end of that
  step: it no longer moves, serves, spends or occupies a cell;
- the episode ends when every node is served or every AUV's battery is spent
  (terminated), or after ``episode_steps`` (truncated).

With ``n_auvs = 1`` the arithmetic is the single AUV's, operation for operation: a fleet of
one gives the single-AUV episode bit for bit (a test holds the two to each other).

The step is plain Python over numpy arrays, compiled by numba from the same source
(:func:`compiled`), as the kernel is.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from swiptopt import kernel as K
from swiptopt.jit import compile_family
from swiptopt.kernel import (
    A_BITS,
    A_COVERED_NODE_STEPS,
    A_HOTEL_J,
    A_JOULES,
    A_NODE_TX_J,
    A_PROJECTOR_J,
    A_PROJECTOR_STEPS,
    A_PROPULSION_J,
    A_RETURN,
    P_HOTEL_J,
    R_HARVEST,
    R_MOVEMENT,
    R_THROUGHPUT,
    VECTOR_NODE_FEATURES,
    W_CELL,
    W_T,
    finish_step,
    observation_at,
    reward_parts,
    serve_pairs,
)
from swiptopt.metrics import episode_metrics, jain_index
from swiptopt.scenario import Scenario

#: Features per other AUV in a fleet's vector observation: its position relative to the
#: observing AUV over the extent (x, y, depth), and 1.0 while it is in the fleet.
OTHER_AUV_FEATURES = 4


@dataclass(frozen=True, eq=False)
class FleetTables:
    """A fleet's scenario tables: the kernel's (:class:`~swiptopt.kernel.Tables`, shared by
    every AUV) and each AUV's start cell and battery."""

    tables: K.Tables
    start_cells: np.ndarray
    """(n_auvs,) int64 flat cell indices."""
    batteries_j: np.ndarray
    """(n_auvs,) float64."""
    share_cells: bool

    @property
    def n_auvs(self) -> int:
        return int(self.start_cells.shape[0])


def fleet_tables(scenario: Scenario, tables: K.Tables | None = None) -> FleetTables:
    """The fleet's tables for ``scenario`` (``tables``: the kernel's, when already built)."""
    tables = K.build_tables(scenario) if tables is None else tables
    starts = np.array([scenario.cell_index(c) for c in scenario.fleet_start_cells], dtype=np.int64)
    return FleetTables(tables, starts, np.array(scenario.fleet_batteries_j, dtype=float), scenario.share_cells)


class FleetState(NamedTuple):
    """The mutable state of a fleet's episode: the nodes' (shared), the fleet's running
    totals, and each AUV's. Its fields after ``where`` are what :func:`fleet_step` writes."""

    where: np.ndarray
    """(4,) int64 as the kernel's ``EpisodeState.where`` (its cell: AUV 0's)."""
    cells: np.ndarray
    """(n_auvs,) int64: each AUV's cell."""
    active: np.ndarray
    """(n_auvs,) bool: whether each AUV is still in the fleet (battery left)."""
    data_left: np.ndarray
    energy: np.ndarray
    delivered: np.ndarray
    collected: np.ndarray
    acc: np.ndarray
    """(N_ACC,) the fleet's totals (``A_*``): its energy summed over AUVs."""
    auv_acc: np.ndarray
    """(n_auvs, N_ACC) each AUV's totals (energies, bits, joules, its own return)."""
    parts: np.ndarray
    """(3,) the fleet's reward parts in the last step."""
    auv_parts: np.ndarray
    """(n_auvs, 3) each AUV's reward parts in the last step (its bits, joules and motion)."""
    busy: np.ndarray
    """(n_auvs,) int64: the step count at the end of each AUV's last step that delivered
    data or energy (0: none yet)."""
    steps: np.ndarray
    """(n_auvs,) int64: the steps each AUV has been in the fleet."""

    @property
    def t(self) -> int:
        return int(self.where[W_T])


def new_fleet_state(fleet: FleetTables) -> FleetState:
    """The state at the start of an episode; its draw positions mark the buffers used up."""
    t, n = fleet.tables, fleet.n_auvs
    state = FleetState(
        where=np.zeros(4, dtype=np.int64), cells=np.zeros(n, dtype=np.int64), active=np.zeros(n, dtype=bool),
        data_left=np.empty(t.n_nodes), energy=np.empty(t.n_nodes), delivered=np.empty(t.n_nodes),
        collected=np.empty(t.n_nodes), acc=np.empty(K.N_ACC), auv_acc=np.zeros((n, K.N_ACC)),
        parts=np.zeros(3), auv_parts=np.zeros((n, 3)), busy=np.zeros(n, dtype=np.int64),
        steps=np.zeros(n, dtype=np.int64),
    )
    reset_fleet(fleet, state)
    state.where[K.W_UPTR] = state.where[K.W_ZPTR] = 2**62
    return state


def reset_fleet(fleet: FleetTables, state: FleetState) -> None:
    """Rewrite ``state`` in place to the start of an episode, keeping its draw positions."""
    t = fleet.tables
    K.reset_state(
        int(fleet.start_cells[0]), t.data0, t.energy0, t.params, state.where, state.data_left, state.energy,
        state.delivered, state.collected, state.acc, state.parts,
    )
    state.cells[:] = fleet.start_cells
    state.active[:] = True
    state.auv_acc[:] = 0.0
    state.auv_parts[:] = 0.0
    state.busy[:] = 0
    state.steps[:] = 0


def needs_refill(fleet: FleetTables, state: FleetState, uniforms: np.ndarray, normals: np.ndarray) -> bool:
    """Whether fewer draws are left than the next step could use."""
    t = fleet.tables
    return bool(K.needs_refill(state.where, t.n_nodes * fleet.n_auvs, uniforms.shape[0], normals.shape[0],
                               t.normal_rows))


#: What :func:`fleet_step` reads (the scenario's tables as the kernel's step takes them, each
#: AUV's battery, whether AUVs may share a cell) and writes (the :class:`FleetState`'s
#: arrays), as one typed argument: the kernel's table fields, then the fleet's own, then the
#: state's.
_TABLE_FIELDS = K.StepArrays._fields[: K.StepArrays._fields.index("where")]
FleetArrays = NamedTuple(  # type: ignore[misc]
    "FleetArrays",
    [(name, np.ndarray) for name in _TABLE_FIELDS] + [("batteries_j", np.ndarray), ("share_cells", bool)]
    + [(name, np.ndarray) for name in FleetState._fields],
)


def fleet_args(fleet: FleetTables, state: FleetState) -> FleetArrays:
    """The arrays :func:`fleet_step` takes after (actions, uniforms, normals)."""
    t = fleet.tables
    return FleetArrays(*(getattr(t, name) for name in _TABLE_FIELDS), fleet.batteries_j, fleet.share_cells, *state)


#: The fleet's energy totals: each the sum of the AUVs'.
_SUMMED = (A_PROPULSION_J, A_HOTEL_J, A_PROJECTOR_J, A_PROJECTOR_STEPS, A_COVERED_NODE_STEPS, A_NODE_TX_J)


def move_auv(k, action, a):  # type: ignore[no-untyped-def]
    """AUV ``k``'s cell after ``action``: the kernel's move, blocked (the AUV stays) when
    another AUV in the fleet is in the target cell and cells are not shared."""
    cell = a.cells[k]
    target = a.next_cell[cell, action]
    if not a.share_cells and target != cell:
        for j in range(a.cells.shape[0]):
            if j != k and a.active[j] and a.cells[j] == target:
                return cell
    return target


def fleet_step(actions, uniforms, normals, a):  # type: ignore[no-untyped-def]
    """Advance a fleet by one step: ``actions`` (n_auvs,) int64 (ignored for AUVs out of
    the fleet), the step's draws, :class:`FleetArrays` ``a``; returns the kernel's RUNNING,
    TERMINATED or TRUNCATED (the module's docstring gives the rules)."""
    params = a.params
    n = a.cells.shape[0]
    bits_total = 0.0
    joules_total = 0.0
    move_total = 0.0
    for k in range(n):
        a.auv_parts[k, :] = 0.0
        if not a.active[k]:
            continue
        a.steps[k] += 1
        cell = a.cells[k]
        action = actions[k]
        new_cell = move_auv(k, action, a)
        a.cells[k] = new_cell
        row = a.auv_acc[k]
        propulsion = a.propulsion_j[cell, action]
        bits, joules = serve_pairs(
            propulsion, a.cov_ptr[new_cell], a.cov_ptr[new_cell + 1], uniforms, normals, a.cov_node, a.cov_snr,
            a.cov_pav, a.capacity, a.fail_prob, params, a.where, a.data_left, a.energy, a.delivered, a.collected,
            row,
        )
        move = propulsion + params[P_HOTEL_J]
        own = a.auv_parts[k]
        reward_parts(bits, joules, move, params, own)
        row[A_BITS] += bits
        row[A_JOULES] += joules
        row[A_RETURN] += own[R_THROUGHPUT] + own[R_HARVEST] + own[R_MOVEMENT]
        if bits > 0.0 or joules > 0.0:
            a.busy[k] = a.where[W_T] + 1
        bits_total += bits
        joules_total += joules
        move_total += move
    for f in _SUMMED:
        total = 0.0
        for k in range(n):
            total += a.auv_acc[k, f]
        a.acc[f] = total
    any_active = False
    for k in range(n):
        if a.active[k]:
            spent = a.auv_acc[k, A_PROPULSION_J] + a.auv_acc[k, A_HOTEL_J] + a.auv_acc[k, A_PROJECTOR_J]
            if spent >= a.batteries_j[k]:
                a.active[k] = False
            else:
                any_active = True
    a.where[W_CELL] = a.cells[0]
    return finish_step(
        bits_total, joules_total, move_total, not any_active, params, a.where, a.data_left, a.energy, a.capacity,
        a.acc, a.parts,
    )


def fleet_observations(t, cells, active, cov_ptr, cov_node, data_left, energy, data0, capacity, params,  # type: ignore[no-untyped-def]
                       cells_norm, nodes_norm, out):
    """Every AUV's vector observation, AUV k's in ``out[k]`` ((n_auvs, 4 + 6 n_nodes + 4
    (n_auvs - 1)) float32): the single AUV's (:func:`~swiptopt.kernel.observation_at`, from
    its own cell), then for each other AUV, in the order k + 1, k + 2, ... (wrapping), its
    position minus AUV k's over the extent and 1.0 while it is in the fleet."""
    n = cells.shape[0]
    n_nodes = data_left.shape[0]
    base = 4 + VECTOR_NODE_FEATURES * n_nodes
    for k in range(n):
        row = out[k]
        here = cells_norm[cells[k]]
        observation_at(
            here, t, cov_ptr[cells[k]], cov_ptr[cells[k] + 1], cov_node, data_left, energy, data0, capacity, params,
            nodes_norm, row[:base],
        )
        for i in range(1, n):
            j = (k + i) % n
            at = base + OTHER_AUV_FEATURES * (i - 1)
            there = cells_norm[cells[j]]
            for axis in range(3):
                row[at + axis] = there[axis] - here[axis]
            row[at + 3] = 1.0 if active[j] else 0.0


_COMPILED: dict[str, Callable[..., Any]] = {}


def compiled(name: str) -> Callable[..., Any]:
    """The numba-compiled :func:`fleet_step` or :func:`fleet_observations`, compiled against
    the kernel's compiled parts (the same source as the Python functions)."""
    if not _COMPILED:
        kernel = {name: K.compiled(name) for name in ("serve_pairs", "reward_parts", "finish_step", "observation_at")}
        _COMPILED.update(compile_family(
            {"move_auv": move_auv, "fleet_step": fleet_step, "fleet_observations": fleet_observations}, kernel,
        ))
    return _COMPILED[name]


def fleet_metrics(fleet: FleetTables, state: FleetState) -> dict[str, Any]:
    """The metrics of a fleet's episode: the single AUV's (:func:`~swiptopt.metrics.episode_metrics`)
    for the fleet as a whole (its energy the sum of its AUVs'), then per AUV (lists in AUV
    order) its energy, data, energy delivered, return and steps in the fleet, the makespan (the time at the end
    of the last step in which any AUV delivered data or energy) and Jain's index of the
    AUVs' energy (how evenly the fleet shares the work)."""
    t = fleet.tables
    state_like = K.EpisodeState(state.where, state.data_left, state.energy, state.delivered, state.collected,
                                state.acc, state.parts)
    # the always-on reading counts every AUV's projector in each of its steps
    out = episode_metrics(t, state_like, None if fleet.n_auvs == 1 else int(state.steps.sum()))
    acc = state.auv_acc
    energy_j = acc[:, A_PROPULSION_J] + acc[:, A_HOTEL_J] + acc[:, A_PROJECTOR_J]
    out.update({
        "n_auvs": fleet.n_auvs,
        "makespan_s": float(state.busy.max(initial=0)) * t.named.dt_s,
        "auv_energy_j_each": [float(x) for x in energy_j],
        "data_bits_each": [float(x) for x in acc[:, A_BITS]],
        "energy_delivered_j_each": [float(x) for x in acc[:, A_JOULES]],
        "return_each": [float(x) for x in acc[:, A_RETURN]],
        "steps_each": [int(x) for x in state.steps],
        "jain_auv_energy": jain_index(energy_j),
    })
    return out
