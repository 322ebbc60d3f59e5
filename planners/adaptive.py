"""The best adaptive policy of a small instance, exactly: dynamic programming over the kernel.

A *non-anticipative* policy chooses each action from what has happened so far (the AUV's
cell, each node's data left and charge, the step); the step's draws (link failures, fading)
come after. When every covered node's step has finitely many outcomes with probabilities
known in closed form, the best such policy's expected return is the value of a finite MDP
over the states (step, cell, each node's data left and charge), and backward induction
computes it exactly. :func:`adaptive_optimum` does so in two regimes and refuses every other
scenario, naming why:

- **no fading** (``channel = "none"``, or shadowing with ``shadowing_sigma_db = 0``), with
  link failures: a covered node's link works with probability 1 - f_i or fails, and
  everything else (data, charge, gate, drain, uplink packets, battery) follows
  deterministically from the state;
- **fading with all-or-nothing data**: every link that works at all (no failure, and
  instantaneous SNR g SNR_p at or above the threshold) carries all of the node's data in one
  step, ``dt B log2(1 + alpha SNR_th) >= D_i`` for every coverable node, so a node's data
  left is D_i or 0; and the charge cannot matter: Gamma = 1 (only data counts, in the reward
  and in "served") or every storage full, with the downlink, no gate and no drain. The
  success probability is (1 - f_i) P(g >= SNR_th / SNR_p) in closed form for the gain the
  kernel draws (:func:`gain_survival`): exp(-x) for Rayleigh (Rician K = 0), Marcum's Q for
  Rician K > 0, the normal tail for shadowing. Nothing is discretised.

The DP does not write the world's rules a second time: each branch of a step is one call of
the kernel's :func:`swiptopt.kernel.step` on a copy of the state, with draws built to give
the branch's outcome (a failure uniform of 0, a gain above or below the threshold), and the
branch's probability comes from the draws' laws. Termination (every node served),
truncation, rewards and the battery are the kernel's own.

:data:`TINY_FADING` is the ``tiny`` variant the tests and ``benchmarks/optimum.py`` solve:
Rayleigh fading and link failures, with the SNR threshold raised to where a fade makes an
outage (docs/optimum.md).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from swiptopt import fpmath
from swiptopt import kernel as K
from swiptopt.acoustics import link_rate_bps
from swiptopt.errors import ConfigError
from swiptopt.scenario import Scenario

#: Overrides of the ``tiny`` preset: Rayleigh fading (Rician with K = 0) and link failures of
#: 5-25 % per step; the SNR threshold at 97 dB, where the links of this layout (97-106 dB
#: mean SNR) lose 13-60 % of their steps to fades (at 10 dB a Rayleigh fade would almost
#: never matter there); Gamma = 1, so that only data counts; a movement weight
#: of 0.1 (five times the default), so that a wasted move costs something; layout 2, where
#: every node is coverable (so an episode can end early) and one cell covers two nodes.
TINY_FADING: dict[str, Any] = {
    "channel": "rician",
    "rician_k": 0.0,
    "failure_prob_min": 0.05,
    "failure_prob_max": 0.25,
    "snr_threshold_db": 97.0,
    "reward_weight": 1.0,
    "movement_weight": 0.1,
    "layout_seed": 2,
}

#: Kernel steps :func:`adaptive_optimum` may take before it gives up.
ADAPTIVE_STEP_LIMIT = 2_000_000

NO_FADING, ALL_OR_NOTHING = "no fading", "all-or-nothing fading"


def gain_survival(tables: K.Tables, threshold_gain: np.ndarray) -> np.ndarray:
    """P(g >= x) for the fading power gain g the kernel draws, elementwise over x (>= 0).

    No fading: g = 1. Shadowing: g = 10^(sigma z / 10), z standard normal, so P = Q(ln x /
    (sigma ln 10 / 10)). Rician K: g = |los + s (z1 + i z2)|^2 with los^2 = K / (K + 1) and
    s^2 = 1 / (2 (K + 1)), so g / s^2 is non-central chi-square (2 dof, non-centrality 2K):
    P = exp(-x) for K = 0 (Rayleigh), Marcum's Q (``scipy.stats.ncx2.sf``) otherwise.
    """
    x = np.asarray(threshold_gain, dtype=float)
    p = tables.named
    channel = int(p.channel)
    if channel == 0 or (channel == 1 and p.shadowing_sigma_db == 0.0):
        return (x <= 1.0).astype(float)
    if channel == 1:
        scale = p.shadowing_sigma_db * K.LN10_OVER_10
        with np.errstate(divide="ignore"):
            z = fpmath.log(np.maximum(x, 0.0)) / scale
        return np.array([0.5 * math.erfc(v / math.sqrt(2.0)) for v in z.ravel()]).reshape(x.shape)
    k = p.rician_k
    if k == 0.0:
        return np.array([math.exp(-v) for v in x.ravel()]).reshape(x.shape)
    from scipy.stats import ncx2

    return np.asarray(ncx2.sf(x * 2.0 * (k + 1.0), 2, 2.0 * k), dtype=float)


def _regime(tables: K.Tables) -> str:
    """The regime of the tables (module docstring), or a ConfigError naming why neither holds."""
    p = tables.named
    channel = int(p.channel)
    if channel == 0 or (channel == 1 and p.shadowing_sigma_db == 0.0):
        return NO_FADING
    if p.link != K.LINK_CODES["downlink_split"]:
        raise ConfigError(
            "adaptive_optimum with fading needs link = 'downlink_split': uplink packets vary with the gain", "link"
        )
    if p.gate_j > 0 or p.drain_j > 0:
        raise ConfigError(
            "adaptive_optimum with fading needs energy_gate_j = 0 and idle_drain_w = 0: the charge, which "
            "fading makes continuous, would matter", "energy_gate_j",
        )
    room = tables.capacity - tables.energy0
    if p.reward_weight < 1.0 and np.any(room > 0):
        raise ConfigError(
            f"adaptive_optimum with fading needs reward_weight = 1 or full storage: at Gamma = {p.reward_weight:g} the "
            "charge, which fading makes continuous, counts", "reward_weight",
        )
    coverable = np.unique(tables.cov_node)
    least_bits = p.dt_s * link_rate_bps(p.bandwidth_hz, p.split_ratio * p.snr_threshold)
    short = coverable[tables.data0[coverable] > least_bits]
    if short.size:
        raise ConfigError(
            f"adaptive_optimum with fading needs all-or-nothing data: node {int(short[0])} holds "
            f"{tables.data0[short[0]]:g} bit, more than the {least_bits:g} bit a step carries at the SNR threshold",
            "data_bits",
        )
    return ALL_OR_NOTHING


@dataclass(frozen=True, eq=False)
class _Branching:
    """What one step's draws can do, per covered pair: the success probability of its link
    and draws that make it work or not (the kernel reads them in coverage order)."""

    p_ok: np.ndarray
    """(nnz,) probability that the pair's link carries data (no failure, no outage)."""
    ok_u: np.ndarray
    ok_z: np.ndarray
    """(nnz,) / (nnz, rows): draws under which it does."""
    no_u: np.ndarray
    no_z: np.ndarray
    """draws under which it does not."""

    @classmethod
    def of(cls, tables: K.Tables, regime: str) -> _Branching:
        p = tables.named
        nodes = tables.cov_node
        rows = max(tables.normal_rows, 1)
        fail = tables.fail_prob[nodes] if tables.draws_uniforms else np.zeros(len(nodes))
        ok_u = np.full(len(nodes), np.nextafter(1.0, 0.0))  # the largest uniform: never a failure
        no_u = np.where(fail > 0, 0.0, ok_u)  # a failure when one is possible
        ok_z = np.zeros((len(nodes), rows))
        no_z = np.zeros((len(nodes), rows))
        if regime == NO_FADING:
            p_ok = 1.0 - fail
        else:
            need = p.snr_threshold / tables.cov_snr  # the gain at which the link reaches the threshold
            p_ok = (1.0 - fail) * gain_survival(tables, need)
            # gains of 4x and 1/4 the needed one: the kernel's gain lands far from the threshold
            if int(p.channel) == 1:
                scale = p.shadowing_sigma_db * K.LN10_OVER_10
                ok_z[:, 0] = fpmath.log(4.0 * need) / scale
                no_z[:, 0] = fpmath.log(need / 4.0) / scale
            else:
                k = p.rician_k
                los, scatter = math.sqrt(k / (k + 1.0)), math.sqrt(0.5 / (k + 1.0))
                ok_z[:, 0] = (np.sqrt(4.0 * need) - los) / scatter
                no_z[:, 0] = (np.sqrt(need / 4.0) - los) / scatter
        return cls(np.clip(p_ok, 0.0, 1.0), ok_u, ok_z, no_u, no_z)


