"""What one step earns and costs from each cell: the planners' per-step model of the simulator.

The simulator's return depends on the walk only through how many steps end in each cell
(each such step serves the nodes covered from it, up to their caps) and what each step
costs. :func:`step_model` reads those per-step amounts from the kernel's tables, with the
kernel's own physics functions:

- deterministic channel (``channel = "none"``, no link failures): the amounts are exactly
  the kernel's, so for any walk ``node i receives min(cap_i, sum of its per-step amounts)``
  and :meth:`StepModel.walk_return` equals the simulator's return;
- stochastic channel: the amounts are expectations over the fading and the link failures
  of the per-step transfer *capped at the node's cap* (computed by Gauss-Legendre quadrature
  over the fading gain's quantile, split where the transfer has kinks: the SNR threshold and
  the caps; Gauss-Hermite would smear those kinks). By Jensen's inequality (the cap is a
  concave function of the total) this model over-estimates what a fixed walk earns on
  average: it is the *expected-rate relaxation*.

With ``link = "uplink"`` a node's data in a step depends on the energy it has stored, hence
on the order of service; the per-step amounts are then the *uplink relaxation*: the packets
that fit the step at the node's own rate (the energy they cost is not modelled) and the
charge with all the received power. It over-estimates data, and it can under-estimate
energy (a node that sends frees storage to be refilled), so it is neither exact nor a
bound: :attr:`StepModel.exact` is false and :attr:`StepModel.uplink` says why; the MILP
refuses it (status ``unsupported``), the heuristics plan on it and the simulator scores
their walks.

:mod:`planners.optimal` writes this model as a mixed-integer program, and
:mod:`planners.rate_greedy` looks ahead with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np

from swiptopt import fpmath
from swiptopt import kernel as K
from swiptopt.acoustics import shannon_rate_bps
from swiptopt.harvesting import harvested_power_w

# Gauss-Legendre nodes per piece of the fading integral, and pieces per smooth stretch.
_QUADRATURE_NODES = 24
_QUADRATURE_PANELS = 8


@cache
def gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (ascending) and weights of ``n``-point Gauss-Legendre quadrature on [-1, 1].

    Newton's method on Legendre's three-term recurrence from the classical starting points
    cos(pi (i - 1/4) / (n + 1/2)), in float arithmetic and the C library's ``cos``:
    the same bits on every CPU (numpy's ``leggauss`` starts from LAPACK's eigenvalues,
    whose kernels depend on the CPU). Agrees with ``leggauss`` to a few ulp (a test).
    """

    def legendre(x: float) -> tuple[float, float]:
        """P_n(x) and P_n'(x)."""
        p_prev, p = 1.0, x
        for k in range(2, n + 1):
            p_prev, p = p, ((2 * k - 1) * x * p - (k - 1) * p_prev) / k
        return p, n * (x * p - p_prev) / (x * x - 1.0)

    nodes, weights = [], []
    for i in range(n, 0, -1):
        x = math.cos(math.pi * (i - 0.25) / (n + 0.5))
        for _ in range(100):
            p, dp = legendre(x)
            step = p / dp
            x -= step
            if abs(step) <= 1e-16:
                break
        _, dp = legendre(x)
        nodes.append(x)
        weights.append(2.0 / ((1.0 - x * x) * dp * dp))
    return np.array(nodes), np.array(weights)


