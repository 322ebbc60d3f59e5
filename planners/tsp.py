"""Shortest tour (or open path from the start) through every node of a distance matrix.

The AUV visits the start and the hover points once each (SPEC 6, ``tsp``). Two OR-Tools
back ends, each a thin wrapper that keeps the solver idiom visible:

- ``"exact"``: CP-SAT, one boolean literal per arc tied together by a circuit constraint
  (``add_circuit``, formerly ``AddCircuit``), minimising the integer-scaled arc costs. Proves optimality on small
  instances; ``proven_optimal`` is true only when CP-SAT says OPTIMAL.
- ``"routing"``: the OR-Tools routing library, PATH_CHEAPEST_ARC for a first tour, then
  guided local search until the time limit. Fast and near-optimal on large instances,
  never a proof.
- ``"auto"``: exact up to :data:`AUTO_EXACT_MAX_NODES` nodes, routing above.

Instances of at most three nodes are solved by enumeration whatever the method (one or two
candidate orders), reported as method ``"enumeration"``.

Costs. Both solvers need integer arc costs, so the float matrix is multiplied by
``COST_SCALE_TARGET / max(off-diagonal entries)`` and rounded: the largest entry becomes 1e6 and each arc
is off by at most 0.5 unit, a relative error of 5e-7 of the longest arc. The reported
``length`` is always recomputed from the float matrix.

Open paths (``closed=False``: start at ``start``, end anywhere) add a dummy node reached at
zero cost from every node and leaving only to the start, so the best circuit through it is
the best path.

:func:`held_karp` is an independent dynamic-programming solver for small instances, the
reference the tests hold both back ends to.

OR-Tools is imported inside the solver functions so ``import planners`` stays light.
"""

from __future__ import annotations

import itertools
import math
import numbers
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from swiptopt.errors import ConfigError

METHODS = ("auto", "exact", "routing")
"""Accepted values of ``solve_tsp(method=...)``."""

AUTO_EXACT_MAX_NODES = 20
"""Largest instance ``method="auto"`` gives to CP-SAT. Measured on a 2-core machine with a
second solver process running beside it, 20 seeds each of uniform, clustered, open-path
and asymmetric instances: at 20 nodes the proof took at most 0.35 s (median 0.06-0.09 s),
well inside the default 1 s limit; at 25 nodes up to 0.65 s, at 40 nodes up to 2.6 s.
Above it routing's near-optimal tour within the limit is the safer bet."""

CP_SAT_WORKERS = 8
"""CP-SAT portfolio size, fixed rather than CP-SAT's default of one worker per core. Its
8-worker portfolio adds LP-based subsolvers (in a logged run on 20 clustered points,
``reduced_costs`` closed the bound) that the 2-worker default of a 2-core machine lacks:
there, 20 clustered points took up to 4 s to prove, against 0.06 s with 8 workers. All the
timings quoted here are with 8 workers."""

GLS_LAMBDA = 0.3
"""Guided local search penalty weight (OR-Tools default 0.1), used with the multi-armed
bandit choice among local search operators. Measured on 60 random Euclidean instances of
20-60 points with CP-SAT-proven optima, at 0.3-1 s limits: mean gap to the optimum
0.0-0.6 % against 0.2-1.1 % with the defaults (lambda 0.1, no bandit), and fewer runs stuck
a few % off; on eil51 and berlin52 it reaches 0.2 % and 0 % in 0.3 s."""

COST_SCALE_TARGET = 1_000_000
"""The largest matrix entry becomes this many integer cost units (see the module docstring)."""

HELD_KARP_MAX_NODES = 13
"""Largest instance :func:`held_karp` accepts (2^12 subsets x 12 end nodes)."""


@dataclass(frozen=True)
class TspResult:
    """A tour or open path found by :func:`solve_tsp`."""

    order: tuple[int, ...]
    """Node indices in visiting order, starting with ``start``, each node exactly once. For a
    closed tour the return to the start is implied, not repeated. Empty when no solution."""
    length: float
    """Sum of the float matrix over the order's arcs (with the closing arc when closed), in
    the matrix's units; ``inf`` when no solution."""
    proven_optimal: bool
    """True only when the method proved no shorter order exists (CP-SAT OPTIMAL, enumeration)."""
    status: str
    """``"optimal"``, ``"feasible"`` (a solution without proof) or ``"no_solution"``."""
    solve_time_s: float
    """Wall-clock time of the whole call, model building included, s."""
    method: str
    """What actually ran: ``"exact"``, ``"routing"`` or ``"enumeration"``."""


