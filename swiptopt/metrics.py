"""Per-episode metrics, computed from the kernel's state at the end of an episode.

The environment computes them once, on an episode's last step; every part is vectorised
over the nodes, so that scoring an episode of many nodes costs little next to its steps.
What each metric means: docs/design.md, 'A step, the reward and the end of an episode
(Section III)'."""

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
    "energy_efficiency_always_on_bit_per_j",
    "energy_efficiency_per_node_bit_per_j",
    "mobility_efficiency_bit_per_j",
    "node_transmit_energy_j",
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


def episode_metrics(tables: K.Tables, state: K.EpisodeState, projector_steps: int | None = None) -> dict[str, Any]:
    """The metrics of an episode from its final state (``projector_steps``: the steps the
    always-on reading counts a projector in; by default the episode's, one AUV's).

    Energy efficiency, bits per joule of AUV energy, under each reading of the paper's
    "EE = T / P_tau ... P_tau is the sum of the transmission power from the AUV to node and
    the navigation power" (Section IV, on Fig. 9), side by side:

    - ``energy_efficiency_bit_per_j``: propulsion + hotel + the projector in the steps where
      it serves at least one node (the simulator's own AUV energy, ``auv_energy_j``);
    - ``energy_efficiency_always_on_bit_per_j``: the projector counted in every step of the
      episode, covered or not;
    - ``energy_efficiency_per_node_bit_per_j``: the projector's energy counted once per node
      it covers in each step, as if "each node transmits with 1 kW" (Section IV) meant one
      P_elec per served link: this AUV energy grows with the number of nodes covered;
    - ``mobility_efficiency_bit_per_j``: propulsion and hotel only (motion, eqs. 16-18).

    ``node_transmit_energy_j``: what the nodes spent from their storage on uplink packets
    (0 on the power-split downlink).

    ``steps_to_data_target`` / ``steps_to_energy_target``: the first step at which the
    episode's data collected (energy delivered) reached ``target_fraction`` of what the
    *coverable* nodes hold (can store): nodes that no cell covers count in neither the
    target nor the progress. ``None`` when the target was not reached (never a number
    that looks like one); ``jain_*`` are NaN when nothing at all was delivered.
    """
    acc = state.acc
    params = tables.named
    gamma = params.reward_weight
    motion_j = float(acc[K.A_PROPULSION_J] + acc[K.A_HOTEL_J])
    auv_j = motion_j + float(acc[K.A_PROJECTOR_J])
    always_on_j = motion_j + params.projector_j * (state.t if projector_steps is None else projector_steps)
    per_node_j = motion_j + params.projector_j * float(acc[K.A_COVERED_NODE_STEPS])
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
        "mission_time_s": state.t * params.dt_s,
        "energy_efficiency_bit_per_j": _ratio(bits, auv_j),
        "energy_efficiency_always_on_bit_per_j": _ratio(bits, always_on_j),
        "energy_efficiency_per_node_bit_per_j": _ratio(bits, per_node_j),
        "mobility_efficiency_bit_per_j": _ratio(bits, motion_j),
        "node_transmit_energy_j": float(acc[K.A_NODE_TX_J]),
        "nodes_served": served,
        "jain_data": jain_index(state.collected),
        "jain_energy": jain_index(state.delivered),
        "steps_to_data_target": None if steps_data < 0 else int(steps_data),
        "steps_to_energy_target": None if steps_energy < 0 else int(steps_energy),
        "length": state.t,
    }


def _ratio(bits: float, joules: float) -> float:
    return bits / joules if joules > 0 else 0.0
