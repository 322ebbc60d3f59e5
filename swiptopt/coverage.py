"""Which nodes the AUV covers, and the paper's coverage-probability analysis (paper eqs. 24-25).

A node is covered from an AUV position when it lies below the AUV inside the downward cone
(half-angle ``cone_half_angle_deg``), within ``cone_range_m`` of it, and its link SNR
reaches ``snr_threshold_db`` (docs/design.md, 'The acoustic link (Section II-B)').

The analysis asks: with n nodes placed uniformly in the free water, what is the probability
that at least k are covered from a position? Each node is covered independently with
probability p = V(cone within reach, clipped to the volume) / V(free water), so the count is
binomial. :func:`coverage_fraction` gives p in closed form when the cone is clipped by
depth only, and by seeded Monte Carlo integration when the side walls, a seabed or obstacles
clip it; :func:`simulated_coverage_probability` checks the whole chain by direct simulation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from swiptopt.link import link_budget, service_range_m
from swiptopt.scenario import Scenario, _uniform_free_points


def cone_mask(
    auv_positions_m: ArrayLike,
    node_positions_m: ArrayLike,
    half_angle_deg: float,
    range_m: float,
    omnidirectional: bool = False,
) -> np.ndarray:
    """Geometric coverage, (P, N) bool, for AUV positions (P, 3) and nodes (N, 3).

    True where the node is strictly below the AUV, within the cone's half-angle of the
    vertical and within ``range_m`` slant distance (``omnidirectional``: within the range,
    in any direction).
    """
    auv = np.asarray(auv_positions_m, dtype=float).reshape(-1, 3)[:, None, :]
    nodes = np.asarray(node_positions_m, dtype=float).reshape(-1, 3)[None, :, :]
    return _in_cone(nodes - auv, half_angle_deg, range_m, omnidirectional)


def _in_cone(rel_m: np.ndarray, half_angle_deg: float, range_m: float, omnidirectional: bool = False) -> np.ndarray:
    """The cone test on node-minus-AUV vectors (..., 3): one elementwise formula for every
    caller, so a pair gets the same answer however the pairs are batched. An
    ``omnidirectional`` link (magnetic induction: no beam) reaches every direction within
    the range."""
    dz = rel_m[..., 2]
    horizontal = np.hypot(rel_m[..., 0], rel_m[..., 1])
    slant = np.sqrt(horizontal**2 + dz**2)
    if omnidirectional:
        return slant <= range_m
    return (dz > 0) & (horizontal <= dz * math.tan(math.radians(half_angle_deg))) & (slant <= range_m)


def is_omnidirectional(scenario: Scenario) -> bool:
    """Whether the scenario's link reaches every direction (magnetic induction), not a cone."""
    return scenario.technology == "magnetic_induction"


def slant_distances_m(auv_positions_m: ArrayLike, node_positions_m: ArrayLike) -> np.ndarray:
    """Euclidean distances, (P, N), between AUV positions (P, 3) and nodes (N, 3)."""
    auv = np.asarray(auv_positions_m, dtype=float).reshape(-1, 3)
    nodes = np.asarray(node_positions_m, dtype=float).reshape(-1, 3)
    return np.linalg.norm(nodes[None, :, :] - auv[:, None, :], axis=-1)


#: Position-node pairs that :func:`covered_pairs` tests at once: its working memory is a few
#: arrays of this many elements (tens of MB), whatever the number of positions and nodes.
PAIRS_PER_BLOCK = 1 << 20


@dataclass(frozen=True, eq=False)
class CoveredPairs:
    """The covered (position, node) pairs, in row-major order (positions ascending, then nodes)."""

    rows: np.ndarray
    """(nnz,) int64 index of the AUV position."""
    nodes: np.ndarray
    """(nnz,) int64 index of the node."""
    distance_m: np.ndarray
    """(nnz,) slant distance of the pair, m."""


