"""Shortest tour (or open path from the start) through every node of a distance matrix.

The AUV visits the start and the hover points once each. Two OR-Tools
back ends, each a thin wrapper that keeps the solver idiom visible:

- ``"exact"``: CP-SAT, one boolean literal per arc tied together by a circuit constraint
  (``add_circuit``), minimising the integer arc costs. Proves optimality on small and
  medium instances; ``proven_optimal`` is true only when CP-SAT says OPTIMAL.
- ``"routing"``: the OR-Tools routing library, PATH_CHEAPEST_ARC for a first tour, then
  guided local search. Near-optimal on large instances, never a proof.
- ``"auto"``: exact up to :data:`AUTO_EXACT_MAX_NODES` nodes; above, routing followed by
  CP-SAT started from routing's order (which proves the optimum or keeps the shorter of the
  two) up to :data:`AUTO_POLISH_MAX_NODES` nodes, and routing alone beyond.

Instances of at most three nodes are solved by enumeration whatever the method (one or two
candidate orders), reported as method ``"enumeration"``.

Reproducibility (a result must not depend on the machine's speed or load). Each
search stops on a deterministic budget: CP-SAT runs one worker with a fixed seed and stops
at ``deterministic_time`` (CP-SAT's own work measure, the same on every machine); guided
local search stops after ``solution_limit`` solutions. ``time_limit_s`` is only a
wall-clock safety net: when it stops a search first, the result's status is
``"time_limit"`` (a valid order that another run may not repeat). Integer costs are
tie-broken (below) so that no two orders cost the same and a proven optimum is one order,
whichever way the search reached it.

Costs. Both solvers need integer arc costs. The float matrix is multiplied by
``COST_SCALE_TARGET / max(off-diagonal entries)`` and rounded: the largest entry becomes 1e6
and each arc is off by at most 0.5 unit, a relative error of 5e-7 of the longest arc. That
primary cost is then multiplied by ``n * tie_range`` and a fixed pseudo-random tie-break in
``[0, tie_range)`` is added to each arc: an order's tie-breaks sum to less than
``n * tie_range``, so an order that is shorter in the primary cost is always cheaper, and
orders of equal primary cost (frequent between grid cells, and every symmetric tour with its
reverse) almost never cost the same. The tie-breaks depend only on n, so the same matrix
always gets the same costs. The reported ``length`` is always recomputed from the float
matrix.

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
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from swiptopt.errors import ConfigError
from swiptopt.validation import Spec, check_value

METHODS = ("auto", "exact", "routing")
"""Accepted values of ``solve_tsp(method=...)``."""

ARGUMENTS = {
    "start": Spec(kind="int", lo=0, strict=True, doc="the first node of the order (its upper end: n - 1)"),
    "method": Spec(kind="str", choices=METHODS),
    "time_limit_s": Spec(lo=0, lo_open=True, unit="s", doc="wall-clock safety net"),
    "deterministic_time": Spec(lo=0, lo_open=True, unit="deterministic s", doc="CP-SAT's work budget"),
    "solution_limit": Spec(kind="int", lo=1, strict=True, doc="guided local search's solution budget"),
}
"""What the scalar arguments of :func:`solve_tsp` and :func:`held_karp` may hold, checked by
:func:`swiptopt.validation.check_value`."""

STATUSES = ("optimal", "feasible", "time_limit", "no_solution")
"""Values of :attr:`TspResult.status`."""

AUTO_EXACT_MAX_NODES = 40
"""Largest instance ``method="auto"`` gives to CP-SAT alone. With one worker at
linearization level 2, CP-SAT proved every one of 32 instances of 40 nodes (uniform,
clustered, grid-cell and asymmetric; closed and open) optimal within 0.19 deterministic
seconds (median 0.07), and TSPLIB's eil51, berlin52, st70 and eil76 within 0.2-0.9."""

AUTO_POLISH_MAX_NODES = 80
"""Above :data:`AUTO_EXACT_MAX_NODES` and up to this size, ``method="auto"`` runs routing and
then CP-SAT from routing's order (a complete hint): on eil51, st70 and eil76 CP-SAT then
proved the optimum within its default budget, from routing's 0.3-2.4 % gaps. Larger
instances get routing alone (CP-SAT's LP grows with the n^2 arcs)."""

CP_SAT_WORKERS = 1
"""CP-SAT runs one worker: a parallel portfolio's result depends on how the workers' threads
are scheduled, one worker's does not."""