def tour_length(distance_matrix: ArrayLike, order: Sequence[int], closed: bool) -> float:
    """Length of visiting ``order`` through the (n, n) ``distance_matrix``, in its units.

    Adds the arc from the last node back to the first when ``closed``; a single node has
    length 0 (there is no arc, whatever the diagonal holds).
    """
    matrix = np.asarray(distance_matrix, dtype=float)
    idx = np.asarray(order, dtype=int).reshape(-1)
    if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1]:
        raise ConfigError(f"distance_matrix must be square (n, n), got shape {matrix.shape}", "distance_matrix")
    if idx.size and (idx.min() < 0 or idx.max() >= matrix.shape[0]):
        raise ConfigError(f"order holds indices outside 0..{matrix.shape[0] - 1}", "order")
    if idx.size < 2:
        return 0.0
    length = float(matrix[idx[:-1], idx[1:]].sum())
    if closed:
        length += float(matrix[idx[-1], idx[0]])
    return length


def solve_tsp(
    distance_matrix: ArrayLike,
    *,
    start: int = 0,
    closed: bool = True,
    time_limit_s: float = 1.0,
    method: str = "auto",
) -> TspResult:
    """Shortest order visiting every node of ``distance_matrix`` once, from ``start``.

    Arguments:
        distance_matrix: (n, n) non-negative finite costs, ``[i, j]`` the cost of going from
            i to j; need not be symmetric. The diagonal is ignored.
        start: the first node of the order.
        closed: True for a tour returning to ``start``; False for an open path ending
            anywhere.
        time_limit_s: the solver's time limit, s (CP-SAT stops at it; guided local search
            always runs until it).
        method: ``"exact"`` (CP-SAT), ``"routing"`` (OR-Tools routing) or ``"auto"``.

    Raises ConfigError (naming the argument) on a bad matrix, start, method or time limit.
    """
    began = time.perf_counter()
    matrix = _validated_matrix(distance_matrix)
    n = matrix.shape[0]
    start = _validated_start(start, n)
    if method not in METHODS:
        raise ConfigError(f"method must be one of {', '.join(METHODS)}; got {method!r}", "method")
    if isinstance(time_limit_s, bool) or not isinstance(time_limit_s, numbers.Real) or not (
        math.isfinite(time_limit_s) and time_limit_s > 0
    ):
        raise ConfigError(f"time_limit_s must be a positive finite number of seconds, got {time_limit_s!r}", "time_limit_s")
    closed = bool(closed)

    if n <= 3:
        order, status, proven = _enumerate(matrix, start, closed), "optimal", True
        ran = "enumeration"
    else:
        ran = method if method != "auto" else ("exact" if n <= AUTO_EXACT_MAX_NODES else "routing")
        costs = _integer_costs(matrix)
        solve = _solve_exact if ran == "exact" else _solve_routing
        order, status, proven = solve(costs, start, closed, float(time_limit_s))

    length = tour_length(matrix, order, closed) if order else math.inf
    return TspResult(
        order=tuple(order),
        length=length,
        proven_optimal=proven,
        status=status,
        solve_time_s=time.perf_counter() - began,
        method=ran,
    )


