"""Bounds on what any policy can achieve in a scenario.

:func:`upper_bound` is valid for every scenario: no policy collects more data than the
coverable nodes hold, delivers more energy than their storage can take, or earns more
reward than those two caps are worth (travel and hovering only cost). With a
deterministic channel it is tightened by the episode length times the best per-step
service any cell offers. :func:`exact_optimum` solves small deterministic instances
(``tiny``) exactly by dynamic programming over the MDP, stepping the simulator kernel
itself, so results can report optimality gaps.

Which bound holds for which policy (docs/optimum.md): a bound holds for a *class* of
policies, :data:`OPEN_LOOP` plans (the actions fixed before the episode) or
:data:`ADAPTIVE` policies (each action chosen from what has been seen; every RL agent and
every planner that reacts to the state). :class:`PolicyBound` carries a bound's value, its
name in the benchmark's tables and its class. The other bounds live beside their solvers:
:func:`planners.optimal.policy_bounds` (the MILP's and its linear relaxation's),
:func:`planners.hindsight.hindsight_bound` (perfect information) and, for small instances,
the exact adaptive optimum :func:`planners.adaptive.adaptive_optimum`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from swiptopt import kernel as K
from swiptopt.acoustics import shannon_rate_bps
from swiptopt.errors import ConfigError
from swiptopt.harvesting import harvest_from_input_array_w
from swiptopt.scenario import Scenario
from swiptopt.validation import Spec, check_value

#: Policy classes (docs/optimum.md): a plan whose actions are fixed before the episode, and
#: a policy that may choose each action from what it has seen. A bound that holds for
#: adaptive policies holds for open-loop plans too.
OPEN_LOOP = "open-loop"
ADAPTIVE = "adaptive"
POLICY_CLASSES = (OPEN_LOOP, ADAPTIVE)

#: The bounds' names, as the benchmark's ``bound`` column prints them.
UPPER_NAME = "upper"
""":func:`upper_bound`: every policy."""
MILP_NAME = "milp"
"""The MILP's dual bound with a deterministic channel: every policy."""
MILP_EXPECTED_NAME = "milp (expected)"
"""The MILP's dual bound on the expected-rate relaxation: open-loop plans that cannot end early."""
LP_EXPECTED_NAME = "lp (expected)"
"""The expected-rate relaxation's linear relaxation: every non-anticipative policy."""
HINDSIGHT_NAME = "hindsight"
"""The perfect-information bound's upper confidence limit: every non-anticipative policy."""


@dataclass(frozen=True)
class PolicyBound:
    """A bound on the expected return, its name and the class of policies it holds for."""

    value: float
    name: str
    holds_for: str
    """:data:`ADAPTIVE` (every non-anticipative policy) or :data:`OPEN_LOOP` (open-loop plans only)."""

    def __post_init__(self) -> None:
        check_value("holds_for", self.holds_for, Spec(kind="str", choices=POLICY_CLASSES))

    def holds(self, policy_class: str) -> bool:
        """Whether the bound holds for a policy of ``policy_class``."""
        return self.holds_for == ADAPTIVE or policy_class == OPEN_LOOP


@dataclass(frozen=True)
class UpperBound:
    """Upper bounds on an episode's return, data collected (bit) and energy delivered (J)."""

    return_: float
    data_bits: float
    energy_delivered_j: float


def upper_bound(scenario: Scenario, tables: K.Tables | None = None) -> UpperBound:
    """Bounds no policy can beat: node caps, and per-step service for a
    deterministic channel.

    With ``link = "uplink"`` the energy cap adds what sending every packet can cost a node
    (each at the threshold rate: sending frees storage to be refilled), and a step's data
    is bounded by the node's own rate for the whole step (alpha is 0 there, so the
    harvest term is the whole received power's).

    ``tables``: the scenario's kernel tables when the caller has them (an environment's
    ``env.tables``), else built here.
    """
    t = K.build_tables(scenario) if tables is None else tables
    p = t.named
    gamma = p.reward_weight
    coverable = np.zeros(t.n_nodes, dtype=bool)
    coverable[np.unique(t.cov_node)] = True
    data_cap = float(t.data0[coverable].sum())
    energy_cap = float((t.capacity - t.energy0)[coverable].sum())
    uplink = scenario.link == "uplink"
    if uplink:
        # a node that sends frees storage to be refilled: at most every packet of its data,
        # each at the slowest rate a link in service can have (SNR at the threshold)
        slowest_bps = float(shannon_rate_bps(p.bandwidth_hz, p.snr_threshold))
        packets = np.ceil(t.data0[coverable] / p.packet_bits)
        packet_j = (p.node_tx_w + p.node_circuit_w) * p.packet_bits / slowest_bps
        energy_cap += float(packets.sum() * packet_j)
    if scenario.idle_drain_w > 0:
        # a draining node can take energy again: its room is refilled by at most the drain
        energy_cap += float(coverable.sum() * p.drain_j * scenario.episode_steps)
    data_bound, energy_bound = data_cap, energy_cap
    if scenario.channel == "none":
        # the most any one step can deliver, from the best cell, ignoring every cap
        dt = p.dt_s
        if uplink:
            # a step carries at most the node's own rate for the whole step
            up = t.cov_snr * p.uplink_snr_gain
            bits = np.where(up >= p.snr_threshold, dt * shannon_rate_bps(p.bandwidth_hz, up), 0.0)
        else:
            bits = dt * shannon_rate_bps(p.bandwidth_hz, p.split_ratio * t.cov_snr)
        joules = dt * harvest_from_input_array_w(
            (1 - p.split_ratio) * t.cov_pav, p.logistic == 1.0, p.efficiency, p.logistic_max_w, p.logistic_a_per_w,
            p.logistic_b_w,
        )
        cell_of_pair = np.repeat(np.arange(t.n_cells), np.diff(t.cov_ptr))
        per_cell_bits = np.bincount(cell_of_pair, weights=bits, minlength=t.n_cells)
        per_cell_joules = np.bincount(cell_of_pair, weights=joules, minlength=t.n_cells)
        data_bound = min(data_cap, scenario.episode_steps * float(per_cell_bits.max()))
        energy_bound = min(energy_cap, scenario.episode_steps * float(per_cell_joules.max()))
        step_reward = gamma * per_cell_bits / p.data_ref_bits + (1 - gamma) * per_cell_joules / p.energy_ref_j
        reward_cap = gamma * data_cap / p.data_ref_bits + (1 - gamma) * energy_cap / p.energy_ref_j
        return UpperBound(
            float(min(reward_cap, scenario.episode_steps * float(step_reward.max()))), data_bound, energy_bound
        )
    reward_cap = gamma * data_cap / p.data_ref_bits + (1 - gamma) * energy_cap / p.energy_ref_j
    return UpperBound(float(reward_cap), data_bound, energy_bound)


