"""Which nodes the AUV covers, and the paper's coverage-probability analysis (eqs. 19-21).

A node is covered from an AUV position when it lies below the AUV inside the downward cone
(half-angle ``cone_half_angle_deg``), within ``cone_range_m`` of it, and its link SNR
reaches ``snr_threshold_db`` (SPEC 3.5).

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
) -> np.ndarray:
    """Geometric coverage, (P, N) bool, for AUV positions (P, 3) and nodes (N, 3).

    True where the node is strictly below the AUV, within the cone's half-angle of the
    vertical and within ``range_m`` slant distance.
    """
    auv = np.asarray(auv_positions_m, dtype=float).reshape(-1, 3)[:, None, :]
    nodes = np.asarray(node_positions_m, dtype=float).reshape(-1, 3)[None, :, :]
    rel = nodes - auv
    dz = rel[..., 2]
    horizontal = np.hypot(rel[..., 0], rel[..., 1])
    slant = np.sqrt(horizontal**2 + dz**2)
    return (dz > 0) & (horizontal <= dz * math.tan(math.radians(half_angle_deg))) & (slant <= range_m)


def slant_distances_m(auv_positions_m: ArrayLike, node_positions_m: ArrayLike) -> np.ndarray:
    """Euclidean distances, (P, N), between AUV positions (P, 3) and nodes (N, 3)."""
    auv = np.asarray(auv_positions_m, dtype=float).reshape(-1, 3)
    nodes = np.asarray(node_positions_m, dtype=float).reshape(-1, 3)
    return np.linalg.norm(nodes[None, :, :] - auv[:, None, :], axis=-1)


def covered_nodes(
    scenario: Scenario, auv_positions_m: ArrayLike, node_positions_m: ArrayLike | None = None
) -> np.ndarray:
    """Coverage by cone, range and SNR threshold, (P, N) bool (nodes default: the layout)."""
    nodes = scenario.layout.positions_m if node_positions_m is None else node_positions_m
    geometric = cone_mask(auv_positions_m, nodes, scenario.cone_half_angle_deg, scenario.cone_range_m)
    snr_ok = link_budget(scenario, slant_distances_m(auv_positions_m, nodes)).in_service
    return geometric & snr_ok


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
    """p = V(covered free water) / V(free water) for a single position (3,)."""
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
    if inside and not scenario.obstacles and scenario.seabed_height_m is None:
        volume = cone_volume_m3(below, half, reach)
        return CoverageFraction(float(volume / np.prod(scenario.extent_m)), "analytic", 0.0)
    gen = np.random.default_rng(rng)
    points = _uniform_free_points(scenario, n_samples, gen)
    hit = cone_mask(pos, points, half, reach)[0]
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
    """P(at least k of n uniform nodes covered from ``position_m``), binomial (paper eq. 21)."""
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