def held_karp(distance_matrix: ArrayLike, *, start: int = 0, closed: bool = True) -> tuple[tuple[int, ...], float]:
    """Optimal order and its length by dynamic programming over subsets (Held & Karp 1962).

    ``best[S, j]`` is the shortest path leaving ``start``, visiting exactly the set S of
    other nodes and ending at j in S; it is built one subset size at a time, vectorised over
    the subsets of each size. O(2^n n^2) time, so limited to ``HELD_KARP_MAX_NODES`` nodes.
    Uses the float matrix directly and shares no code with the OR-Tools back ends.
    """
    matrix = _validated_matrix(distance_matrix)
    n = matrix.shape[0]
    if n > HELD_KARP_MAX_NODES:
        raise ConfigError(f"held_karp handles at most {HELD_KARP_MAX_NODES} nodes, got {n}", "distance_matrix")
    start = _validated_start(start, n)
    others = np.array([v for v in range(n) if v != start], dtype=int)
    m = others.size
    if m == 0:
        return (start,), 0.0

    sub = matrix[np.ix_(others, others)]  # sub[k, j]: from other k to other j
    bits = 1 << np.arange(m)
    best = np.full((1 << m, m), np.inf)
    parent = np.full((1 << m, m), -1, dtype=int)
    best[bits, np.arange(m)] = matrix[start, others]
    popcount = np.array([bin(s).count("1") for s in range(1 << m)])
    for size in range(2, m + 1):
        subsets = np.flatnonzero(popcount == size)
        without_j = subsets[:, None] ^ bits[None, :]  # (S, j): the set before arriving at j
        # candidate[S, k, j] = best[S - {j}, k] + d[k, j]; inf whenever k or j is not in S.
        candidate = best[without_j].transpose(0, 2, 1) + sub[None, :, :]
        has_j = (subsets[:, None] & bits[None, :]) != 0
        candidate = np.where(has_j[:, None, :], candidate, np.inf)
        parent[subsets] = candidate.argmin(axis=1)
        best[subsets] = candidate.min(axis=1)

    full = (1 << m) - 1
    finish = best[full] + (matrix[others, start] if closed else 0.0)
    last = int(finish.argmin())
    length = float(finish[last])
    reversed_path, subset = [], full
    while last >= 0:
        reversed_path.append(int(others[last]))
        subset, last = subset ^ (1 << last), int(parent[subset, last])
    return (start, *reversed(reversed_path)), length


def _validated_matrix(distance_matrix: ArrayLike) -> np.ndarray:
    """The matrix as an (n, n) float array, n >= 1, finite and non-negative, or ConfigError."""
    try:
        matrix = np.asarray(distance_matrix, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"distance_matrix must be an (n, n) array of numbers: {exc}", "distance_matrix") from exc
    if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1] or matrix.shape[0] == 0:
        raise ConfigError(f"distance_matrix must be square (n, n) with n >= 1, got shape {matrix.shape}", "distance_matrix")
    if not np.isfinite(matrix).all():
        raise ConfigError("distance_matrix must be finite (no NaN or inf entries)", "distance_matrix")
    if (matrix < 0).any():
        raise ConfigError(f"distance_matrix must be non-negative, min entry is {matrix.min()}", "distance_matrix")
    return matrix


def _validated_start(start: int, n: int) -> int:
    """``start`` as an int in 0..n-1 (bools and non-integers refused), or ConfigError."""
    if isinstance(start, bool) or not isinstance(start, numbers.Integral) or not 0 <= start < n:
        raise ConfigError(f"start must be an integer node index in 0..{n - 1}, got {start!r}", "start")
    return int(start)


def _integer_costs(matrix: np.ndarray) -> np.ndarray:
    """The matrix scaled so its largest entry is ``COST_SCALE_TARGET``, rounded to int64.

    The diagonal is zeroed: neither model uses it, and it must not set the scale.
    """
    off_diagonal = matrix.copy()
    np.fill_diagonal(off_diagonal, 0.0)
    largest = off_diagonal.max()
    scale = COST_SCALE_TARGET / largest if largest > 0 else 1.0
    return np.rint(off_diagonal * scale).astype(np.int64)


def _enumerate(matrix: np.ndarray, start: int, closed: bool) -> list[int]:
    """Best order by trying every permutation of the non-start nodes (for n <= 3)."""
    rest = [v for v in range(matrix.shape[0]) if v != start]
    orders = ([start, *p] for p in itertools.permutations(rest))
    return min(orders, key=lambda order: tour_length(matrix, order, closed))


def _nearest_neighbour(costs: np.ndarray, start: int) -> list[int]:
    """Greedy order from ``start``: always go to the cheapest unvisited node."""
    order, unvisited = [start], set(range(costs.shape[0])) - {start}
    while unvisited:
        here = order[-1]
        order.append(min(unvisited, key=lambda v: (costs[here, v], v)))
        unvisited.remove(order[-1])
    return order


