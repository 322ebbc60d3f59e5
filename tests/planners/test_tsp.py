"""planners.tsp: CP-SAT and routing against Held-Karp, each other and TSPLIB optima.

Held-Karp is itself checked against brute-force enumeration first, so every reference in
this file rests on something simpler than what it checks. Quality is asserted, speed is
not (beyond the solvers keeping loosely to their own time limits).
"""

from __future__ import annotations

import itertools
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planners.tsp import AUTO_EXACT_MAX_NODES, TspResult, held_karp, solve_tsp, tour_length
from swiptopt.errors import ConfigError

TSPLIB_FILE = Path(__file__).parent / "data" / "tsplib_instances.json"


def euclidean_matrix(points: np.ndarray) -> np.ndarray:
    """(n, n) Euclidean distances between the rows of ``points`` (n, d)."""
    return np.linalg.norm(points[:, None, :] - points[None, :, :], axis=-1)


def random_matrix(n: int, seed: int, asymmetric: bool = False) -> np.ndarray:
    """Distances between n uniform points in a 1000 x 1000 square; asymmetric: each arc
    scaled by an independent factor in [0.7, 1.5] (a current that helps one way)."""
    rng = np.random.default_rng(seed)
    matrix = euclidean_matrix(rng.uniform(0.0, 1000.0, (n, 2)))
    if asymmetric:
        matrix *= rng.uniform(0.7, 1.5, (n, n))
    return matrix


def tsplib_matrix(coords: list[list[float]]) -> np.ndarray:
    """TSPLIB EUC_2D distances: Euclidean, rounded to the nearest integer (nint)."""
    return np.floor(euclidean_matrix(np.asarray(coords, dtype=float)) + 0.5)


def load_tsplib() -> dict[str, dict]:
    with TSPLIB_FILE.open() as f:
        return {inst["name"]: inst for inst in json.load(f)["instances"]}


def brute_force(matrix: np.ndarray, start: int, closed: bool) -> float:
    rest = [v for v in range(len(matrix)) if v != start]
    return min(tour_length(matrix, [start, *perm], closed) for perm in itertools.permutations(rest))


def assert_valid(result: TspResult, matrix: np.ndarray, start: int, closed: bool) -> None:
    """The order is a permutation beginning at start, and length is its float length."""
    n = len(matrix)
    assert result.order[0] == start
    assert sorted(result.order) == list(range(n))
    assert all(isinstance(v, int) for v in result.order)
    assert result.length == pytest.approx(tour_length(matrix, result.order, closed), rel=1e-12, abs=1e-12)


# --- tour_length and the reference solver --------------------------------------------------


def test_tour_length_by_hand():
    matrix = np.array([[0, 1, 5], [2, 0, 3], [4, 7, 0]], dtype=float)
    assert tour_length(matrix, [0, 1, 2], closed=False) == 1 + 3
    assert tour_length(matrix, [0, 1, 2], closed=True) == 1 + 3 + 4
    assert tour_length(matrix, [2, 1, 0], closed=True) == 7 + 2 + 5
    assert tour_length(matrix, [1], closed=True) == 0.0


@pytest.mark.parametrize("n", [1, 2, 3, 5, 7])
@pytest.mark.parametrize("closed", [True, False])
def test_held_karp_matches_brute_force(n, closed):
    for seed in range(3):
        matrix = random_matrix(n, seed, asymmetric=seed % 2 == 1)
        start = seed % n
        order, length = held_karp(matrix, start=start, closed=closed)
        assert order[0] == start and sorted(order) == list(range(n))
        assert length == pytest.approx(tour_length(matrix, order, closed), rel=1e-12)
        assert length == pytest.approx(brute_force(matrix, start, closed), rel=1e-12)


def test_held_karp_refuses_large_instances():
    with pytest.raises(ConfigError) as err:
        held_karp(random_matrix(14, 0))
    assert err.value.field == "distance_matrix"


# --- exact and routing against Held-Karp ---------------------------------------------------

SMALL_CASES = [
    pytest.param(seed, closed, asym, id=f"seed{seed}-{'closed' if closed else 'open'}-{'asym' if asym else 'sym'}")
    for seed in (1, 2, 3)
    for closed in (True, False)
    for asym in (False, True)
]


@pytest.mark.parametrize(("seed", "closed", "asymmetric"), SMALL_CASES)
def test_exact_matches_held_karp(seed, closed, asymmetric):
    n = 12 if seed != 2 else 9
    matrix = random_matrix(n, seed, asymmetric)
    start = seed % n
    _, reference = held_karp(matrix, start=start, closed=closed)
    result = solve_tsp(matrix, start=start, closed=closed, method="exact", time_limit_s=5.0)
    assert_valid(result, matrix, start, closed)
    assert result.method == "exact"
    assert result.proven_optimal and result.status == "optimal"
    # Integer scaling moves each arc by <= 5e-7 of the longest, so n arcs stay within 1e-5.
    assert result.length == pytest.approx(reference, rel=1e-5)