@dataclass(frozen=True, eq=False)
class AdaptiveOptimum:
    """The best non-anticipative policy's expected return and the policy itself."""

    value: float
    """Its expected return from the start, exact (up to float summation)."""
    regime: str
    """``"no fading"`` or ``"all-or-nothing fading"`` (module docstring)."""
    states: int
    """States (step, cell, data left, charge) reached from the start."""
    kernel_steps: int
    """Kernel steps taken to enumerate every branch."""
    tracks_charge: bool
    """Whether the state holds the charge (else it cannot matter: module docstring)."""
    policy: dict[tuple[int, bytes], int] = field(repr=False, default_factory=dict)
    """The best action of each state reached, by (step, :func:`state_key`)."""

    def action(self, state: K.EpisodeState) -> int:
        """The best action in the kernel state ``state`` (one the DP reached)."""
        key = (state.t, state_key(state, self.tracks_charge))
        if key not in self.policy:
            raise KeyError(f"state at step {state.t} in cell {state.cell} was not reached by the DP")
        return self.policy[key]


def state_key(state: K.EpisodeState, charge: bool) -> bytes:
    """The DP's name of a kernel state: its cell, each node's data left (to 1 mbit) and,
    when ``charge``, its stored energy (to 1 nJ): float sums of the same service in another
    order differ in the last bits only."""
    key = int(state.where[K.W_CELL]).to_bytes(4, "little") + np.round(state.data_left, 3).tobytes()
    return key + np.round(state.energy, 9).tobytes() if charge else key


