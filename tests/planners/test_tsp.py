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

from planners.tsp import (
    AUTO_EXACT_MAX_NODES,
    AUTO_POLISH_MAX_NODES,
    TspResult,
    _integer_costs,
    _solve_exact,
    held_karp,
    solve_tsp,
    tour_length,
)
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
    result = solve_tsp(matrix, start=start, closed=closed, method="exact")
    assert_valid(result, matrix, start, closed)
    assert result.method == "exact"
    assert result.proven_optimal and result.status == "optimal"
    # Integer scaling moves each arc by <= 5e-7 of the longest, so n arcs stay within 1e-5.
    assert result.length == pytest.approx(reference, rel=1e-5)


@pytest.mark.parametrize(("seed", "closed", "asymmetric"), SMALL_CASES)
def test_routing_matches_held_karp(seed, closed, asymmetric):
    # Guided local search finds these optima within 200 solutions; 400 leaves a margin.
    n = 12 if seed != 2 else 9
    matrix = random_matrix(n, seed, asymmetric)
    start = (seed * 5) % n
    _, reference = held_karp(matrix, start=start, closed=closed)
    result = solve_tsp(matrix, start=start, closed=closed, method="routing", solution_limit=400)
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
    result = solve_tsp(matrix, start=start, closed=closed, method="exact")
    assert_valid(result, matrix, start, closed)
    assert result.proven_optimal
    assert result.length == pytest.approx(reference, rel=1e-5, abs=1e-9)


def test_exact_proves_optimality_on_15_points():
    matrix = random_matrix(15, 42)
    result = solve_tsp(matrix, method="exact")
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
    exact = solve_tsp(matrix, start=start, closed=closed, method="exact")
    routing = solve_tsp(matrix, start=start, closed=closed, method="routing", solution_limit=400)
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


def test_auto_picks_exact_then_routing_and_exact_then_routing():
    small = solve_tsp(random_matrix(AUTO_EXACT_MAX_NODES, 1))
    assert small.method == "exact" and small.proven_optimal and small.status == "optimal"
    medium = solve_tsp(random_matrix(AUTO_EXACT_MAX_NODES + 1, 1))
    assert medium.method == "routing+exact" and medium.proven_optimal
    assert medium.length == pytest.approx(solve_tsp(random_matrix(AUTO_EXACT_MAX_NODES + 1, 1), method="exact").length)
    large = solve_tsp(random_matrix(AUTO_POLISH_MAX_NODES + 1, 1), solution_limit=20)
    assert large.method == "routing" and not large.proven_optimal and large.status == "feasible"
    assert sorted(large.order) == list(range(AUTO_POLISH_MAX_NODES + 1))


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
    ("name", "max_gap"),
    [("eil51", 0.005), ("berlin52", 0.005), ("st70", 0.005), ("eil76", 0.02), ("kroA100", 0.02)],
)
def test_routing_on_tsplib(name, max_gap):
    """Routing alone, on its default deterministic budget."""
    inst = load_tsplib()[name]
    matrix = tsplib_matrix(inst["coords"])
    result = solve_tsp(matrix, method="routing")
    assert_valid(result, matrix, 0, True)
    assert result.status == "feasible"
    assert result.length >= inst["best_known"]  # nothing beats a proven optimum
    assert result.length <= inst["best_known"] * (1 + max_gap)


@pytest.mark.parametrize(("name", "max_gap"), [("st70", 0.005), ("kroA100", 0.02)])
def test_auto_on_tsplib(name, max_gap):
    """The default method: 70 points go to routing then CP-SAT, which proves the optimum;
    100 points to routing alone."""
    inst = load_tsplib()[name]
    matrix = tsplib_matrix(inst["coords"])
    result = solve_tsp(matrix)
    assert_valid(result, matrix, 0, True)
    assert inst["best_known"] <= result.length <= inst["best_known"] * (1 + max_gap)
    if len(matrix) <= AUTO_POLISH_MAX_NODES:
        assert result.method == "routing+exact" and result.proven_optimal
        assert result.length == inst["best_known"]


@pytest.mark.parametrize("budget", [1e-6, 0.05])
def test_exact_stops_on_its_deterministic_budget_without_proof(budget):
    """Too small a budget for CP-SAT to take up its hint returns the hint (the greedy
    order); a small one returns CP-SAT's best so far: either way an order, every time."""
    inst = load_tsplib()["eil51"]
    matrix = tsplib_matrix(inst["coords"])
    results = [solve_tsp(matrix, method="exact", deterministic_time=budget) for _ in range(2)]
    for result in results:
        assert not result.proven_optimal and result.status == "feasible"
        assert_valid(result, matrix, 0, True)
        assert result.length > inst["best_known"]
    assert results[0].order == results[1].order


