"""Per-episode metrics (SPEC 4), computed from the kernel's state at the end of an episode.

The environment computes them once, on an episode's last step; every part is vectorised
over the nodes (a Python loop over 1000 nodes here once cost more per episode than the
episode's 50 steps)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from swiptopt import kernel as K

#: Metric names of ``info["episode_metrics"]``, in table order.
EPISODE_METRICS = (
    "return",
    "data_bits",
    "energy_delivered_j",
    "auv_energy_j",
    "auv_propulsion_j",
    "auv_hotel_j",
    "auv_projector_j",
    "mission_time_s",
    "energy_efficiency_bit_per_j",
    "mobility_efficiency_bit_per_j",
    "nodes_served",
    "jain_data",
    "jain_energy",
    "steps_to_data_target",
    "steps_to_energy_target",
    "length",
)


def jain_index(x: np.ndarray) -> float:
    """Jain's fairness (sum x)^2 / (n sum x^2) in [1/n, 1]; NaN when every x is 0 (undefined)."""
    x = np.asarray(x, dtype=float)
    squares = float(np.sum(x * x))
    if squares == 0.0:
        return math.nan
    return float(np.sum(x) ** 2 / (x.size * squares))


def episode_metrics(tables: K.Tables, state: K.EpisodeState) -> dict[str, Any]:
    """The metrics of an episode from its final state.

    ``energy_efficiency_bit_per_j`` divides the data by all the AUV's energy (propulsion,
    hotel and projector: SPEC 4); ``mobility_efficiency_bit_per_j`` by propulsion and hotel
    energy only, the AUV energy of the paper's eqs. 14-16, for comparison with its results.

    ``steps_to_*_target`` are ``None`` when the target was not reached (never a number
    that looks like one); ``jain_*`` are NaN when nothing at all was delivered.
    """
    acc = state.acc
    gamma = tables.params[K.P_GAMMA]
    auv_j = float(acc[K.A_PROPULSION_J] + acc[K.A_HOTEL_J] + acc[K.A_PROJECTOR_J])
    mobility_j = float(acc[K.A_PROPULSION_J] + acc[K.A_HOTEL_J])
    bits = float(acc[K.A_BITS])
    served = int(np.count_nonzero(K.served_mask(state.data_left, state.energy, tables.capacity, gamma)))
    steps_data = acc[K.A_STEPS_DATA_TARGET]
    steps_energy = acc[K.A_STEPS_ENERGY_TARGET]
    return {
        "return": float(acc[K.A_RETURN]),
        "data_bits": bits,
        "energy_delivered_j": float(acc[K.A_JOULES]),
        "auv_energy_j": auv_j,
        "auv_propulsion_j": float(acc[K.A_PROPULSION_J]),
        "auv_hotel_j": float(acc[K.A_HOTEL_J]),
        "auv_projector_j": float(acc[K.A_PROJECTOR_J]),
        "mission_time_s": state.t * float(tables.params[K.P_DT]),
        "energy_efficiency_bit_per_j": bits / auv_j if auv_j > 0 else 0.0,
        # the paper's AUV energy (eqs. 14-16) is propulsion and hotel load only
        "mobility_efficiency_bit_per_j": bits / mobility_j if mobility_j > 0 else 0.0,
        "nodes_served": served,
        "jain_data": jain_index(state.collected),
        "jain_energy": jain_index(state.delivered),
        "steps_to_data_target": None if steps_data < 0 else int(steps_data),
        "steps_to_energy_target": None if steps_energy < 0 else int(steps_energy),
        "length": state.t,
    }