class _Stepper:
    """Expands a kernel state by an action into its branches: (probability, next state, reward, code)."""

    def __init__(self, tables: K.Tables, regime: str):
        self.tables = tables
        self.branching = _Branching.of(tables, regime)
        n = max(int(np.diff(tables.cov_ptr).max(initial=0)), 1)
        self.uniforms = np.ones(n)
        self.normals = np.zeros(n * max(tables.normal_rows, 1))
        self.rows = tables.normal_rows
        self.steps = 0

    def branches(self, state: K.EpisodeState, action: int) -> list[tuple[float, K.EpisodeState, float, int]]:
        t, b = self.tables, self.branching
        cell = int(t.next_cell[state.cell, action])
        pairs = np.arange(t.cov_ptr[cell], t.cov_ptr[cell + 1])
        open_ = [j for j, q in enumerate(pairs) if state.data_left[t.cov_node[q]] > 0.0 and 0.0 < b.p_ok[q] < 1.0]
        out = []
        for outcome in itertools.product((True, False), repeat=len(open_)):
            works = np.ones(len(pairs), dtype=bool)
            prob = 1.0
            for j, ok in zip(open_, outcome):
                works[j] = ok
                prob *= b.p_ok[pairs[j]] if ok else 1.0 - b.p_ok[pairs[j]]
            for j, q in enumerate(pairs):
                # a pair that does not branch: its link works unless it never can
                good = works[j] and b.p_ok[q] > 0.0
                self.uniforms[j] = b.ok_u[q] if good else b.no_u[q]
                if self.rows:
                    self.normals[j * self.rows : (j + 1) * self.rows] = (b.ok_z[q] if good else b.no_z[q])[: self.rows]
            s = state.copy()
            s.where[K.W_UPTR] = s.where[K.W_ZPTR] = 0
            code = K.step(action, self.uniforms, self.normals, K.step_args(t, s))
            self.steps += 1
            out.append((prob, s, float(s.parts.sum()), int(code)))
        return out


def _tracks_charge(tables: K.Tables, regime: str) -> bool:
    p = tables.named
    if regime == ALL_OR_NOTHING:
        return False
    # the charge matters to the reward, to "served", to the gate, to the uplink or to the drain
    room = tables.capacity - tables.energy0
    return bool(
        (p.reward_weight < 1.0 and np.any(room > 0)) or p.gate_j > 0 or p.drain_j > 0
        or p.link == K.LINK_CODES["uplink"]
    )