CP_SAT_SEED = 0
"""CP-SAT's random seed (fixed, so one worker repeats its search exactly)."""

CP_SAT_LINEARIZATION_LEVEL = 2
"""CP-SAT's ``linearization_level``: 2 adds the circuit's LP relaxation with its cuts to the
single worker (level 1, the default, leaves the LP weak for a circuit)."""

DEFAULT_DETERMINISTIC_TIME = 1.0
"""CP-SAT's ``max_deterministic_time`` when ``deterministic_time`` is not given, in CP-SAT's
deterministic seconds (a count of its work, not of the clock): five times the most that any
40-node instance measured needed for its proof (see :data:`AUTO_EXACT_MAX_NODES`). How much
wall-clock time that is depends on the machine: ``python benchmarks/bench_tsp.py`` prints it."""

DEFAULT_SOLUTION_LIMIT = 100
"""Guided local search's ``solution_limit`` when ``solution_limit`` is not given. With it,
routing alone reached 0.2 % on eil51, 0 % on berlin52, 0.3 % on st70, 1.7 % on eil76 and
0.5 % on kroA100 (``python benchmarks/bench_tsp.py`` prints them; the gaps move by a percent
or two with any change to the instance or the costs: guided local search is chaotic, hence
the CP-SAT stage of ``auto``)."""

DEFAULT_TIME_LIMIT_S = 60.0
"""Default wall-clock safety net, s: far above what the default budgets need, so it stops a
search only on a machine that is badly overloaded."""

GLS_LAMBDA = 0.3
"""Guided local search penalty weight (OR-Tools default 0.1), used with the multi-armed
bandit choice among local search operators. Measured on 60 random Euclidean instances of
20-60 points with CP-SAT-proven optima, at 0.3-1 s limits: mean gap to the optimum
0.0-0.6 % against 0.2-1.1 % with the defaults (lambda 0.1, no bandit), and fewer runs stuck
a few % off; on eil51 and berlin52 it reaches 0.2 % and 0 % at a 0.3 s limit."""

COST_SCALE_TARGET = 1_000_000
"""The largest matrix entry becomes this many primary cost units (see the module docstring)."""

TIE_RANGE_MAX = 1 << 20
"""Largest tie-break range; smaller for huge n so that a tour's cost fits in 62 bits."""