#: Default ``max_states`` of :func:`exact_optimum`, and the most states the benchmark lets
#: it explore (by :func:`exact_state_bound`, decided before it runs), so that a run's time and
#: memory are bounded before it starts.
EXACT_STATE_LIMIT = 2_000_000


def exact_state_bound(scenario: Scenario, tables: K.Tables | None = None) -> int:
    """An upper bound on the states :func:`exact_optimum` explores, computed before running it.

    The search expands every state of layer t (t = 0 .. T-1) by the 7 actions, so it
    explores 7 times the sum of the layer sizes. A layer holds at most 7^t states (one per
    action sequence). Without idle drain and energy gate, a node's data and energy depend
    only on how often the AUV served it from each cell (sums of fixed per-cell increments,
    capped), so a state is fixed by the AUV's cell and the counts of visits to the m cells
    that cover any node: at most n_cells * C(t + m, m) states in layer t. With a drain or a
    gate the order of the visits matters, and only 7^t holds. Float sums in another order
    can differ in the last bits; the search merges states at 1 mbit and 1 nJ, so the bound
    holds in practice, and ``max_states`` still guards the search.
    """
    t = K.build_tables(scenario) if tables is None else tables
    covering = int(np.count_nonzero(np.diff(t.cov_ptr)))
    order_free = scenario.idle_drain_w == 0 and scenario.energy_gate_j == 0
    total = 0
    for step in range(scenario.episode_steps):
        layer = K.N_ACTIONS**step
        if order_free:
            layer = min(layer, t.n_cells * math.comb(step + covering, covering))
        total += K.N_ACTIONS * layer
    return total


@dataclass(frozen=True, eq=False)
class ExactOptimum:
    """The best return of a deterministic scenario and one action sequence that earns it."""

    return_: float
    actions: list[int]
    states_explored: int


def exact_optimum(
    scenario: Scenario, *, max_states: int = EXACT_STATE_LIMIT, tables: K.Tables | None = None
) -> ExactOptimum:
    """Exact optimum by forward dynamic programming over the deterministic MDP.

    States are (cell, node data left, node energy), merged when equal to 1 mbit and 1 nJ;
    each layer t keeps the best return reaching every state. The returned actions, replayed
    in the environment, earn the returned value (the tests check this). Needs ``channel="none"`` and no link failures;
    ``max_states`` bounds the work (an error names it when exceeded; :func:`exact_state_bound`
    tells beforehand whether it can be). ``tables``: the scenario's kernel tables when the
    caller has them.
    """
    if scenario.channel != "none" or scenario.failure_prob_max > 0:
        raise ConfigError(
            "exact_optimum needs a deterministic scenario: channel = 'none' and failure_prob_max = 0",
            "channel",
        )
    t = K.build_tables(scenario) if tables is None else tables
    step = K.compiled("step") if K.numba_available() else K.step
    uniforms, normals = K.noise_buffers(t)
    start = K.new_state(t)
    start.where[K.W_UPTR] = start.where[K.W_ZPTR] = 0  # no draws are read (deterministic)

    def key(s: K.EpisodeState) -> bytes:
        # node states reached by the same service in another order differ only by float
        # rounding; merge them at 1 mbit and 1 nJ, far below anything the reward can see
        return (
            int(s.where[K.W_CELL]).to_bytes(4, "little")
            + np.round(s.data_left, 3).tobytes()
            + np.round(s.energy, 9).tobytes()
        )

    layer = {key(start): (0.0, start, [])}
    best_return, best_actions = -np.inf, []
    explored = 0
    for _ in range(scenario.episode_steps):
        nxt: dict[bytes, tuple[float, K.EpisodeState, list[int]]] = {}
        for value, state, actions in layer.values():
            for a in range(K.N_ACTIONS):
                s = state.copy()
                code = step(a, uniforms, normals, K.step_args(t, s))
                explored += 1
                r = float(s.parts[0] + s.parts[1] + s.parts[2])
                total = value + r
                if code != K.RUNNING:
                    if total > best_return:
                        best_return, best_actions = total, actions + [a]
                    continue
                k = key(s)
                if k not in nxt or total > nxt[k][0]:
                    nxt[k] = (total, s, actions + [a])
        if explored > max_states:
            raise ConfigError(f"exact_optimum explored more than max_states = {max_states} states", "max_states")
        layer = nxt
        if not layer:
            break
    return ExactOptimum(float(best_return), best_actions, explored)