def adaptive_optimum(
    scenario: Scenario, *, tables: K.Tables | None = None, max_kernel_steps: int = ADAPTIVE_STEP_LIMIT
) -> AdaptiveOptimum:
    """The best non-anticipative policy of ``scenario`` and its expected return, exactly.

    Forward, every state (cell, data left, charge) reachable at each step is enumerated by
    stepping the kernel on every action and every outcome of the covered nodes' links;
    backward, each state's value is the best action's expected reward plus the next states'
    values (0 once the episode ends). Ties go to the lowest action. Raises
    :class:`~swiptopt.errors.ConfigError` for a scenario outside both regimes (module
    docstring) or when more than ``max_kernel_steps`` kernel steps would be needed.
    ``tables``: the scenario's kernel tables when the caller has them (or made them).
    """
    t = K.build_tables(scenario) if tables is None else tables
    regime = _regime(t)
    charge = _tracks_charge(t, regime)
    stepper = _Stepper(t, regime)
    steps = int(t.named.steps)
    start = K.new_state(t)
    layers: list[dict[bytes, K.EpisodeState]] = [{state_key(start, charge): start}]
    edges: list[dict[bytes, list[list[tuple[float, float, bytes | None]]]]] = []
    for _ in range(steps):
        nxt: dict[bytes, K.EpisodeState] = {}
        layer_edges: dict[bytes, list[list[tuple[float, float, bytes | None]]]] = {}
        for key, state in layers[-1].items():
            per_action = []
            for a in range(K.N_ACTIONS):
                out = []
                for prob, s, reward, code in stepper.branches(state, a):
                    if code == K.RUNNING:
                        k = state_key(s, charge)
                        nxt.setdefault(k, s)
                        out.append((prob, reward, k))
                    else:
                        out.append((prob, reward, None))
                per_action.append(out)
            layer_edges[key] = per_action
            if stepper.steps > max_kernel_steps:
                raise ConfigError(
                    f"adaptive_optimum needs more than max_kernel_steps = {max_kernel_steps} kernel steps",
                    "max_kernel_steps",
                )
        edges.append(layer_edges)
        layers.append(nxt)
        if not nxt:
            break
    value: dict[bytes, float] = {}
    policy: dict[tuple[int, bytes], int] = {}
    for step in range(len(edges) - 1, -1, -1):
        later = value
        value = {}
        for key, per_action in edges[step].items():
            totals = [
                sum(prob * (reward + (later[k] if k is not None else 0.0)) for prob, reward, k in out)
                for out in per_action
            ]
            best = int(np.argmax(totals))
            value[key] = totals[best]
            policy[(step, key)] = best
    start_key = state_key(start, charge)
    return AdaptiveOptimum(
        float(value[start_key]), regime, sum(len(layer) for layer in layers), stepper.steps, charge, policy
    )


def open_loop_value(scenario: Scenario, actions: list[int], *, tables: K.Tables | None = None) -> float:
    """The exact expected return of playing ``actions`` whatever the draws (an open-loop
    plan; the episode still ends when every node is served), in the regimes of
    :func:`adaptive_optimum`: the distribution over states is carried forward step by step."""
    t = K.build_tables(scenario) if tables is None else tables
    regime = _regime(t)
    charge = _tracks_charge(t, regime)
    stepper = _Stepper(t, regime)
    start = K.new_state(t)
    states: dict[bytes, tuple[float, K.EpisodeState]] = {state_key(start, charge): (1.0, start)}
    total = 0.0
    for a in actions[: int(t.named.steps)]:
        nxt: dict[bytes, tuple[float, K.EpisodeState]] = {}
        for weight, state in states.values():
            for prob, s, reward, code in stepper.branches(state, int(a)):
                total += weight * prob * reward
                if code == K.RUNNING:
                    k = state_key(s, charge)
                    nxt[k] = (nxt[k][0] + weight * prob, nxt[k][1]) if k in nxt else (weight * prob, s)
        states = nxt
    return total


class AdaptivePolicy:
    """The DP's policy (:func:`adaptive_optimum`) as a planner for :func:`swiptopt.evaluate`:
    it solves once per environment, then reads the environment's state each step."""

    def __init__(self, *, max_kernel_steps: int = ADAPTIVE_STEP_LIMIT):
        self.max_kernel_steps = max_kernel_steps
        self._env: Any = None

    def begin_episode(self, env: Any, obs: Any = None, info: Any = None) -> None:
        if env is not self._env:
            self._env = env
            self.result_ = adaptive_optimum(env.scenario, tables=env.tables, max_kernel_steps=self.max_kernel_steps)

    def predict(self, obs: Any, deterministic: bool = True) -> int:
        if self._env is None or self._env.state is None:
            raise RuntimeError("call begin_episode(env, obs, info) after each reset (swiptopt.evaluate does)")
        return self.result_.action(self._env.state)