TIE_SEED = 20230713
"""Seed of the fixed pseudo-random tie-breaks (any fixed value; changing it may change which
of several equally short orders is returned)."""

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
    """``"optimal"`` (proven), ``"feasible"`` (a solution without proof, the search stopped by
    its deterministic budget: every run gives this order), ``"time_limit"`` (a solution, but
    the wall-clock safety net stopped the search first, so another run may give another
    order) or ``"no_solution"``."""
    solve_time_s: float
    """Wall-clock time of the whole call, model building included, s."""
    method: str
    """What actually ran: ``"exact"``, ``"routing"``, ``"routing+exact"`` (routing, then CP-SAT
    from its order; ``method="auto"`` on medium instances) or ``"enumeration"``."""


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
    time_limit_s: float = DEFAULT_TIME_LIMIT_S,
    method: str = "auto",
    deterministic_time: float | None = None,
    solution_limit: int | None = None,
) -> TspResult:
    """Shortest order visiting every node of ``distance_matrix`` once, from ``start``.

    Arguments:
        distance_matrix: (n, n) non-negative finite costs, ``[i, j]`` the cost of going from
            i to j; need not be symmetric. The diagonal is ignored.
        start: the first node of the order.
        closed: True for a tour returning to ``start``; False for an open path ending
            anywhere.
        time_limit_s: wall-clock safety net, s. The searches stop on their deterministic
            budgets; should this limit stop one first, the status is ``"time_limit"``.
        method: ``"exact"`` (CP-SAT), ``"routing"`` (OR-Tools routing) or ``"auto"`` (module
            docstring).
        deterministic_time: CP-SAT's work budget in its deterministic seconds (default
            :data:`DEFAULT_DETERMINISTIC_TIME`); used by the CP-SAT stage.
        solution_limit: guided local search stops after this many solutions (default
            :data:`DEFAULT_SOLUTION_LIMIT`); used by the routing stage.

    The same arguments give the same order on any machine unless the status is
    ``"time_limit"``. Raises ConfigError (naming the argument) on a bad matrix, start,
    method or limit.
    """
    began = time.perf_counter()
    matrix = _validated_matrix(distance_matrix)
    n = matrix.shape[0]
    start = _validated_start(start, n)
    method = check_value("method", method, ARGUMENTS["method"])
    time_limit_s = check_value("time_limit_s", time_limit_s, ARGUMENTS["time_limit_s"])
    work_s = check_value(
        "deterministic_time", DEFAULT_DETERMINISTIC_TIME if deterministic_time is None else deterministic_time,
        ARGUMENTS["deterministic_time"],
    )
    limit = check_value(
        "solution_limit", DEFAULT_SOLUTION_LIMIT if solution_limit is None else solution_limit,
        ARGUMENTS["solution_limit"],
    )
    closed = bool(closed)

    if n <= 3:
        order, status, proven = _enumerate(matrix, start, closed), "optimal", True
        ran = "enumeration"
    else:
        ran = method
        if method == "auto":
            ran = "exact" if n <= AUTO_EXACT_MAX_NODES else "routing+exact" if n <= AUTO_POLISH_MAX_NODES else "routing"
        order, status, proven = [], "no_solution", False
        if ran.startswith("routing"):
            order, status, proven = _solve_routing(_integer_costs(matrix), start, closed, int(limit), time_limit_s)
        if ran.endswith("exact"):
            left_s = time_limit_s - (time.perf_counter() - began)
            if left_s <= 0:
                status = "time_limit"  # the routing stage used up the safety net
            else:
                costs = _integer_costs(matrix, tie_break=True)
                found = _solve_exact(costs, start, closed, work_s, left_s, order or None)
                order, status, proven = _better(matrix, closed, (order, status, proven), found)

    length = tour_length(matrix, order, closed) if order else math.inf
    return TspResult(
        order=tuple(int(v) for v in order),
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
        raise ConfigError(
            f"distance_matrix must be square (n, n) with n >= 1, got shape {matrix.shape}", "distance_matrix"
        )
    if not np.isfinite(matrix).all():
        raise ConfigError("distance_matrix must be finite (no NaN or inf entries)", "distance_matrix")
    if (matrix < 0).any():
        raise ConfigError(f"distance_matrix must be non-negative, min entry is {matrix.min()}", "distance_matrix")
    return matrix


def _validated_start(start: int, n: int) -> int:
    """``start`` as an int in 0..n-1 (bools and non-integers refused), or ConfigError."""
    return check_value("start", start, ARGUMENTS["start"], hi=n - 1)


def tie_range(n: int) -> int:
    """The tie-break range for n nodes: :data:`TIE_RANGE_MAX`, or less if a tour's integer
    cost (n + 1 arcs of at most ``COST_SCALE_TARGET * n * range`` each) would pass 2^62."""
    fits = (1 << 62) // (COST_SCALE_TARGET * (n + 1) * (n + 1))
    return int(max(1, min(TIE_RANGE_MAX, fits)))


def _integer_costs(matrix: np.ndarray, *, tie_break: bool = False) -> np.ndarray:
    """int64 arc costs: the primary cost (the matrix scaled so its largest entry is
    ``COST_SCALE_TARGET``, rounded); with ``tie_break``, times ``n * tie_range(n)`` plus each
    arc's fixed tie-break in ``[0, tie_range(n))`` (module docstring).

    CP-SAT gets the tie-broken costs, so that its proven optimum is one order. Routing gets
    the primary costs: its search is deterministic anyway, never proves anything, and guided
    local search measured no better on the tie-broken ones. The diagonal is zero: neither
    model uses it, and it must not set the scale.
    """
    n = matrix.shape[0]
    off_diagonal = matrix.copy()
    np.fill_diagonal(off_diagonal, 0.0)
    largest = off_diagonal.max()
    scale = COST_SCALE_TARGET / largest if largest > 0 else 1.0
    costs = np.rint(off_diagonal * scale).astype(np.int64)
    if tie_break:
        ties = tie_range(n)
        costs = costs * (n * ties) + np.random.default_rng(TIE_SEED).integers(0, ties, (n, n), dtype=np.int64)
        np.fill_diagonal(costs, 0)
    return costs


def _better(
    matrix: np.ndarray, closed: bool, first: tuple[list[int], str, bool], second: tuple[list[int], str, bool]
) -> tuple[list[int], str, bool]:
    """Combine two searches of one instance, (order, status, proven) each: a proof wins, else
    the shorter order (the first on a tie); the status is ``"time_limit"`` if the clock cut
    either search short, so a result the clock touched is never reported as reproducible."""
    if second[2]:
        return second
    if not first[0] or not second[0]:
        best = first if first[0] else second
    else:
        best = second if tour_length(matrix, second[0], closed) < tour_length(matrix, first[0], closed) else first
    if not best[0]:
        return [], "no_solution", False
    clock = "time_limit" in (first[1], second[1])
    return best[0], ("time_limit" if clock else "feasible"), False


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


def _solve_exact(
    costs: np.ndarray,
    start: int,
    closed: bool,
    deterministic_time: float,
    time_limit_s: float,
    hint: list[int] | None = None,
) -> tuple[list[int], str, bool]:
    """CP-SAT circuit model over boolean arc literals, started from ``hint`` (an order; default
    the nearest-neighbour order); (order, status, proven). Never worse than the hint."""
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

    # A complete hint gives CP-SAT a first solution at once.
    first = list(hint) if hint is not None else _nearest_neighbour(costs, start)
    hinted = set(zip(first, first[1:] + ([first[0]] if closed else [])))
    for (i, j), lit in arcs.items():
        model.add_hint(lit, (i, j) in hinted)
    for i, lit in ends.items():
        model.add_hint(lit, i == first[-1])

    solver = cp_model.CpSolver()
    solver.parameters.num_workers = CP_SAT_WORKERS
    solver.parameters.random_seed = CP_SAT_SEED
    solver.parameters.linearization_level = CP_SAT_LINEARIZATION_LEVEL
    solver.parameters.max_deterministic_time = deterministic_time
    solver.parameters.max_time_in_seconds = time_limit_s
    solver.parameters.log_search_progress = False
    status = solver.solve(model)
    if status == cp_model.MODEL_INVALID:
        raise RuntimeError(f"CP-SAT rejected the TSP model: {model.validate()}")
    # the clock stopped the search if it ended before its deterministic budget without a proof
    clock = status != cp_model.OPTIMAL and solver.deterministic_time < deterministic_time
    if status not in (cp_model.OPTIMAL, cp_model.FEASIBLE):
        # a budget too small for CP-SAT to take up even the hint: the hint is still an order
        return first, ("time_limit" if clock else "feasible"), False

    successor = {i: j for (i, j), lit in arcs.items() if solver.boolean_value(lit)}
    order = [start]
    while len(order) < n:
        order.append(successor[order[-1]])
    proven = status == cp_model.OPTIMAL
    return order, ("optimal" if proven else "time_limit" if clock else "feasible"), proven


def routing_search_parameters(solution_limit: int, time_limit_s: float) -> object:
    """OR-Tools routing's search as this package runs it: PATH_CHEAPEST_ARC, then guided
    local search stopped after ``solution_limit`` solutions. Guided local search never stops
    by itself: the solution count is its deterministic exit, the clock (``time_limit_s``)
    only a safety net. The large-neighbourhood operators have a clock of their own (100 ms
    by default): they get the safety net too, so load cannot cut one short."""
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2

    params = pywrapcp.DefaultRoutingSearchParameters()
    params.first_solution_strategy = routing_enums_pb2.FirstSolutionStrategy.PATH_CHEAPEST_ARC
    params.local_search_metaheuristic = routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH
    params.guided_local_search_lambda_coefficient = GLS_LAMBDA
    params.use_multi_armed_bandit_concatenate_operators = True
    params.solution_limit = solution_limit
    milliseconds = max(1, round(time_limit_s * 1000))
    params.time_limit.FromMilliseconds(milliseconds)
    params.lns_time_limit.FromMilliseconds(milliseconds)
    return params


def _solve_routing(
    costs: np.ndarray, start: int, closed: bool, solution_limit: int, time_limit_s: float
) -> tuple[list[int], str, bool]:
    """OR-Tools routing, PATH_CHEAPEST_ARC + guided local search; (order, status, False)."""
    from ortools.constraint_solver import pywrapcp

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

    solution = routing.SolveWithParameters(routing_search_parameters(solution_limit, time_limit_s))
    solutions = routing.solver().Solutions()
    if solution is None:
        return [], "no_solution", False

    order, index = [], routing.Start(0)
    while not routing.IsEnd(index):
        order.append(manager.IndexToNode(index))
        index = solution.Value(routing.NextVar(index))
    return order, ("time_limit" if solutions < solution_limit else "feasible"), False