@pytest.mark.parametrize(("seed", "closed", "asymmetric"), SMALL_CASES)
def test_routing_matches_held_karp(seed, closed, asymmetric):
    # Guided local search finds these optima in a few ms; 0.3 s leaves a wide margin.
    n = 12 if seed != 2 else 9
    matrix = random_matrix(n, seed, asymmetric)
    start = (seed * 5) % n
    _, reference = held_karp(matrix, start=start, closed=closed)
    result = solve_tsp(matrix, start=start, closed=closed, method="routing", time_limit_s=0.3)
    assert_valid(result, matrix, start, closed)
    assert result.method == "routing"
    assert not result.proven_optimal and result.status == "feasible"
    assert result.length == pytest.approx(reference, rel=1e-5)


@settings(max_examples=25, deadline=None)
@given(
    n=st.integers(4, 8),
    seed=st.integers(0, 2**32 - 1),
    closed=st.booleans(),
    integer_costs=st.booleans(),
)
def test_exact_equals_held_karp_property(n, seed, closed, integer_costs):
    """Asymmetric matrices, with many ties when the entries are small integers."""
    rng = np.random.default_rng(seed)
    matrix = rng.integers(0, 5, (n, n)).astype(float) if integer_costs else rng.uniform(0, 100, (n, n))
    start = int(rng.integers(n))
    _, reference = held_karp(matrix, start=start, closed=closed)
    result = solve_tsp(matrix, start=start, closed=closed, method="exact", time_limit_s=5.0)
    assert_valid(result, matrix, start, closed)
    assert result.proven_optimal
    assert result.length == pytest.approx(reference, rel=1e-5, abs=1e-9)


def test_exact_proves_optimality_on_15_points():
    matrix = random_matrix(15, 42)
    result = solve_tsp(matrix, method="exact", time_limit_s=10.0)
    assert_valid(result, matrix, 0, True)
    assert result.proven_optimal and result.status == "optimal"
    # No 2-opt move (reversing a segment) can shorten a proven optimal symmetric tour.
    order = list(result.order)
    for i, j in itertools.combinations(range(1, 15), 2):
        candidate = order[:i] + order[i : j + 1][::-1] + order[j + 1 :]
        assert tour_length(matrix, candidate, True) >= result.length - 1e-6


@pytest.mark.parametrize("n", [15, 20])
@pytest.mark.parametrize("closed", [True, False])
def test_routing_matches_exact_on_random_points(n, closed):
    matrix = random_matrix(n, 100 + n)
    start = n // 3
    exact = solve_tsp(matrix, start=start, closed=closed, method="exact", time_limit_s=10.0)
    routing = solve_tsp(matrix, start=start, closed=closed, method="routing", time_limit_s=0.5)
    assert exact.proven_optimal
    assert_valid(routing, matrix, start, closed)
    assert exact.length <= routing.length * (1 + 1e-5)
    assert routing.length == pytest.approx(exact.length, rel=1e-5)


def test_open_path_is_never_longer_than_closed_tour():
    matrix = random_matrix(10, 7)
    open_path = solve_tsp(matrix, start=3, closed=False, method="exact")
    tour = solve_tsp(matrix, start=3, closed=True, method="exact")
    # Dropping the tour's closing arc leaves an open path from the same start.
    assert open_path.length <= tour.length - matrix[tour.order[-1], 3] + 1e-6


def test_tiny_and_huge_scales_are_solved_alike():
    """The integer scale follows the matrix, so units (mm or km) do not change the answer."""
    matrix = random_matrix(11, 5, asymmetric=True)
    base = solve_tsp(matrix, method="exact")
    for factor in (1e-9, 1e9):
        scaled = solve_tsp(matrix * factor, method="exact")
        assert scaled.proven_optimal
        assert scaled.length == pytest.approx(base.length * factor, rel=1e-5)


def test_all_zero_matrix():
    result = solve_tsp(np.zeros((6, 6)), method="exact")
    assert result.length == 0.0 and result.proven_optimal
    assert sorted(result.order) == list(range(6))


# --- auto and trivial sizes ----------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 3])
@pytest.mark.parametrize("method", ["auto", "exact", "routing"])
def test_up_to_three_nodes_by_enumeration(n, method):
    matrix = random_matrix(n, 3, asymmetric=True)
    start = n - 1
    for closed in (True, False):
        result = solve_tsp(matrix, start=start, closed=closed, method=method)
        assert_valid(result, matrix, start, closed)
        assert result.method == "enumeration" and result.proven_optimal
        assert result.length == pytest.approx(brute_force(matrix, start, closed))
    assert solve_tsp(matrix, start=start, method=method).order[0] == start