@dataclass(frozen=True, eq=False)
class StepModel:
    """Per-step service and cost of every cell; arrays follow the kernel's coverage lists."""

    next_cell: np.ndarray
    """(n_cells, 7) the kernel's transition table."""
    cov_ptr: np.ndarray
    """(n_cells + 1,) covered nodes of cell c are ``cov_node[cov_ptr[c]:cov_ptr[c + 1]]``."""
    cov_node: np.ndarray
    """(nnz,) node indices."""
    bits: np.ndarray
    """(nnz,) bits one step ending in the cell delivers from the node (expected for a
    stochastic channel), capped at the node's data."""
    joules: np.ndarray
    """(nnz,) energy one step delivers to the node, J (expected), capped at its free storage."""
    data_bits: np.ndarray
    """(n_nodes,) data each node holds at the start."""
    room_j: np.ndarray
    """(n_nodes,) free storage of each node at the start, J."""
    capacity_j: np.ndarray
    """(n_nodes,) storage capacity, J (the kernel calls a node full within 1e-12 of it)."""
    data_weight: float
    """Reward per bit, Gamma / D_ref."""
    energy_weight: float
    """Reward per joule, (1 - Gamma) / E_ref."""
    step_cost: np.ndarray
    """(n_cells, 7) the movement penalty of each action, lambda (propulsion + hotel) / E_move_ref."""
    stay_action: np.ndarray
    """(n_cells,) the cheapest action that leaves the AUV in its cell (hover, or a blocked move)."""
    stay_cost: np.ndarray
    """(n_cells,) its penalty."""
    start_cell: int
    steps: int
    """Episode length."""
    needs_energy: bool
    """Whether a node must also be full to count as served (Gamma < 1)."""
    exact: bool
    """Whether the amounts are the simulator's own (deterministic channel, power-split downlink)."""
    uplink: bool = False
    """Whether the scenario's data link is the uplink, where the amounts are the uplink
    relaxation (module docstring), not the simulator's."""

    @property
    def n_cells(self) -> int:
        return self.next_cell.shape[0]

    @property
    def n_nodes(self) -> int:
        return self.data_bits.shape[0]

    def cell_of_pair(self) -> np.ndarray:
        """(nnz,) the cell of each covered pair."""
        return np.repeat(np.arange(self.n_cells), np.diff(self.cov_ptr))

    def coverable(self) -> np.ndarray:
        """(n_nodes,) bool: whether some cell covers the node."""
        out = np.zeros(self.n_nodes, dtype=bool)
        out[self.cov_node] = True
        return out

    def can_finish_early(self) -> bool:
        """Whether serving every node (which ends the episode) is possible at all."""
        return bool(self.coverable().all())

    def delivered(self, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n_nodes,) bits and joules (uncapped) from ``counts[c]`` steps ending in each cell c."""
        per_pair = counts[self.cell_of_pair()]
        bits = np.bincount(self.cov_node, weights=per_pair * self.bits, minlength=self.n_nodes)
        joules = np.bincount(self.cov_node, weights=per_pair * self.joules, minlength=self.n_nodes)
        return bits, joules

    def service_value(self, counts: np.ndarray) -> float:
        """The service part of the return of a walk with ``counts[c]`` steps ending in cell c
        (each node capped at what it holds and can store; order does not matter)."""
        bits, joules = self.delivered(counts)
        return float(
            self.data_weight * np.minimum(bits, self.data_bits).sum()
            + self.energy_weight * np.minimum(joules, self.room_j).sum()
        )

    def serve(self, cell: int, data_left: np.ndarray, room_left: np.ndarray) -> float:
        """Serve the nodes covered from ``cell`` for one step, updating the two (n_nodes,)
        arrays in place (the kernel's rule: each node gets min(what is left, the step's
        amount)); returns the service part of the step's reward."""
        lo, hi = self.cov_ptr[cell], self.cov_ptr[cell + 1]
        if hi == lo:
            return 0.0
        nodes = self.cov_node[lo:hi]
        bits = np.minimum(data_left[nodes], self.bits[lo:hi])
        joules = np.minimum(room_left[nodes], self.joules[lo:hi])
        data_left[nodes] -= bits
        room_left[nodes] -= joules
        return self.data_weight * float(bits.sum()) + self.energy_weight * float(joules.sum())

    def all_served(self, data_left: np.ndarray, room_left: np.ndarray) -> bool:
        """The kernel's end condition: every node's data delivered (and storage full)."""
        if np.any(data_left > 0.0):
            return False
        return not self.needs_energy or bool(np.all(room_left <= self.capacity_j * 1e-12))

    def walk_return(self, actions: list[int] | np.ndarray) -> tuple[float, int]:
        """The return of an action sequence in this model and the steps it runs.

        Follows the simulator: the start cell earns nothing until a step ends there, the
        walk stops after ``steps`` steps or once every node is served, blocked moves stay
        put. Deterministic channel: the simulator's return (up to float summation order).
        """
        data_left = self.data_bits.astype(float).copy()
        room_left = self.room_j.astype(float).copy()
        cell = self.start_cell
        total = 0.0
        used = 0
        for a in actions[: self.steps]:
            total -= self.step_cost[cell, a]
            cell = int(self.next_cell[cell, a])
            gained = self.serve(cell, data_left, room_left)
            total += gained
            used += 1
            if gained > 0.0 and self.all_served(data_left, room_left):
                break
        return total, used