def _solve_exact(costs: np.ndarray, start: int, closed: bool, time_limit_s: float) -> tuple[list[int], str, bool]:
    """CP-SAT circuit model over boolean arc literals; (order, status, proven_optimal)."""
    from ortools.sat.python import cp_model

    n = costs.shape[0]
    model = cp_model.CpModel()
    arcs = {(i, j): model.new_bool_var(f"x_{i}_{j}") for i in range(n) for j in range(n) if i != j}
    circuit = [(i, j, lit) for (i, j), lit in arcs.items()]
    ends = {}
    if not closed:
        # Dummy node n: every node but the start may end the path by stepping to it for free
        # (n >= 2, so the path must leave the start), and its only way out is to the start,
        # so each circuit is a path from the start plus a free loop back.
        dummy = n
        ends = {i: model.new_bool_var(f"end_{i}") for i in range(n) if i != start}
        circuit += [(i, dummy, lit) for i, lit in ends.items()]
        circuit.append((dummy, start, model.new_constant(1)))
    model.add_circuit(circuit)
    model.minimize(sum(int(costs[i, j]) * lit for (i, j), lit in arcs.items()))

    # A greedy order as a complete hint gives CP-SAT a first solution at once.
    greedy = _nearest_neighbour(costs, start)
    hinted = set(zip(greedy, greedy[1:] + ([greedy[0]] if closed else [])))
    for (i, j), lit in arcs.items():
        model.add_hint(lit, (i, j) in hinted)
    for i, lit in ends.items():
        model.add_hint(lit, i == greedy[-1])

    solver = cp_model.CpSolver()
    solver.parameters.max_time_in_seconds = time_limit_s
    solver.parameters.log_search_progress = False
    solver.parameters.num_workers = CP_SAT_WORKERS
    status = solver.solve(model)
    if status == cp_model.MODEL_INVALID:
        raise RuntimeError(f"CP-SAT rejected the TSP model: {model.validate()}")
    if status not in (cp_model.OPTIMAL, cp_model.FEASIBLE):
        return [], "no_solution", False

    successor = {i: j for (i, j), lit in arcs.items() if solver.boolean_value(lit)}
    order = [start]
    while len(order) < n:
        order.append(successor[order[-1]])
    proven = status == cp_model.OPTIMAL
    return order, ("optimal" if proven else "feasible"), proven


def _solve_routing(costs: np.ndarray, start: int, closed: bool, time_limit_s: float) -> tuple[list[int], str, bool]:
    """OR-Tools routing, PATH_CHEAPEST_ARC + guided local search; (order, status, False)."""
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2

    n = costs.shape[0]
    if closed:
        matrix = costs
        manager = pywrapcp.RoutingIndexManager(n, 1, start)
    else:
        # Dummy end node n, reached at zero cost from every node; the route ends there.
        matrix = np.zeros((n + 1, n + 1), dtype=np.int64)
        matrix[:n, :n] = costs
        manager = pywrapcp.RoutingIndexManager(n + 1, 1, [start], [n])
    routing = pywrapcp.RoutingModel(manager)
    transit = routing.RegisterTransitMatrix(matrix.tolist())
    routing.SetArcCostEvaluatorOfAllVehicles(transit)

    params = pywrapcp.DefaultRoutingSearchParameters()
    params.first_solution_strategy = routing_enums_pb2.FirstSolutionStrategy.PATH_CHEAPEST_ARC
    params.local_search_metaheuristic = routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH
    params.guided_local_search_lambda_coefficient = GLS_LAMBDA
    params.use_multi_armed_bandit_concatenate_operators = True
    # Guided local search never stops by itself: the time limit is its only exit.
    params.time_limit.FromMilliseconds(max(1, round(time_limit_s * 1000)))
    solution = routing.SolveWithParameters(params)
    if solution is None:
        return [], "no_solution", False

    order, index = [], routing.Start(0)
    while not routing.IsEnd(index):
        order.append(manager.IndexToNode(index))
        index = solution.Value(routing.NextVar(index))
    return order, "feasible", False