def test_auto_picks_exact_up_to_threshold_then_routing():
    small = solve_tsp(random_matrix(AUTO_EXACT_MAX_NODES, 1))
    assert small.method == "exact" and small.proven_optimal
    large = solve_tsp(random_matrix(AUTO_EXACT_MAX_NODES + 1, 1), time_limit_s=0.2)
    assert large.method == "routing" and not large.proven_optimal
    assert sorted(large.order) == list(range(AUTO_EXACT_MAX_NODES + 1))


# --- TSPLIB benchmarks ---------------------------------------------------------------------


def test_tsplib_data_reproduces_best_known_lengths():
    """The stored coordinates with the stored optimal tours give the published optima."""
    instances = load_tsplib()
    assert {"eil51", "berlin52", "st70", "eil76", "kroA100"} <= set(instances)
    checked = 0
    for inst in instances.values():
        assert len(inst["coords"]) == int("".join(ch for ch in inst["name"] if ch.isdigit()))
        if "optimal_tour" in inst:
            matrix = tsplib_matrix(inst["coords"])
            assert tour_length(matrix, inst["optimal_tour"], closed=True) == inst["best_known"]
            checked += 1
    assert checked >= 4


@pytest.mark.parametrize(
    ("name", "time_limit_s", "max_gap"),
    [
        ("eil51", 1.0, 0.005),
        ("berlin52", 1.0, 0.005),
        ("st70", 1.0, 0.02),
        ("eil76", 1.0, 0.02),
        ("kroA100", 2.0, 0.02),
    ],
)
def test_routing_on_tsplib(name, time_limit_s, max_gap):
    inst = load_tsplib()[name]
    matrix = tsplib_matrix(inst["coords"])
    result = solve_tsp(matrix, method="routing", time_limit_s=time_limit_s)
    assert_valid(result, matrix, 0, True)
    assert result.length >= inst["best_known"]  # nothing beats a proven optimum
    assert result.length <= inst["best_known"] * (1 + max_gap)
    assert result.solve_time_s < time_limit_s + 1.5


def test_exact_respects_its_time_limit_and_reports_no_proof():
    matrix = tsplib_matrix(load_tsplib()["kroA100"]["coords"])
    result = solve_tsp(matrix, method="exact", time_limit_s=0.5)
    assert result.solve_time_s < 0.5 + 1.5
    assert not result.proven_optimal and result.status in ("feasible", "no_solution")
    if result.status == "feasible":
        assert_valid(result, matrix, 0, True)
    else:
        assert result.order == () and math.isinf(result.length)


# --- validation ----------------------------------------------------------------------------

GOOD = np.ones((4, 4))


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"distance_matrix": np.ones((3, 4))}, "distance_matrix"),
        ({"distance_matrix": np.ones(4)}, "distance_matrix"),
        ({"distance_matrix": np.ones((0, 0))}, "distance_matrix"),
        ({"distance_matrix": [[0, 1], [1, float("nan")]]}, "distance_matrix"),
        ({"distance_matrix": [[0, math.inf], [1, 0]]}, "distance_matrix"),
        ({"distance_matrix": [[0, -1], [1, 0]]}, "distance_matrix"),
        ({"distance_matrix": [["a", "b"], ["c", "d"]]}, "distance_matrix"),
        ({"start": 4}, "start"),
        ({"start": -1}, "start"),
        ({"start": 1.0}, "start"),
        ({"start": True}, "start"),
        ({"method": "greedy"}, "method"),
        ({"time_limit_s": 0}, "time_limit_s"),
        ({"time_limit_s": -1.0}, "time_limit_s"),
        ({"time_limit_s": math.inf}, "time_limit_s"),
        ({"time_limit_s": "1"}, "time_limit_s"),
    ],
)
def test_bad_arguments_raise_config_error_naming_the_field(kwargs, field):
    args = {"distance_matrix": GOOD, **kwargs}
    with pytest.raises(ConfigError) as err:
        solve_tsp(args.pop("distance_matrix"), **args)
    assert err.value.field == field
    assert field in str(err.value)
    assert isinstance(err.value, ValueError)


@settings(max_examples=40, deadline=None)
@given(start=st.integers().filter(lambda s: not 0 <= s < 4))
def test_any_out_of_range_start_is_refused(start):
    with pytest.raises(ConfigError, match="start"):
        solve_tsp(GOOD, start=start)


def test_import_planners_tsp_does_not_load_ortools():
    code = "import sys, planners, planners.tsp; print('ortools' in sys.modules)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "False" and result.stderr == ""