def step_model(tables: K.Tables) -> StepModel:
    """The per-step model of a scenario from its kernel tables (see the module docstring)."""
    p = tables.named
    dt, alpha = p.dt_s, p.split_ratio
    gamma = p.reward_weight
    nodes = tables.cov_node
    data = tables.data0.astype(float)
    room = np.maximum(tables.capacity - tables.energy0, 0.0)
    harvester = dict(
        efficiency=p.efficiency,
        model="logistic" if p.logistic == 1.0 else "linear",
        logistic_max_w=p.logistic_max_w,
        logistic_a_per_w=p.logistic_a_per_w,
        logistic_b_w=p.logistic_b_w,
    )

    uplink = p.link == K.LINK_CODES["uplink"]

    def step_bits(gain: np.ndarray, snr: np.ndarray) -> np.ndarray:
        if uplink:
            # the whole packets that fit the step at the node's own SNR; their energy is not modelled
            up = gain * snr * p.uplink_snr_gain
            ok = up >= p.snr_threshold
            rate = shannon_rate_bps(p.bandwidth_hz, np.where(ok, up, 1.0))
            return np.where(ok, np.floor(dt / (p.packet_bits / rate)) * p.packet_bits, 0.0)
        return np.where(gain * snr >= p.snr_threshold, dt * shannon_rate_bps(p.bandwidth_hz, alpha * (gain * snr)), 0.0)

    def step_joules(gain: np.ndarray, pav: np.ndarray) -> np.ndarray:
        # the kernel sends (1 - alpha) * gain * P_av to the harvester
        return dt * harvested_power_w(gain * pav, alpha, **harvester)

    channel = int(p.channel)
    deterministic = channel == 0 or (channel == 1 and p.shadowing_sigma_db == 0.0)
    if deterministic:
        one = np.ones(len(nodes))
        bits = np.minimum(step_bits(one, tables.cov_snr), data[nodes])
        joules = np.minimum(step_joules(one, tables.cov_pav), room[nodes])
    else:
        quantile, cdf = _gain_distribution(channel, p.shadowing_sigma_db, p.rician_k)
        threshold_gain = p.snr_threshold / (tables.cov_snr * (p.uplink_snr_gain if uplink else 1.0))
        bits = _expected_capped(
            lambda g: step_bits(g, tables.cov_snr[:, None]), data[nodes], quantile, cdf, kinks=[threshold_gain],
        )
        joules = _expected_capped(lambda g: step_joules(g, tables.cov_pav[:, None]), room[nodes], quantile, cdf)
    bits = bits * (1.0 - tables.fail_prob[nodes])  # a failed link carries no data (energy still flows)

    step_cost = p.movement_weight * (tables.propulsion_j + p.hotel_j) / p.move_ref_j
    stays = np.where(tables.moved, np.inf, step_cost)
    stay_action = np.argmin(stays, axis=1)
    return StepModel(
        next_cell=tables.next_cell,
        cov_ptr=tables.cov_ptr,
        cov_node=nodes,
        bits=bits,
        joules=joules,
        data_bits=data,
        room_j=room,
        capacity_j=tables.capacity.astype(float),
        data_weight=float(gamma / p.data_ref_bits),
        energy_weight=float((1.0 - gamma) / p.energy_ref_j),
        step_cost=step_cost,
        stay_action=stay_action.astype(np.int64),
        stay_cost=stays[np.arange(tables.n_cells), stay_action],
        start_cell=int(tables.start_cell),
        steps=int(p.steps),
        needs_energy=bool(gamma < 1.0),
        exact=bool(deterministic and not tables.draws_uniforms and not uplink),
        uplink=bool(uplink),
    )