def covered_pairs(
    scenario: Scenario,
    auv_positions_m: ArrayLike,
    node_positions_m: ArrayLike | None = None,
    *,
    pairs_per_block: int = PAIRS_PER_BLOCK,
) -> CoveredPairs:
    """Coverage by cone, range and SNR threshold as a list of covered pairs (nodes default:
    the layout), for positions (P, 3) and nodes (N, 3).

    The same test as :func:`covered_nodes`, pair for pair, but run over blocks of about
    ``pairs_per_block`` pairs: the cone test on the block, then the link budget only on the
    pairs inside the cone. Memory grows with the covered pairs, not with P x N.
    """
    auv = np.asarray(auv_positions_m, dtype=float).reshape(-1, 3)
    nodes = np.asarray(scenario.layout.positions_m if node_positions_m is None else node_positions_m, dtype=float)
    nodes = nodes.reshape(-1, 3)
    block = max(1, int(pairs_per_block) // max(1, nodes.shape[0]))
    rows, cols, dist = [], [], []
    for lo in range(0, auv.shape[0], block):
        inside = cone_mask(auv[lo : lo + block], nodes, scenario.cone_half_angle_deg, scenario.cone_range_m,
                           is_omnidirectional(scenario))
        r, c = np.nonzero(inside)
        # the same arithmetic as slant_distances_m, on the pairs in the cone only
        d = np.linalg.norm(nodes[c] - auv[lo + r], axis=-1)
        ok = link_budget(scenario, d).in_service
        rows.append(r[ok] + lo)
        cols.append(c[ok])
        dist.append(d[ok])
    if not rows:
        return CoveredPairs(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    return CoveredPairs(
        np.concatenate(rows).astype(np.int64), np.concatenate(cols).astype(np.int64), np.concatenate(dist)
    )


def covered_nodes(
    scenario: Scenario, auv_positions_m: ArrayLike, node_positions_m: ArrayLike | None = None
) -> np.ndarray:
    """Coverage by cone, range and SNR threshold, (P, N) bool (nodes default: the layout).

    Computed by :func:`covered_pairs`, so only the bool result is P x N.
    """
    nodes = np.asarray(scenario.layout.positions_m if node_positions_m is None else node_positions_m, dtype=float)
    auv = np.asarray(auv_positions_m, dtype=float).reshape(-1, 3)
    pairs = covered_pairs(scenario, auv, nodes)
    out = np.zeros((auv.shape[0], nodes.reshape(-1, 3).shape[0]), dtype=bool)
    out[pairs.rows, pairs.nodes] = True
    return out


def cell_coverage(scenario: Scenario, *, pairs_per_block: int = PAIRS_PER_BLOCK) -> CoveredPairs:
    """The covered (cell, node) pairs from every free cell centre of the grid (rows are flat
    cell indices), in row-major order: :func:`covered_pairs` over the cell centres, without
    blocked cells, found without testing every cell against every node.

    For each node and each layer of cells above it, only the cells inside the square that
    bounds the cone's cross-section there (widened by a hair for rounding) are candidates,
    about 1.3 times the pairs the cone holds; each candidate then gets the very test of
    :func:`covered_pairs` (the cone formula, then the link budget), so the pairs are the
    same. Nodes are taken in groups of about ``pairs_per_block`` candidates, so memory
    grows with the covered pairs, not with cells x nodes.
    """
    c = scenario.cell_size_m
    nx, ny, nz = scenario.grid_shape
    nodes = np.asarray(scenario.layout.positions_m, dtype=float)
    centres = scenario.cell_centers_m
    blocked = scenario.blocked_cells
    tan = math.tan(math.radians(scenario.cone_half_angle_deg))
    reach_m = scenario.cone_range_m
    slack = 1.0 + 1e-9

    omni = is_omnidirectional(scenario)
    layer_z = (np.arange(nz) + 0.5) * c  # as in cell_centers_m
    dz = nodes[:, 2, None] - layer_z[None, :]  # (N, nz)
    with np.errstate(invalid="ignore"):
        sphere = np.sqrt(np.maximum(reach_m**2 - dz**2, 0.0))
        radius = (sphere if omni else np.minimum(dz * tan, sphere)) * slack + 1e-9 * c
    usable = (np.abs(dz) <= reach_m * slack) if omni else (dz > 0) & (dz <= reach_m * slack)

    def cell_range(coord: np.ndarray, n_cells: int) -> tuple[np.ndarray, np.ndarray]:
        lo = np.clip(np.ceil((coord[:, None] - radius) / c - 0.5), 0, n_cells - 1).astype(np.int64)
        hi = np.clip(np.floor((coord[:, None] + radius) / c - 0.5), 0, n_cells - 1).astype(np.int64)
        return lo, np.where(usable, hi - lo + 1, 0).clip(min=0)

    i_lo, i_n = cell_range(nodes[:, 0], nx)
    j_lo, j_n = cell_range(nodes[:, 1], ny)
    count = i_n * j_n  # (N, nz) candidate cells per node and layer
    per_node = count.sum(axis=1)

    rows, cols, dist = [], [], []
    first = 0
    while first < nodes.shape[0]:
        # the next group of nodes with about pairs_per_block candidates (at least one node)
        last = first + max(1, int(np.searchsorted(np.cumsum(per_node[first:]), pairs_per_block, side="right")))
        node_of, layer_of = np.nonzero(count[first:last])
        node_of += first
        n_cand = count[node_of, layer_of]
        owner = np.repeat(np.arange(n_cand.size), n_cand)
        t = np.arange(int(n_cand.sum())) - np.repeat(np.cumsum(n_cand) - n_cand, n_cand)
        width = j_n[node_of, layer_of][owner]
        i = i_lo[node_of, layer_of][owner] + t // width
        j = j_lo[node_of, layer_of][owner] + t % width
        cell = (i * ny + j) * nz + layer_of[owner]
        node = node_of[owner]
        free = ~blocked[cell]
        cell, node = cell[free], node[free]
        rel = nodes[node] - centres[cell]
        inside = _in_cone(rel, scenario.cone_half_angle_deg, reach_m, omni)
        cell, node = cell[inside], node[inside]
        d = np.linalg.norm(rel[inside], axis=-1)  # as slant_distances_m
        ok = link_budget(scenario, d).in_service
        rows.append(cell[ok])
        cols.append(node[ok])
        dist.append(d[ok])
        first = last
    if not rows:
        return CoveredPairs(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    cell, node, d = np.concatenate(rows), np.concatenate(cols), np.concatenate(dist)
    order = np.lexsort((node, cell))
    return CoveredPairs(cell[order].astype(np.int64), node[order].astype(np.int64), d[order])


def cone_volume_m3(depth_below_m: float, half_angle_deg: float, range_m: float) -> float:
    """Volume of the cone within ``range_m`` of its apex, cut ``depth_below_m`` below it, m^3.

    The region {0 < z <= h, r <= z tan(theta), r^2 + z^2 <= R^2}: a cone up to z* = R cos(theta),
    then a spherical cap, each integrated in closed form.
    """
    t2 = math.tan(math.radians(half_angle_deg)) ** 2
    z_star = range_m * math.cos(math.radians(half_angle_deg))
    h = max(0.0, min(depth_below_m, range_m))
    z1 = min(h, z_star)
    volume = math.pi * t2 * z1**3 / 3.0
    if h > z_star:
        volume += math.pi * ((range_m**2 * h - h**3 / 3.0) - (range_m**2 * z_star - z_star**3 / 3.0))
    return volume


@dataclass(frozen=True)
class CoverageFraction:
    """Probability that one uniformly placed node is covered from a position."""

    p: float
    method: str
    """``"analytic"`` or ``"monte-carlo"``."""
    std_error: float
    """Monte Carlo standard error of ``p`` (0 when analytic)."""


def coverage_fraction(
    scenario: Scenario,
    position_m: ArrayLike,
    *,
    rng: np.random.Generator | int | None = None,
    n_samples: int = 200_000,
) -> CoverageFraction:
    """p = V(covered free water) / V(free water) for a single position (3,) (the paper's
    analysis of the downward cone; an omnidirectional link's reach is a ball, always
    integrated by Monte Carlo)."""
    pos = np.asarray(position_m, dtype=float)
    reach = service_range_m(scenario)
    half = scenario.cone_half_angle_deg
    below = scenario.depth_m - pos[2]
    theta = math.radians(half)
    z_star = reach * math.cos(theta)
    widest = reach * math.sin(theta) if below >= z_star else max(below, 0.0) * math.tan(theta)
    inside = (
        pos[0] - widest >= 0
        and pos[0] + widest <= scenario.length_m
        and pos[1] - widest >= 0
        and pos[1] + widest <= scenario.width_m
    )
    if inside and not scenario.obstacles and scenario.seabed_height_m is None and not is_omnidirectional(scenario):
        volume = cone_volume_m3(below, half, reach)
        return CoverageFraction(float(volume / np.prod(scenario.extent_m)), "analytic", 0.0)
    gen = np.random.default_rng(rng)
    points = _uniform_free_points(scenario, n_samples, gen)
    hit = cone_mask(pos, points, half, reach, is_omnidirectional(scenario))[0]
    p = float(hit.mean())
    return CoverageFraction(p, "monte-carlo", math.sqrt(max(p * (1 - p), 1e-300) / n_samples))


def binomial_at_least(n: int, k: int, p: float) -> float:
    """P(X >= k) for X ~ Binomial(n, p)."""
    if k <= 0:
        return 1.0
    if k > n:
        return 0.0
    return float(sum(math.comb(n, j) * p**j * (1 - p) ** (n - j) for j in range(k, n + 1)))


def analytic_coverage_probability(
    scenario: Scenario,
    position_m: ArrayLike,
    n_nodes: int,
    k: int,
    *,
    rng: np.random.Generator | int | None = None,
) -> float:
    """P(at least k of n uniform nodes covered from ``position_m``), binomial (paper eq. 25)."""
    return binomial_at_least(n_nodes, k, coverage_fraction(scenario, position_m, rng=rng).p)


def simulated_coverage_probability(
    scenario: Scenario,
    position_m: ArrayLike,
    n_nodes: int,
    k: int,
    *,
    trials: int = 2000,
    rng: np.random.Generator | int | None = None,
) -> float:
    """The same probability by direct simulation: place n nodes, test coverage, count.

    Uses :func:`covered_nodes` (cone, range and the SNR of every link), independent of the
    volume formula of the analytic path.
    """
    gen = np.random.default_rng(rng)
    nodes = _uniform_free_points(scenario, trials * n_nodes, gen)
    covered = covered_nodes(scenario, np.asarray(position_m, float), nodes)[0]
    counts = covered.reshape(trials, n_nodes).sum(axis=1)
    return float(np.mean(counts >= k))


@dataclass(frozen=True)
class CoverageStatement:
    """One of the paper's coverage statements (Section III-B, on Fig. 5) checked from one position."""

    text: str
    """The statement, quoted from the paper."""
    n_nodes: int
    at_least: int
    """k in P(at least k of n covered)."""
    claimed_above: float
    """The probability the paper's words imply it exceeds (0.5 for "greater than 50 %" and,
    read generously, for "a high probability")."""
    analytic: float
    """P(at least k of n) from the binomial with the cone's volume fraction (eq. 25)."""

    @property
    def holds(self) -> bool:
        return self.analytic > self.claimed_above


#: The paper's coverage statements (Section III-B, on Fig. 5) as (quote, n, at least k, implied floor).
#: "More than 10 nodes" is read at n = 11, "> 30" at 31 and "exceeds 50" at 51.
PAPER_COVERAGE_STATEMENTS = (
    ("more than 10 nodes: P(covering at least one node) > 50 %", 11, 1, 0.5),
    ("the same at exactly 10 nodes: P(at least one) > 50 %", 10, 1, 0.5),
    ("more than 30 nodes: a high probability of covering more than 3 nodes", 31, 4, 0.5),
    ("more than 50 nodes: > 50 % probability of covering more than 4 nodes", 51, 5, 0.5),
)


def paper_coverage_statements(
    scenario: Scenario, position_m: ArrayLike, *, rng: np.random.Generator | int | None = 0
) -> list[CoverageStatement]:
    """The paper's coverage statements (Section III-B) evaluated from ``position_m`` (3,)."""
    return [
        CoverageStatement(text, n, k, floor, analytic_coverage_probability(scenario, position_m, n, k, rng=rng))
        for text, n, k, floor in PAPER_COVERAGE_STATEMENTS
    ]
