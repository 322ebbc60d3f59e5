"""The per-step model of the continuous world: what a step ending at a point earns, priced
by the kernel's own functions (:func:`point_model`), the value of hovering at candidate
points (:func:`hover_values`), a trajectory's return (:func:`trajectory_return`), and the
service of single positions computed in batches (:class:`PointService`)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np

from swiptopt import kernel as K

#: Under fading, the model prices the service of a position at the nearest point of a grid
#: this fine, m (:class:`PointService`).
SERVICE_GRID_M = 1e-3


def point_model(world: Any, points_m: np.ndarray, *, mean_channel: bool = False) -> Any:
    """The per-step model (:class:`planners.service.StepModel`) with the given points as its
    "cells": a step ending at point c serves the nodes :func:`swiptopt.continuous.coverage_at`
    covers from it, priced by the kernel's functions; staying there costs holding station.

    ``points_m``: (m, 3). Only the service amounts and the stay costs are meaningful (there
    are no moves between the points). ``mean_channel``: price the mean channel (no fading;
    link failures still scale the data) instead of the expectation over the fading, which
    costs a quadrature per call: the hover-point search ranks many points with it.
    """
    from planners.service import step_model

    cover, _, propulsion_j = step_functions()
    points = np.ascontiguousarray(np.asarray(points_m, dtype=float).reshape(-1, 3))
    m = len(points)
    n = int(world.n_nodes)
    nodes, snr, pav, counts = [], [], [], np.zeros(m, dtype=np.int64)
    hover_j = np.empty(m)
    scratch = (np.empty(n, dtype=np.int64), np.empty(n), np.empty(n))
    still = np.zeros(3)
    for c, p in enumerate(points):
        count = cover(world.world, world.nodes_m, p, *scratch)
        nodes.append(scratch[0][:count].copy())
        snr.append(scratch[1][:count].copy())
        pav.append(scratch[2][:count].copy())
        counts[c] = count
        hover_j[c] = propulsion_j(world.world, world.params, float(p[2]), still, 0.0)
    cov_ptr = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(counts, out=cov_ptr[1:])
    params = np.asarray(world.params, dtype=float)
    if mean_channel:
        params = K.replace_params(params, channel=K.CHANNEL_CODES["none"])
    tables = K.Tables(
        next_cell=np.repeat(np.arange(m, dtype=np.int64)[:, None], K.N_ACTIONS, axis=1),
        moved=np.zeros((m, K.N_ACTIONS), dtype=bool),
        propulsion_j=np.repeat(hover_j[:, None], K.N_ACTIONS, axis=1),
        cov_ptr=cov_ptr,
        cov_node=np.concatenate(nodes) if m else np.zeros(0, dtype=np.int64),
        cov_snr=np.concatenate(snr) if m else np.zeros(0),
        cov_pav=np.concatenate(pav) if m else np.zeros(0),
        data0=np.asarray(world.data0, dtype=float),
        energy0=np.asarray(world.energy0, dtype=float),
        capacity=np.asarray(world.capacity, dtype=float),
        fail_prob=np.asarray(world.fail_prob, dtype=float),
        params=params,
        start_cell=0,
        n_cells=m,
        n_nodes=int(world.n_nodes),
        draws_uniforms=bool(np.any(np.asarray(world.fail_prob) > 0)),
        normal_rows=int(world.named.normal_rows),
    )
    return step_model(tables)




@functools.lru_cache(maxsize=1)
def step_functions() -> tuple[Callable[..., Any], Callable[..., Any], Callable[..., Any]]:
    """:mod:`swiptopt.continuous`'s ``cover``, ``command`` and ``propulsion_j``: the env's own
    compiled functions when numba is installed, else the Python originals."""
    from swiptopt import continuous as C
    from swiptopt.jit import numba_available

    if numba_available():
        return C.compiled("cover"), C.compiled("command"), C.compiled("propulsion_j")
    return C.cover, C.command, C.propulsion_j



def hover_values(world: Any, points_m: np.ndarray, group: np.ndarray) -> np.ndarray:
    """(m,) what one step of hovering at each point earns from the nodes of ``group`` (fresh:
    all their data and storage room left), less the cost of holding station there, on the
    mean channel (link failures counted, fading not: see :func:`point_model`)."""
    model = point_model(world, points_m, mean_channel=True)
    member = np.zeros(model.n_nodes)
    member[np.asarray(group, dtype=np.int64)] = 1.0
    per_pair = (model.data_weight * model.bits + model.energy_weight * model.joules) * member[model.cov_node]
    earned = np.bincount(model.cell_of_pair(), weights=per_pair, minlength=model.n_cells)
    return earned - model.stay_cost


def trajectory_return(world: Any, positions_m: np.ndarray, actions: np.ndarray) -> float:
    """The return of a trajectory in the per-step model: ``positions_m`` (T + 1, 3) the start
    and the position after each step, ``actions`` (T, 3) the actions taken.

    Each step costs the env's movement penalty (propulsion from the step's start at the
    commanded velocity, plus hotel) and earns the service of where it ends, each node capped
    at what it still holds and can store; the trajectory stops once every node is served, as
    the env does.
    """
    from swiptopt.continuous import propulsion_energy_j, velocity_of

    p = world.named
    model = point_model(world, positions_m[1:])
    data_left = model.data_bits.copy()
    room_left = model.room_j.copy()
    total = 0.0
    for t, action in enumerate(actions):
        velocity = velocity_of(action, world.speed_mps)
        move_j = propulsion_energy_j(world, positions_m[t], velocity) + p.hotel_j
        total -= p.movement_weight * move_j / p.move_ref_j
        gained = model.serve(t, data_left, room_left)
        total += gained
        if gained > 0.0 and model.all_served(data_left, room_left):
            break
    return float(total)



class PointService:
    """The per-step model's service from single positions (:func:`point_model`), computed
    in batches and kept, for the model's rollouts.

    On a deterministic channel the amounts are the kernel's own, cheap to compute, and kept
    by exact position. Under fading each costs a quadrature, and the executor's positions
    differ by float rounding from run to run (where it arrives at a site depends on where it
    came from, within a micrometre), so the expected amounts are priced at the position
    rounded to :data:`SERVICE_GRID_M` and kept by that: the same few points serve every run.
    """

    def __init__(self, world: Any):
        self.world = world
        self.exact = point_model(world, np.zeros((0, 3))).exact
        self.known: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def _point(self, position_m: np.ndarray) -> np.ndarray:
        return position_m if self.exact else np.round(position_m / SERVICE_GRID_M) * SERVICE_GRID_M

    def get(self, position_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """(nodes, bits, joules) a step ending at the position serves, or None if not computed."""
        return self.known.get(self._point(position_m).tobytes())

    def compute(self, positions_m: list[np.ndarray]) -> None:
        points = [self._point(p) for p in positions_m]
        fresh = {p.tobytes(): p for p in points if p.tobytes() not in self.known}
        if not fresh:
            return
        model = point_model(self.world, np.stack(list(fresh.values())))
        for c, key in enumerate(fresh):
            lo, hi = model.cov_ptr[c], model.cov_ptr[c + 1]
            self.known[key] = (model.cov_node[lo:hi], model.bits[lo:hi], model.joules[lo:hi])