def _gain_distribution(channel: int, sigma_db: float, rician_k: float):  # type: ignore[no-untyped-def]
    """The fading power gain's quantile function and CDF, as the kernel draws it.

    Shadowing: g = 10^(sigma z / 10), z standard normal. Rician: g = |los + s (z1 + i z2)|^2
    with los^2 = K / (K + 1) and s^2 = 1 / (2 (K + 1)), i.e. s^2 times a non-central
    chi-square with 2 degrees of freedom and non-centrality 2K.
    """
    from scipy import special, stats

    if channel == 1:
        scale = sigma_db * math.log(10.0) / 10.0
        return (
            lambda u: fpmath.exp(scale * special.ndtri(u)),
            lambda g: special.ndtr(fpmath.log(np.maximum(g, 1e-300)) / scale),
        )
    s2 = 0.5 / (rician_k + 1.0)
    law = stats.ncx2(2, 2.0 * rician_k)
    return (lambda u: s2 * law.ppf(u), lambda g: law.cdf(np.maximum(g, 0.0) / s2))


def _expected_capped(amount, cap, quantile, cdf, kinks=()):  # type: ignore[no-untyped-def]
    """E[min(cap, amount(g))] per pair, for an amount non-decreasing in the gain g.

    ``amount`` maps a (pairs, m) array of gains to amounts; ``cap``: (pairs,). The integral
    runs over the gain's quantile u in [0, 1], in pieces split at ``kinks`` (gains where the
    amount jumps) and where the amount reaches the cap (beyond it the integrand is the
    constant cap).
    """
    n = len(cap)
    if n == 0:
        return np.zeros(0)
    # the gain at which the amount reaches the cap, by bisection in log-gain (monotone)
    lo, hi = np.full(n, -60.0), np.full(n, 60.0)
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        reach = amount(fpmath.exp(mid)[:, None])[:, 0] >= cap
        hi = np.where(reach, mid, hi)
        lo = np.where(reach, lo, mid)
    u_cap = np.where(amount(np.full((n, 1), math.exp(60.0)))[:, 0] >= cap, cdf(fpmath.exp(hi)), 1.0)
    cuts = [np.zeros(n)] + [np.minimum(cdf(k), u_cap) for k in kinks] + [u_cap]
    cuts = np.sort(np.stack(cuts, axis=1), axis=1)
    x, w = gauss_legendre(_QUADRATURE_NODES)
    total = cap * (1.0 - u_cap)
    for j in range(cuts.shape[1] - 1):
        a, b = cuts[:, j], cuts[:, j + 1]
        edges = a[:, None] + (b - a)[:, None] * np.linspace(0.0, 1.0, _QUADRATURE_PANELS + 1)[None, :]
        for k in range(_QUADRATURE_PANELS):
            left, right = edges[:, k : k + 1], edges[:, k + 1 : k + 2]
            u = left + (right - left) * (x[None, :] + 1.0) / 2.0
            values = np.minimum(amount(quantile(u)), cap[:, None])
            total = total + ((right - left)[:, 0] / 2.0) * fpmath.dot(values, w)
    return np.where(cap > 0, total, 0.0)