@pytest.mark.parametrize("method", ["exact", "routing"])
def test_the_wall_clock_safety_net_is_reported_in_the_status(method):
    """A search cut short by ``time_limit_s`` (here absurdly short against a huge budget)
    says so: its order is valid but not reproducible."""
    matrix = tsplib_matrix(load_tsplib()["kroA100"]["coords"])
    result = solve_tsp(matrix, method=method, time_limit_s=0.05, deterministic_time=100.0, solution_limit=10**6)
    assert not result.proven_optimal and result.status in ("time_limit", "no_solution")
    if result.status == "time_limit":
        assert_valid(result, matrix, 0, True)


# --- reproducibility ---------------------------------------------------------------------


def grid_matrix(side: int) -> np.ndarray:
    """Points on a side x side lattice: a huge number of tours tie for shortest."""
    points = np.array([(x, y) for x in range(side) for y in range(side)], dtype=float) * 10.0
    return euclidean_matrix(points)


@pytest.mark.parametrize("closed", [True, False])
def test_tied_optima_resolve_to_one_order_whatever_the_start_of_the_search(closed):
    """On a lattice every optimal tour has many equally short rivals (its reverse, and
    others); the tie-broken costs make the proven optimum one order, whether CP-SAT starts
    from its greedy order, from the optimum reversed, or from another optimal order."""
    matrix = grid_matrix(4)
    first = solve_tsp(matrix, closed=closed, method="exact")
    assert first.proven_optimal
    costs = _integer_costs(matrix, tie_break=True)
    transpose = np.arange(16).reshape(4, 4).T.ravel()  # the lattice mirrored in its diagonal
    if closed:
        reverse = [first.order[0], *first.order[:0:-1]]
        rivals = [reverse, list(transpose[list(first.order)]), list(transpose[reverse])]
    else:
        # a boustrophedon through the lattice: every arc one 10 m step
        snake = [y * 4 + (x if y % 2 == 0 else 3 - x) for y in range(4) for x in range(4)]
        rivals = [snake, list(transpose[snake])]
    assert any(tuple(rival) != first.order for rival in rivals)
    for rival in rivals:
        assert tour_length(matrix, rival, closed) == pytest.approx(first.length)
        order, status, proven = _solve_exact(costs, 0, closed, 10.0, 60.0, rival)
        assert proven and tuple(order) == first.order


def _burn_cpu() -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", "while True: pass"])


@pytest.mark.parametrize(("method", "n"), [("exact", 30), ("routing", 60), ("auto", 45)])
def test_the_same_instance_gives_the_same_order_with_and_without_cpu_load(method, n):
    """Budgets count work, not seconds: the order does not depend on the machine's load."""
    matrix = random_matrix(n, 2024 + n, asymmetric=True)
    quiet = solve_tsp(matrix, start=3, closed=False, method=method)
    burners = [_burn_cpu() for _ in range(2)]
    try:
        loaded = solve_tsp(matrix, start=3, closed=False, method=method)
    finally:
        for burner in burners:
            burner.kill()
            burner.wait()
    again = solve_tsp(matrix, start=3, closed=False, method=method)
    assert quiet.status in ("optimal", "feasible")
    assert quiet.order == loaded.order == again.order
    assert quiet.status == loaded.status == again.status


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
        ({"deterministic_time": 0}, "deterministic_time"),
        ({"deterministic_time": math.nan}, "deterministic_time"),
        ({"deterministic_time": "1"}, "deterministic_time"),
        ({"solution_limit": 0}, "solution_limit"),
        ({"solution_limit": 10.0}, "solution_limit"),
        ({"solution_limit": True}, "solution_limit"),
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


@pytest.mark.parametrize("n_nodes", [30, 50])
def test_kmeans_tsp_plans_identically_across_runs(n_nodes):
    """The benchmark's k-means + TSP planner on the paper preset: the same plan on a quiet
    and on a loaded machine (these sizes once gave different tours from run to run)."""
    from planners.policies import KMeansTspPlanner
    from swiptopt.env import AuvSwiptEnv
    from swiptopt.scenario import Scenario

    def plan():
        env = AuvSwiptEnv(Scenario.preset("paper", n_nodes=n_nodes, layout_seed=2))
        return KMeansTspPlanner(seed=2).make_plan(env)

    quiet = plan()
    burners = [_burn_cpu() for _ in range(2)]
    try:
        loaded = plan()
    finally:
        for burner in burners:
            burner.kill()
            burner.wait()
    assert quiet.status.startswith("tsp optimal")
    assert quiet.stops == loaded.stops and quiet.status == loaded.status
    assert quiet.details["tour_length"] == loaded.details["tour_length"]
