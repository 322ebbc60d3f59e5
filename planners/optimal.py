"""The episode as a mixed-integer program: the best walk, a proven bound, the gap.

**Formulation.** The simulator's return depends on a walk only through how many steps end
in each cell and what each step costs (:mod:`planners.service`): node i receives
``min(cap_i, sum over cells c of n_c * a_ci)`` of data and of energy, with ``n_c`` the steps
ending in c and ``a_ci`` the per-step amount. So the grid is reduced to the cells that
cover some node plus the start cell (the *vertices*); the stretches in between, through
cells that cover nothing, become arcs carrying their number of moves and their movement
penalty, and an arc is kept only when no vertex lies on any of its shortest paths (such a
path is two shorter arcs that earn at least as much). The walk is written without a time
index:

- integer arc counts ``x_a`` and hover counts ``h_v`` (self-loops, the cheapest way to stay
  in a cell: hover, or a blocked move), flow balance from the start to one end vertex
  ``y_v``;
- duration: the moves and hovers fill ``episode_steps`` exactly, or fewer steps when every
  node is served by then (the episode ends there, with no more penalties);
- connectivity: a single-commodity flow from the start reaches every visited vertex
  ``z_v`` (so the arc counts form one walk: an Euler trail from the start);
- service: ``u_i <= min(data_i, sum_v n_v b_vi)``, ``w_i <= min(room_i, sum_v n_v e_vi)``
  with the per-step amounts capped per step (exact for whole step counts, and tighter in
  the relaxation), plus ``u_i <= data_i * (visited vertices covering i)``;
- objective: ``sum_i Gamma u_i / D_ref + (1 - Gamma) w_i / E_ref`` minus the movement
  penalty of every move and hover: the simulator's return, term for term.

The start cell counts only when a step ends there (``n_v`` counts arrivals), blocked moves
are never better than the cheapest stay, and every walk of the grid maps onto a walk of this
model that earns at least as much (shorter stretches padded with hovers, which cost no more
than moves), so with a deterministic channel and direction-independent move costs the
model's optimum *is* the simulator's optimum.

**Solving.** The linear relaxation is tightened by a fixed number of rounds of
connectivity cuts (every set of vertices holding a visited vertex but not the start is
entered; separated by max flow), each round's value a valid bound (``lp_bound``). HiGHS then
branches single-threaded from a warm start, the rate-greedy walk
(:func:`planners.rate_greedy.rate_greedy_actions`) polished by a seeded local search
(:func:`planners.walk_search.polish_walk`), within a node budget; with a deterministic channel its dual bound is a
proven upper bound on every policy's return. Every limit is deterministic (:class:`MilpBudget`), so
the same scenario and budget give the same numbers on any machine; the wall-clock limit is
a safety net whose hitting the status reports.

**Stochastic channel.** The per-step amounts are the expectations of the capped per-step
transfer over the fading and link failures (the *expected-rate relaxation*), and the plan
runs open loop. ``objective`` is then the plan's value in that relaxation and ``bound``
bounds the relaxation's value over all walks. What each bounds (proof in docs/optimum.md;
:func:`policy_bounds` lists them with the class of policy each holds for):

- ``lp_bound``, the linear relaxation after any round of cuts, bounds the expected return of
  *every* non-anticipative policy, adaptive ones included and episodes that end early
  because every node was served: a policy's expected step counts lie in the convex hull of
  walks, which the relaxation contains, and its expected return is at most the relaxation's
  objective there (Jensen's inequality for the caps; Markov's for the early end);
- ``bound``, the branch-and-bound's dual bound, bounds only the relaxation's value over
  whole walks. Open-loop walks that cannot end early (some node no cell covers) stay below
  it, by Jensen's inequality; a policy that reacts to the draws, or an open-loop walk whose
  episode may end early, can exceed it (the tests hold a two-cell case of each).

**Currents.** With a current, moves cost different energies by direction and depth, and an
arc's fewest moves and least penalty may come from different paths. The arcs then carry
both minima (a relaxation: every real stretch needs at least as many moves and at least as
much penalty), the duration may fall short of the episode, and the bound stays valid; the
plan follows the least-penalty paths and its ``objective`` is what it really earns
(:meth:`planners.service.StepModel.walk_return`), so the status is at best ``feasible``.

**Fleets.** The program is built for a list of walks sharing the service (one here);
:mod:`planners.fleet_optimal` builds it with one walk per AUV from the same pieces, and
with one AUV gets this module's program column for column.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, NamedTuple

import numpy as np

from planners.bounds import ADAPTIVE, LP_EXPECTED_NAME, MILP_EXPECTED_NAME, MILP_NAME, OPEN_LOOP, PolicyBound
from planners.service import StepModel, step_model
from swiptopt import kernel as K
from swiptopt.errors import ConfigError
from swiptopt.scenario import Scenario
from swiptopt.validation import Spec, check_value

#: Statuses of :class:`OptimumResult`.
STATUSES = ("optimal", "feasible", "no_solution", "unsupported", "error")


@dataclass(frozen=True)
class MilpBudget:
    """How much search the MILP gets: deterministic limits first, the clock only as a net."""

    max_nodes: int = 2000
    """Branch-and-bound nodes (HiGHS ``mip_max_nodes``): the deterministic budget."""
    rel_gap: float = 1e-6
    """Stop when (bound - best) / |best| is below this."""
    time_limit_s: float = 600.0
    """Safety net only: hitting it is reported in the status, as results then depend on the
    machine's speed."""
    polish_evaluations: int = 20_000
    """Walk evaluations of the local search polishing the warm start
    (:func:`planners.walk_search.polish_walk`)."""
    cut_rounds: int = 30
    """Rounds of connectivity cuts added to the linear relaxation before branching."""
    sub_mip_heuristics: bool = True
    """Whether HiGHS runs its sub-MIP heuristics (RINS, RENS): better walks, more time."""
    seed: int = 0
    """HiGHS ``random_seed``."""
    max_arcs: int = 200_000
    """Larger reduced graphs are reported ``unsupported`` rather than attempted."""

    #: What each field may hold, checked at construction (:func:`swiptopt.validation.check_value`).
    FIELDS: ClassVar[dict[str, Spec]] = {
        "max_nodes": Spec(kind="int", lo=0, strict=True),
        "polish_evaluations": Spec(kind="int", lo=0, strict=True),
        "cut_rounds": Spec(kind="int", lo=0, strict=True),
        "seed": Spec(kind="int", lo=0, strict=True),
        "max_arcs": Spec(kind="int", lo=0, strict=True),
        "rel_gap": Spec(lo=0),
        "time_limit_s": Spec(lo=0, lo_open=True, unit="s"),
        "sub_mip_heuristics": Spec(kind="bool"),
    }

    def __post_init__(self) -> None:
        for name, spec in self.FIELDS.items():
            check_value(name, getattr(self, name), spec)


#: Named budgets. ``quick`` for tests (root node only, a short polish); ``compare`` for the
#: benchmark table (root node with HiGHS's cuts, a longer polish); ``default`` (branch and
#: bound with HiGHS's sub-MIP heuristics). The time limits are safety nets far above what
#: these budgets take (docs/optimum.md, 'On the paper preset', has their times).
BUDGETS: dict[str, MilpBudget] = {
    "quick": MilpBudget(
        max_nodes=1, polish_evaluations=2000, cut_rounds=2, sub_mip_heuristics=False, time_limit_s=300.0
    ),
    "compare": MilpBudget(
        max_nodes=1, polish_evaluations=20_000, cut_rounds=0, sub_mip_heuristics=False, time_limit_s=600.0
    ),
    "default": MilpBudget(max_nodes=500, polish_evaluations=50_000, cut_rounds=10, time_limit_s=1800.0),
}


def resolve_budget(budget: MilpBudget | str) -> MilpBudget:
    """A :class:`MilpBudget` or the name of one in :data:`BUDGETS`."""
    if isinstance(budget, MilpBudget):
        return budget
    if isinstance(budget, str) and budget in BUDGETS:
        return BUDGETS[budget]
    raise ConfigError(f"budget = {budget!r} must be a MilpBudget or one of {', '.join(BUDGETS)}", "budget")


@dataclass(frozen=True, eq=False)
class OptimumResult:
    """The MILP's best walk, its value, a proven bound and how the search ended."""

    status: str
    """``optimal`` (gap within the budget's ``rel_gap``, exact model), ``feasible`` (a plan
    with a gap), ``no_solution`` (no plan within the budget), ``unsupported`` (the scenario
    has something the model cannot express; ``message`` says what) or ``error`` (the solver
    failed; ``message`` says how)."""
    message: str
    objective: float | None
    """The plan's return: the simulator's with a deterministic channel, else its value in
    the expected-rate relaxation (see the module docstring)."""
    bound: float | None
    """Proven upper bound on the best walk's return (the relaxation's, with a stochastic
    channel: then it does not bound every policy, :func:`policy_bounds`)."""
    lp_bound: float | None
    """The linear relaxation's value (a weaker bound, but one that holds for adaptive
    policies too: :func:`policy_bounds`), and its solve time below."""
    lp_time_s: float | None
    actions: list[int] = field(default_factory=list)
    """The plan: one action per step."""
    exact: bool = False
    """Whether the model is the simulator's own (deterministic channel, no current)."""
    nodes: int = 0
    """Branch-and-bound nodes used."""
    time_limit_hit: bool = False
    wall_s: float = 0.0
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def gap(self) -> float | None:
        """(bound - objective) / |bound|, the benchmark's gap convention."""
        if self.objective is None or self.bound is None:
            return None
        return (self.bound - self.objective) / max(abs(self.bound), 1e-12)


def policy_bounds(result: OptimumResult) -> list[PolicyBound]:
    """The bounds of ``result`` with the class of policy each holds for (docs/optimum.md):

    - deterministic channel: ``bound`` as ``milp``, for every policy (each policy's episode
      is a walk, and the model is exact or a relaxation of every walk);
    - stochastic channel: ``lp_bound`` as ``lp (expected)``, for every non-anticipative
      policy; and ``bound`` as ``milp (expected)`` for open-loop plans, only when no walk can
      end early (some node no cell covers) and only when it is below ``lp_bound``.

    Empty when the solve found no bound (an unsupported scenario, a solver error).
    """
    out: list[PolicyBound] = []
    finite = [v is not None and math.isfinite(v) for v in (result.bound, result.lp_bound)]
    if result.details.get("deterministic"):
        if finite[0]:
            out.append(PolicyBound(float(result.bound), MILP_NAME, ADAPTIVE))  # type: ignore[arg-type]
        return out
    if finite[1]:
        out.append(PolicyBound(float(result.lp_bound), LP_EXPECTED_NAME, ADAPTIVE))  # type: ignore[arg-type]
    if (finite[0] and result.details.get("can_end_early") is False
            and not (finite[1] and result.bound >= result.lp_bound)):
        out.append(PolicyBound(float(result.bound), MILP_EXPECTED_NAME, OPEN_LOOP))  # type: ignore[arg-type]
    return out


def solve_optimum(
    scenario: Scenario, *, budget: MilpBudget | str = "default", tables: K.Tables | None = None
) -> OptimumResult:
    """The best walk of ``scenario`` by mixed-integer programming (module docstring).

    Never raises for a scenario: what the model cannot express comes back as status
    ``unsupported`` and a solver failure as ``error``, each with a message naming the reason.
    A bad ``budget`` raises :class:`~swiptopt.errors.ConfigError`.
    """
    budget = resolve_budget(budget)
    started = time.perf_counter()
    tables = K.build_tables(scenario) if tables is None else tables
    reason = unsupported_reason(scenario, tables)
    if reason:
        return OptimumResult("unsupported", reason, None, None, None, None, wall_s=time.perf_counter() - started)
    model = step_model(tables)
    graph = _ReducedGraph.build(model)
    if graph.n_arcs > budget.max_arcs:
        return OptimumResult(
            "unsupported",
            f"the reduced graph has {graph.n_arcs} arcs, more than max_arcs = {budget.max_arcs}",
            None, None, None, None, wall_s=time.perf_counter() - started,
        )
    try:
        return _solve(model, graph, budget, started)
    except Exception as error:  # a solver failure is a status, never a crash
        return OptimumResult(
            "error", f"{type(error).__name__}: {error}", None, None, None, None, wall_s=time.perf_counter() - started
        )


def unsupported_reason(scenario: Scenario, tables: K.Tables, batteries_j: Sequence[float] | None = None) -> str:
    """Why the model cannot express the scenario ('' when it can); the time-indexed
    programs of :mod:`planners.hindsight` and the fleet's (:mod:`planners.fleet_optimal`)
    share these limits. ``batteries_j``: each AUV's battery when not the scenario's one
    ``battery_j`` (a fleet's)."""
    p = tables.named
    if scenario.link == "uplink":
        return (
            "link = 'uplink': a node's data depends on the energy it has stored when served, hence on "
            "the order of service, which the per-cell step counts of the model cannot express"
        )
    if scenario.idle_drain_w > 0:
        return f"idle_drain_w = {scenario.idle_drain_w:g}: a draining node's storage makes service depend on timing"
    if p.gate_j > 0 and np.any(tables.energy0 < p.gate_j):
        return (
            f"energy_gate_j = {p.gate_j:g}: a node starting below the gate cannot send until charged, "
            "so its data depends on the order of service"
        )
    worst = float(tables.propulsion_j.max()) + p.hotel_j + p.projector_j
    name, battery = "battery_j", p.battery_j
    if batteries_j is not None:
        name, battery = "auv_batteries_j", min(batteries_j)
    if worst * p.steps >= battery:
        return (
            f"{name} = {battery:g}: the battery may run out within the episode "
            f"(up to {worst * p.steps:g} J), which the model does not track"
        )
    return ""


# --------------------------------------------------------------------------- reduced graph


@dataclass(eq=False)
class _ReducedGraph:
    """Vertices (start first, then the covering cells), arcs between them and their paths."""

    vertices: np.ndarray
    """(V,) cells; vertex 0 is the start cell."""
    tail: np.ndarray
    """(A,) arc tails (vertex indices)."""
    head: np.ndarray
    moves: np.ndarray
    """(A,) moves of each arc (its duration in steps)."""
    cost: np.ndarray
    """(A,) movement penalty of each arc."""
    from_start: np.ndarray
    """(V,) fewest moves from the start to each vertex (inf when unreachable)."""
    pair_moves: np.ndarray
    """(V, V) fewest moves between vertices (inf when unreachable)."""
    pair_cost: np.ndarray
    """(V, V) least movement penalty between vertices."""
    exact: bool
    """Whether each arc's fewest moves and least penalty come from one path and stays are
    never dearer than moves (no current): the model is then exact."""
    predecessors: Any = None
    """(V, n_cells) shortest-path predecessors from each vertex: how to rebuild an arc's cells."""

    @property
    def n_arcs(self) -> int:
        return int(self.tail.shape[0])

    @classmethod
    def build(cls, model: StepModel) -> _ReducedGraph:
        from scipy.sparse import csr_matrix
        from scipy.sparse.csgraph import dijkstra

        n = model.n_cells
        covering = np.flatnonzero(np.diff(model.cov_ptr) > 0)
        vertices = np.concatenate([[model.start_cell], covering[covering != model.start_cell]]).astype(np.int64)
        moved = model.next_cell[:, : K.HOVER] != np.arange(n)[:, None]
        rows = np.repeat(np.arange(n), K.HOVER).reshape(n, K.HOVER)[moved]
        cols = model.next_cell[:, : K.HOVER][moved]
        move_cost = model.step_cost[:, : K.HOVER][moved]
        uniform = move_cost.size == 0 or np.ptp(move_cost) <= 1e-12 * max(float(move_cost.max()), 1e-300)
        unit = float(move_cost.max()) if move_cost.size else 0.0
        # exact when moves cost alike and staying anywhere costs the same, no more than a move
        stays = model.stay_cost
        exact = bool(uniform and np.ptp(stays) <= 1e-12 * max(unit, 1e-300) and np.all(stays <= unit * (1 + 1e-12)))
        steps_graph = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
        steps, step_pred = dijkstra(steps_graph, indices=vertices, return_predecessors=True, unweighted=True)
        if uniform:
            energy, pred = steps * unit, step_pred
        else:
            # tiny floor: scipy's sparse graphs drop zero-weight edges
            energy_graph = csr_matrix((np.maximum(move_cost, 1e-15), (rows, cols)), shape=(n, n))
            energy, pred = dijkstra(energy_graph, indices=vertices, return_predecessors=True)
        s_vv, e_vv = steps[:, vertices], energy[:, vertices]
        from_start = s_vv[0]
        horizon = model.steps
        nv = len(vertices)
        keep = np.isfinite(s_vv) & (s_vv > 0)
        keep &= (from_start[:, None] + s_vv) <= horizon
        tol = 1e-9 * max(unit, 1e-300)
        diag = np.arange(nv)
        for u in range(nv):
            candidates = np.flatnonzero(keep[u])
            if candidates.size == 0:
                continue
            # a vertex m (not u, not w) on a path as short in moves and as cheap: drop u -> w
            via = (s_vv[u, :, None] + s_vv[:, candidates] == s_vv[u, candidates][None, :]) & (
                e_vv[u, :, None] + e_vv[:, candidates] <= e_vv[u, candidates][None, :] + tol
            )
            via[u, :] = False
            via[candidates, np.arange(candidates.size)] = False
            keep[u, candidates[via.any(axis=0)]] = False
        keep[diag, diag] = False
        tail, head = np.nonzero(keep)
        return cls(
            vertices=vertices,
            tail=tail.astype(np.int64),
            head=head.astype(np.int64),
            moves=s_vv[tail, head].astype(np.int64),
            cost=e_vv[tail, head],
            from_start=from_start,
            pair_moves=s_vv,
            pair_cost=e_vv,
            exact=exact,
            predecessors=pred,
        )

    def arc_cells(self, a: int) -> list[int]:
        """The cells an arc passes through after its tail, ending at its head."""
        pred = self.predecessors[self.tail[a]]
        target = int(self.vertices[self.head[a]])
        source = int(self.vertices[self.tail[a]])
        cells = [target]
        while cells[-1] != source:
            cells.append(int(pred[cells[-1]]))
        return cells[::-1][1:]


# --------------------------------------------------------------------------- the program

#: A walk's own column blocks, in their order in the program.
_WALK_BLOCKS = ("x", "h", "y", "z", "g", "fd", "fe")


@dataclass(eq=False)
class _WalkColumns:
    """One walk's part of a program: its columns and its (vertex, node) service pairs."""

    blocks: dict[str, slice]
    """Column block of each variable family the walk reads: its own x, h, y, z, g, fd, fe
    and slack, and the service variables u, w and q that every walk shares."""
    pair_vertex: np.ndarray
    """(P,) vertex of each (vertex, node) service pair, the order of fd and fe."""
    pair_node: np.ndarray
    """(P,) position of its node in the program's ``nodes``."""
    pair_data: np.ndarray
    """(P,) one step's data as a fraction of the node's data."""
    pair_energy: np.ndarray
    """(P,) one step's energy as a fraction of the node's free storage (0 if none)."""

    @property
    def starts(self) -> dict[str, int]:
        """The first column of each block."""
        return {name: b.start for name, b in self.blocks.items()}


@dataclass(eq=False)
class _Program:
    """The MILP's columns (named blocks, per walk), bounds, objective and constraint rows."""

    walks: list[_WalkColumns]
    """Each walk's columns: one for the single AUV, one per AUV for a fleet
    (:mod:`planners.fleet_optimal`)."""
    nodes: np.ndarray
    """Coverable nodes (the ones with service variables), in the order of u and w."""
    cost: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    integer: np.ndarray
    a_rows: Any
    row_lower: np.ndarray
    row_upper: np.ndarray

    @property
    def blocks(self) -> dict[str, slice]:
        """The first walk's column blocks (the single AUV's: every column)."""
        return self.walks[0].blocks


class _Rows:
    """Collects sparse constraint rows as triplets."""

    def __init__(self) -> None:
        self.r: list[np.ndarray] = []
        self.c: list[np.ndarray] = []
        self.v: list[np.ndarray] = []
        self.lo: list[np.ndarray] = []
        self.hi: list[np.ndarray] = []
        self.count = 0

    def add(self, count: int, lo: float, hi: float) -> int:
        """Append ``count`` rows with bounds [lo, hi]; returns the first one's index."""
        first = self.count
        self.count += count
        self.lo.append(np.full(count, lo, dtype=float))
        self.hi.append(np.full(count, hi, dtype=float))
        return first

    def put(self, rows: Any, cols: Any, vals: Any) -> None:
        rows, cols, vals = np.broadcast_arrays(np.asarray(rows), np.asarray(cols), np.asarray(vals, dtype=float))
        self.r.append(rows.ravel())
        self.c.append(cols.ravel())
        self.v.append(vals.ravel())

    def matrix(self, n_cols: int):  # type: ignore[no-untyped-def]
        from scipy.sparse import coo_matrix

        m = coo_matrix(
            (np.concatenate(self.v), (np.concatenate(self.r), np.concatenate(self.c))), shape=(self.count, n_cols)
        ).tocsc()
        m.sum_duplicates()
        return m, np.concatenate(self.lo), np.concatenate(self.hi)


def _program(
    model: StepModel, graphs: list[_ReducedGraph], *, stay_cost: np.ndarray | None = None,
    extra_rows: Callable[[_Rows, list[_WalkColumns]], None] | None = None,
) -> _Program:
    """The MILP of the module docstring with one walk over each of ``graphs`` (each graph's
    vertex 0 its walk's start) and the service shared: its columns, then its rows block by
    block (each walk, each walk's service pairs, the nodes, each walk's visits and their
    connectivity, then ``extra_rows``). One graph gives the single AUV's program; a fleet's
    (:mod:`planners.fleet_optimal`) has one per AUV. ``stay_cost``: (n_cells,) the penalty
    of a hover, when not the model's cheapest stay."""
    T = model.steps
    nodes = np.flatnonzero(model.coverable())
    walks, n_cols = _layout(model, graphs, nodes)
    cost, lower, upper = np.zeros(n_cols), np.zeros(n_cols), np.zeros(n_cols)
    integer = np.zeros(n_cols, dtype=bool)
    stays = model.stay_cost if stay_cost is None else stay_cost
    # steps left on arrival at each vertex, and the most commodity an arc can carry
    reach = [T - np.where(np.isfinite(g.from_start), g.from_start, T + 1) for g in graphs]
    k_flow = [float(min(len(g.vertices) - 1, T)) for g in graphs]
    for graph, walk, r, k in zip(graphs, walks, reach, k_flow):
        _walk_columns(model, graph, walk, r, k, stays, (cost, lower, upper, integer))
    _service_columns(model, graphs[0], nodes, walks[0].blocks, (cost, lower, upper, integer))

    rows = _Rows()
    into = [_arcs_into(graph) for graph in graphs]
    for graph, walk in zip(graphs, walks):
        _walk_rows(rows, model, graph, walk.starts)
    for walk, arcs_in in zip(walks, into):
        _pair_rows(rows, walk, arcs_in)
    _node_rows(rows, model, model.room_j[nodes], walks)
    for graph, walk, arcs_in, r, k in zip(graphs, walks, into, reach, k_flow):
        _visit_rows(rows, graph, walk.starts, arcs_in, r, k)
    if extra_rows is not None:
        extra_rows(rows, walks)

    matrix, row_lower, row_upper = rows.matrix(n_cols)
    return _Program(walks, nodes, cost, lower, upper, integer, matrix, row_lower, row_upper)


def _layout(model: StepModel, graphs: list[_ReducedGraph], nodes: np.ndarray) -> tuple[list[_WalkColumns], int]:
    """Each walk's columns and the number of columns: every walk's own blocks in turn, then
    the shared u, w and q, then each walk's slack (one walk: x, h, y, z, g, fd, fe, u, w, q,
    slack, the single AUV's order)."""
    pairs = [_pairs(model, graph, nodes) for graph in graphs]
    at = 0
    own: list[dict[str, slice]] = []
    for graph, (pair_vertex, *_) in zip(graphs, pairs):
        A, V, P = graph.n_arcs, len(graph.vertices), len(pair_vertex)
        blocks = {}
        for name, size in zip(_WALK_BLOCKS, (A, V, V, V, A, P, P)):
            blocks[name] = slice(at, at + size)
            at += size
        own.append(blocks)
    shared = {}
    for name, size in (("u", len(nodes)), ("w", len(nodes)), ("q", 1)):
        shared[name] = slice(at, at + size)
        at += size
    walks = []
    for k, (blocks, walk_pairs) in enumerate(zip(own, pairs)):
        blocks.update(shared)
        blocks["slack"] = slice(at + k, at + k + 1)
        walks.append(_WalkColumns(blocks, *walk_pairs))
    return walks, at + len(graphs)


def _pairs(model: StepModel, graph: _ReducedGraph, nodes: np.ndarray) -> tuple[np.ndarray, ...]:
    """The (vertex, node) pairs of the coverage lists (every vertex covers nodes but the
    start): each pair's vertex, its node's position in ``nodes``, and one step's data and
    energy as fractions of the node's data and free storage."""
    N = len(nodes)
    node_index = np.full(model.n_nodes, -1, dtype=np.int64)
    node_index[nodes] = np.arange(N)
    data = model.data_bits[nodes]
    room = model.room_j[nodes]
    vertex_of_cell = np.full(model.n_cells, -1, dtype=np.int64)
    vertex_of_cell[graph.vertices] = np.arange(len(graph.vertices))
    pair_vertex = vertex_of_cell[model.cell_of_pair()]
    pair_node = node_index[model.cov_node]
    ok = pair_vertex >= 0
    pair_vertex, pair_node = pair_vertex[ok], pair_node[ok]
    pair_data = model.bits[ok] / data[pair_node]
    pair_energy = np.where(room[pair_node] > 0, model.joules[ok] / np.where(room > 0, room, 1.0)[pair_node], 0.0)
    return pair_vertex, pair_node, pair_data, pair_energy


def _walk_columns(
    model: StepModel, graph: _ReducedGraph, walk: _WalkColumns, reach: np.ndarray, k_flow: float,
    stay_cost: np.ndarray, arrays: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:
    """One walk's columns in ``arrays`` (objective, lower and upper bounds, integrality)."""
    cost, lower, upper, integer = arrays
    b = walk.blocks
    T = model.steps
    cost[b["x"]] = -graph.cost
    cost[b["h"]] = -stay_cost[graph.vertices]
    upper[b["x"]] = np.floor(T / graph.moves)
    upper[b["h"]] = np.maximum(reach, 0)
    upper[b["y"]] = reach >= 0
    upper[b["z"]] = reach >= 0
    z = b["z"].start
    lower[z] = upper[z] = 1.0  # the start is where the walk begins
    upper[b["g"]] = np.where(graph.head == 0, 0.0, k_flow * upper[b["x"]])
    upper[b["fd"]] = 1.0
    upper[b["fe"]] = walk.pair_energy > 0
    upper[b["slack"]] = T
    for name in ("x", "h", "y", "z"):
        integer[b[name]] = True


def _service_columns(
    model: StepModel, graph: _ReducedGraph, nodes: np.ndarray, blocks: dict[str, slice],
    arrays: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:
    """The shared service columns u, w and q in ``arrays`` (``graph``: any walk's, for
    whether the model is exact)."""
    cost, _, upper, integer = arrays
    data = model.data_bits[nodes]
    room = model.room_j[nodes]
    can_stop_early = graph.exact and model.can_finish_early()
    # service variables are fractions of each node's data and free storage (well scaled)
    cost[blocks["u"]] = model.data_weight * data
    cost[blocks["w"]] = model.energy_weight * room
    upper[blocks["u"]] = 1.0
    upper[blocks["w"]] = room > 0
    upper[blocks["q"]] = 1.0 if can_stop_early else 0.0
    integer[blocks["q"]] = True


def _walk_rows(rows: _Rows, model: StepModel, graph: _ReducedGraph, ix: dict[str, int]) -> None:
    """Flow balance from the start to one end vertex, and the duration."""
    T = model.steps
    arcs, verts = np.arange(graph.n_arcs), np.arange(len(graph.vertices))
    # flow balance: out - in + end = [v is the start]
    first = rows.add(len(verts), 0.0, 0.0)
    rows.lo[-1][0] = rows.hi[-1][0] = 1.0
    rows.put(first + graph.tail, ix["x"] + arcs, 1.0)
    rows.put(first + graph.head, ix["x"] + arcs, -1.0)
    rows.put(first + verts, ix["y"] + verts, 1.0)
    # one end
    rows.put(rows.add(1, 1.0, 1.0), ix["y"] + verts, 1.0)
    # duration: moves + hovers + slack = T, slack only when the episode ends early
    row = rows.add(1, T, T)
    rows.put(row, ix["x"] + arcs, graph.moves)
    rows.put(row, ix["h"] + verts, 1.0)
    rows.put(row, ix["slack"], 1.0)
    if graph.exact:
        rows.put(rows.add(1, -np.inf, 0.0), [ix["slack"], ix["q"]], [1.0, -float(T)])


def _pair_rows(rows: _Rows, walk: _WalkColumns, into: list[np.ndarray]) -> None:
    """What each of a walk's (vertex, node) pairs delivers: at most what its steps there
    deliver, at most everything, and only if the vertex is visited (sum over v of
    min(n_v a_vi, z_v) >= min(1, sum over v of n_v a_vi) for whole counts)."""
    ix = walk.starts
    pair_vertex = walk.pair_vertex
    P = len(pair_vertex)
    pairs = np.arange(P)
    for name, amount in (("fd", walk.pair_data), ("fe", walk.pair_energy)):
        first = rows.add(P, -np.inf, 0.0)
        rows.put(first + pairs, ix[name] + pairs, 1.0)
        rows.put(first + pairs, ix["h"] + pair_vertex, -amount)
        arcs_in = [into[v] for v in pair_vertex]
        counts = np.array([a.size for a in arcs_in], dtype=np.int64)
        if counts.sum():
            rows.put(np.repeat(first + pairs, counts), ix["x"] + np.concatenate(arcs_in), -np.repeat(amount, counts))
        first = rows.add(P, -np.inf, 0.0)
        rows.put(first + pairs, ix[name] + pairs, 1.0)
        rows.put(first + pairs, ix["z"] + pair_vertex, -1.0)


def _node_rows(rows: _Rows, model: StepModel, room: np.ndarray, walks: list[_WalkColumns]) -> None:
    """What each node receives (at most what every walk's pairs of it deliver together),
    and every node served when the walks stop early."""
    N = len(room)
    nn = np.arange(N)
    ix = walks[0].starts  # u, w and q are every walk's
    for name, per_pair in (("u", "fd"), ("w", "fe")):
        first = rows.add(N, -np.inf, 0.0)
        rows.put(first + nn, ix[name] + nn, 1.0)
        for walk in walks:
            rows.put(first + walk.pair_node, walk.starts[per_pair] + np.arange(len(walk.pair_node)), -1.0)
    # every node served when the walk stops early
    first = rows.add(N, -np.inf, 0.0)
    rows.put(first + nn, ix["q"], 1.0)
    rows.put(first + nn, ix["u"] + nn, -1.0)
    if model.needs_energy:
        full = np.flatnonzero(room > 0)
        first = rows.add(len(full), -np.inf, 0.0)
        rows.put(first + np.arange(len(full)), ix["q"], 1.0)
        rows.put(first + np.arange(len(full)), ix["w"] + full, -1.0)


def _visit_rows(
    rows: _Rows, graph: _ReducedGraph, ix: dict[str, int], into: list[np.ndarray], reach: np.ndarray, k_flow: float
) -> None:
    """Arrivals only at visited vertices, a visited vertex entered, and the connectivity flow."""
    A, V = graph.n_arcs, len(graph.vertices)
    arcs, verts = np.arange(A), np.arange(V)
    # arrivals only at visited vertices, and a visited vertex is entered
    others = verts[1:]
    in_counts = np.array([into[v].size for v in others], dtype=np.int64)
    in_arcs = np.concatenate([into[v] for v in others]) if len(others) else np.zeros(0, dtype=np.int64)
    first = rows.add(V - 1, -np.inf, 0.0)
    rows.put(np.repeat(first + others - 1, in_counts), ix["x"] + in_arcs, 1.0)
    rows.put(first + others - 1, ix["h"] + others, 1.0)
    rows.put(first + others - 1, ix["z"] + others, -np.maximum(reach[others] + 1, 0))
    first = rows.add(V - 1, -np.inf, 0.0)
    rows.put(first + others - 1, ix["z"] + others, 1.0)
    rows.put(np.repeat(first + others - 1, in_counts), ix["x"] + in_arcs, -1.0)
    # connectivity: one unit of commodity from the start to every visited vertex
    first = rows.add(A, -np.inf, 0.0)
    rows.put(first + arcs, ix["g"] + arcs, 1.0)
    rows.put(first + arcs, ix["x"] + arcs, -k_flow)
    first = rows.add(V - 1, 0.0, 0.0)
    inner = graph.head > 0
    rows.put(first + graph.head[inner] - 1, ix["g"] + arcs[inner], 1.0)
    out = graph.tail > 0
    rows.put(first + graph.tail[out] - 1, ix["g"] + arcs[out], -1.0)
    rows.put(first + others - 1, ix["z"] + others, -1.0)


def _arcs_into(graph: _ReducedGraph) -> list[np.ndarray]:
    order = np.argsort(graph.head, kind="stable")
    bounds = np.searchsorted(graph.head[order], np.arange(len(graph.vertices) + 1))
    return [order[bounds[v] : bounds[v + 1]] for v in range(len(graph.vertices))]


def _highs(program: _Program, budget: MilpBudget, *, relax: bool, time_limit_s: float):  # type: ignore[no-untyped-def]
    """A HiGHS instance holding the program, quiet, single-threaded, with the budget."""
    import highspy

    # the plain binding: highspy.Highs's constructor logs a banner before options can be set
    h = getattr(highspy, "_Highs", highspy.Highs)()
    for name, value in (
        ("output_flag", False),
        ("threads", 1),
        ("random_seed", int(budget.seed)),
        ("mip_max_nodes", int(budget.max_nodes)),
        ("mip_rel_gap", float(budget.rel_gap)),
        ("mip_abs_gap", 1e-9),
        ("time_limit", float(time_limit_s)),
        ("mip_heuristic_run_rins", bool(budget.sub_mip_heuristics)),
        ("mip_heuristic_run_rens", bool(budget.sub_mip_heuristics)),
    ):
        h.setOptionValue(name, value)
    lp = highspy.HighsLp()
    lp.num_col_ = len(program.cost)
    lp.num_row_ = len(program.row_lower)
    lp.col_cost_ = program.cost
    lp.col_lower_ = program.lower
    lp.col_upper_ = program.upper
    lp.row_lower_ = np.where(np.isfinite(program.row_lower), program.row_lower, -highspy.kHighsInf)
    lp.row_upper_ = np.where(np.isfinite(program.row_upper), program.row_upper, highspy.kHighsInf)
    lp.sense_ = highspy.ObjSense.kMaximize
    m = program.a_rows
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.start_ = m.indptr
    lp.a_matrix_.index_ = m.indices
    lp.a_matrix_.value_ = m.data
    if not relax:
        lp.integrality_ = [
            highspy.HighsVarType.kInteger if i else highspy.HighsVarType.kContinuous for i in program.integer
        ]
    h.passModel(lp)
    return h


def _solve(model: StepModel, graph: _ReducedGraph, budget: MilpBudget, started: float) -> OptimumResult:
    program = _program(model, [graph])
    cols = program.blocks
    exact = bool(model.exact and graph.exact)
    lp_bound, cuts, lp_time = _relaxation_bound(program, [graph], budget)

    from planners.rate_greedy import rate_greedy_actions
    from planners.walk_search import polish_walk

    greedy_actions = rate_greedy_actions(model)
    warm_actions = polish_walk(model, greedy_actions, max_evaluations=budget.polish_evaluations, seed=budget.seed)
    warm = _warm_start(model, graph, program, warm_actions)
    run = _branch(program, budget, started, cuts, warm)
    wall = time.perf_counter() - started
    details = {
        **_size_details(program, [graph], cuts, run),
        "rate_greedy_return": model.walk_return(greedy_actions)[0],
        "warm_start_return": model.walk_return(warm_actions)[0],
        "deterministic": bool(model.exact),
        "can_end_early": bool(model.can_finish_early()),
    }
    if run.values is None:
        return _unsolved(OptimumResult, run, lp_bound, lp_time, exact, wall, details)
    x = np.rint(run.values[cols["x"]]).astype(np.int64)
    hov = np.rint(run.values[cols["h"]]).astype(np.int64)
    actions = _trail_actions(model, graph, x, hov)
    objective, used = model.walk_return(actions)
    details["plan"] = "milp"
    warm_value, warm_used = model.walk_return(warm_actions)
    if warm_value > objective:  # only possible with relaxed arcs (a current)
        actions, objective, used, details["plan"] = warm_actions, warm_value, warm_used, "warm start"
    bound = _final_bound(run, lp_bound)
    details["highs_objective"] = run.objective
    details["steps_run"] = used
    state, message = _verdict(model, graph, budget, objective, bound, run.optimal)
    if run.time_hit:
        message += _time_note(budget)
    return OptimumResult(
        state, message, objective, bound, lp_bound, lp_time, actions, exact, run.nodes, run.time_hit, wall, details
    )


class _MipRun(NamedTuple):
    """How a branch-and-bound run ended."""

    values: np.ndarray | None
    """The incumbent's column values (None: no feasible point found)."""
    highs_status: str
    optimal: bool
    infeasible: bool
    time_hit: bool
    """Whether the safety time limit stopped the search."""
    nodes: int
    dual_bound: float
    """HiGHS's dual bound (may be infinite)."""
    objective: float
    """HiGHS's value of the incumbent."""


def _branch(
    program: _Program, budget: MilpBudget, started: float, cuts: list[tuple[np.ndarray, np.ndarray]],
    warm: np.ndarray | None,
) -> _MipRun:
    """Branch and bound on ``program`` with the connectivity ``cuts`` of its relaxation and the
    feasible point ``warm`` (if any), within the budget and what is left of its time limit."""
    import highspy

    left = max(budget.time_limit_s - (time.perf_counter() - started), 1e-3)
    h = _highs(program, budget, relax=False, time_limit_s=left)
    _add_cuts(h, cuts)
    if warm is not None:
        solution = highspy.HighsSolution()
        solution.col_value = warm.tolist()
        solution.value_valid = True
        h.setSolution(solution)
    h.run()
    status = h.getModelStatus()
    info = h.getInfo()
    found = info.primal_solution_status == highspy.kSolutionStatusFeasible
    return _MipRun(
        values=np.asarray(h.getSolution().col_value) if found else None,
        highs_status=h.modelStatusToString(status),
        optimal=status == highspy.HighsModelStatus.kOptimal,
        infeasible=status == highspy.HighsModelStatus.kInfeasible,
        time_hit=status == highspy.HighsModelStatus.kTimeLimit,
        nodes=int(info.mip_node_count),
        dual_bound=float(info.mip_dual_bound),
        objective=float(info.objective_function_value),
    )


def _size_details(
    program: _Program, graphs: list[_ReducedGraph], cuts: list[tuple[np.ndarray, np.ndarray]], run: _MipRun
) -> dict[str, Any]:
    """The program's size (vertices and arcs summed over its walks) and how HiGHS ended."""
    return {
        "vertices": sum(len(graph.vertices) for graph in graphs),
        "arcs": sum(graph.n_arcs for graph in graphs),
        "rows": len(program.row_lower),
        "columns": len(program.cost),
        "highs_status": run.highs_status,
        "cuts": len(cuts),
    }


def _unsolved(
    result_type: Any, run: _MipRun, lp_bound: float | None, lp_time: float | None, exact: bool, wall: float,
    details: dict[str, Any],
) -> Any:
    """The result (of ``result_type``, :class:`OptimumResult` or one with its fields) of a
    run that found no plan: ``error`` if the program is infeasible, else ``no_solution``."""
    if run.infeasible:
        message = "the program is infeasible, which a correct model never is"
        return result_type("error", message, None, None, lp_bound, lp_time, exact=exact, nodes=run.nodes,
                           time_limit_hit=run.time_hit, wall_s=wall, details=details)
    message = f"no walk found within the budget (HiGHS: {run.highs_status})"
    return result_type("no_solution", message, None, _dual_bound(run.dual_bound, lp_bound), lp_bound, lp_time,
                       exact=exact, nodes=run.nodes, time_limit_hit=run.time_hit, wall_s=wall, details=details)


def _final_bound(run: _MipRun, lp_bound: float | None) -> float | None:
    """The tighter of the branch-and-bound's dual bound and the cut rounds' bound."""
    bound = _dual_bound(run.dual_bound, lp_bound)
    if bound is not None and lp_bound is not None:
        bound = min(bound, lp_bound)
    return bound


def _time_note(budget: MilpBudget) -> str:
    return (f"; the safety time limit ({budget.time_limit_s:g} s) was hit, "
            "so this result depends on the machine's speed")


def _relaxation_bound(
    program: _Program, graphs: list[_ReducedGraph], budget: MilpBudget
) -> tuple[float | None, list[tuple[np.ndarray, np.ndarray]], float]:
    """The linear relaxation, tightened by rounds of connectivity cuts (each walk's, over its
    graph): its bound (the least of every round's value, each a bound; None if it did not
    solve), the cuts and its time, s."""
    import highspy

    lp_started = time.perf_counter()
    h = _highs(program, budget, relax=True, time_limit_s=budget.time_limit_s)
    cuts: list[tuple[np.ndarray, np.ndarray]] = []
    lp_bound = None
    most = budget.cut_rounds * sum(len(graph.vertices) for graph in graphs)
    for _ in range(budget.cut_rounds + 1):
        h.run()
        if h.getModelStatus() != highspy.HighsModelStatus.kOptimal:
            break
        value = float(h.getInfo().objective_function_value)
        lp_bound = value if lp_bound is None else min(lp_bound, value)  # each round's is a bound
        values = np.asarray(h.getSolution().col_value)
        found = [
            cut for graph, walk in zip(graphs, program.walks)
            for cut in _separate(graph, values[walk.blocks["x"]], values[walk.blocks["z"]], walk.blocks)
        ]
        if not found or len(cuts) >= most:
            break
        _add_cuts(h, found)
        cuts.extend(found)
    lp_time = time.perf_counter() - lp_started
    return lp_bound, cuts, lp_time


def _verdict(
    model: StepModel, graph: _ReducedGraph, budget: MilpBudget, objective: float, bound: float | None,
    highs_optimal: bool,
) -> tuple[str, str]:
    """The status and message of a walk worth ``objective`` under ``bound``."""
    exact = bool(model.exact and graph.exact)
    gap = (bound - objective) / max(abs(bound), 1e-12) if bound is not None else math.inf
    # HiGHS proves optimality up to its feasibility tolerance (1e-6): its own verdict counts
    if exact and (gap <= max(budget.rel_gap, 1e-9) or highs_optimal):
        return "optimal", "optimal within the budget's rel_gap and the solver's tolerances"
    message = f"best walk with a gap of {100 * gap:.3g} % to the bound"
    relaxed = [reason for reason, applies in (
        ("expected-rate relaxation", not model.exact), ("current: relaxed arcs", not graph.exact)
    ) if applies]
    if relaxed:
        message += f" ({'; '.join(relaxed)})"
    return "feasible", message


def _separate(
    graph: _ReducedGraph, x: np.ndarray, z: np.ndarray, cols: dict[str, slice]
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Connectivity cuts the linear relaxation violates, as (columns, coefficients) rows >= 0.

    For a visited vertex v, every set S of vertices holding v but not the start must be
    entered: sum of x over arcs into S >= z_v. The most violated S for each v is the sink
    side of a minimum s-v cut in the graph with capacities x (max flow, scipy).
    """
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import breadth_first_order, maximum_flow

    n = len(graph.vertices)
    scale = 1e6
    capacity = csr_matrix(
        (np.floor(np.maximum(x, 0.0) * scale).astype(np.int32), (graph.tail, graph.head)), shape=(n, n)
    )
    found: list[tuple[np.ndarray, np.ndarray]] = []
    seen: set[bytes] = set()
    for v in np.argsort(-z, kind="stable"):
        if v == 0 or z[v] < 1e-3:
            continue
        flow = maximum_flow(capacity, 0, int(v))
        if flow.flow_value >= (z[v] - 1e-4) * scale:
            continue
        residual = (capacity - flow.flow).tocsr()
        residual.data[residual.data < 0] = 0
        residual.eliminate_zeros()
        source_side = np.zeros(n, dtype=bool)
        source_side[breadth_first_order(residual, 0, directed=True, return_predecessors=False)] = True
        key = source_side.tobytes()
        if key in seen:
            continue
        seen.add(key)
        sink_side = np.flatnonzero(~source_side)
        entering = np.flatnonzero(source_side[graph.tail] & ~source_side[graph.head])
        w = int(sink_side[np.argmax(z[sink_side])])  # the most violated choice of v in S
        columns = np.concatenate([cols["x"].start + entering, [cols["z"].start + w]])
        found.append((columns, np.concatenate([np.ones(entering.size), [-1.0]])))
    return found


def _add_cuts(h: Any, cuts: list[tuple[np.ndarray, np.ndarray]]) -> None:
    import highspy

    if not cuts:
        return
    starts = np.cumsum([0] + [len(c) for c, _ in cuts[:-1]])
    h.addRows(
        len(cuts),
        np.zeros(len(cuts)),
        np.full(len(cuts), highspy.kHighsInf),
        int(sum(len(c) for c, _ in cuts)),
        starts.astype(np.int32),
        np.concatenate([c for c, _ in cuts]).astype(np.int32),
        np.concatenate([v for _, v in cuts]),
    )


def _dual_bound(bound: float, lp_bound: float | None) -> float | None:
    """HiGHS's dual bound, or ``lp_bound`` when it gave none."""
    if not math.isfinite(bound):
        return lp_bound
    return bound


# --------------------------------------------------------------------------- walks


def _trail_actions(model: StepModel, graph: _ReducedGraph, x: np.ndarray, hovers: np.ndarray) -> list[int]:
    """The arc and hover counts as one walk from the start (an Euler trail), as actions."""
    out: list[list[int]] = [[] for _ in range(len(graph.vertices))]
    for a in np.flatnonzero(x > 0):
        out[graph.tail[a]].extend([int(a)] * int(x[a]))
    for arcs in out:
        arcs.reverse()  # pop() takes them in arc order
    # Hierholzer: walk until stuck, splice the detours in
    stack: list[tuple[int, int]] = [(0, -1)]
    trail: list[tuple[int, int]] = []
    while stack:
        vertex, arc = stack[-1]
        if out[vertex]:
            a = out[vertex].pop()
            stack.append((int(graph.head[a]), a))
        else:
            trail.append(stack.pop())
    trail.reverse()
    actions: list[int] = []
    cell = int(graph.vertices[0])
    hovered = np.zeros(len(graph.vertices), dtype=bool)
    for vertex, arc in trail:
        if arc >= 0:
            for nxt in graph.arc_cells(arc):
                actions.append(_move(model, cell, nxt))
                cell = nxt
        if not hovered[vertex]:
            hovered[vertex] = True
            actions.extend([int(model.stay_action[cell])] * int(hovers[vertex]))
    # a relaxed plan may fall short of the episode: stay where it ends
    actions.extend([int(model.stay_action[cell])] * max(model.steps - len(actions), 0))
    return actions[: model.steps]


def _move(model: StepModel, cell: int, nxt: int) -> int:
    hits = np.flatnonzero(model.next_cell[cell, : K.HOVER] == nxt)
    if hits.size == 0:
        raise RuntimeError(f"cells {cell} and {nxt} are not neighbours")
    return int(hits[0])


def _warm_start(model: StepModel, graph: _ReducedGraph, program: _Program, actions: list[int]) -> np.ndarray | None:
    """A feasible point of the program from a walk of the grid (or None if it has none).

    Stretches between vertices become arcs (split at vertices on equally short paths), the
    extra steps of longer stretches and the tail after the last vertex become hovers at the
    vertex before them: a walk of the model earning at least as much.
    """
    return _warm_point(program, [(model, graph, actions)])


def _warm_point(program: _Program, walks: list[tuple[StepModel, _ReducedGraph, list[int]]]) -> np.ndarray | None:
    """A feasible point of a program of one or more walks from one walk of the grid per
    walk of the program, each ``(model, graph, actions)`` with ``model.start_cell`` the
    graph's start (None if some walk has none): each walk's columns as :func:`_warm_start`
    describes, and the service that all of them deliver together."""
    values = np.zeros(len(program.cost))
    for columns, (model, graph, actions) in zip(program.walks, walks):
        if not _warm_walk(model, graph, columns, actions, values):
            return None
    N = len(program.nodes)
    cols = program.blocks
    data, energy = np.zeros(N), np.zeros(N)
    for walk in program.walks:
        data += np.bincount(walk.pair_node, weights=values[walk.blocks["fd"]], minlength=N)
        energy += np.bincount(walk.pair_node, weights=values[walk.blocks["fe"]], minlength=N)
    values[cols["u"]] = np.minimum(data, 1.0)
    values[cols["w"]] = np.minimum(energy, program.upper[cols["w"]])
    return values


def _warm_walk(
    model: StepModel, graph: _ReducedGraph, walk: _WalkColumns, actions: list[int], values: np.ndarray
) -> bool:
    """Write one walk's columns of the point made from ``actions`` into ``values`` (all but
    the shared service); False if the walk has no such point."""
    counts = _walk_counts(model, graph, actions)
    if counts is None:
        return False
    x, hov, here, entry = counts
    cols = walk.blocks
    V = len(graph.vertices)
    values[cols["x"]] = x
    values[cols["h"]] = hov
    values[cols["y"].start + here] = 1.0
    visited = np.zeros(V, dtype=bool)
    visited[0] = True
    visited[list(entry)] = True
    values[cols["z"]] = visited
    # commodity: down the tree of first entries, one unit per visited vertex below
    below = visited.astype(float)
    below[0] = 0.0
    order = sorted(entry, key=lambda v: -_depth(graph, entry, v))
    g = np.zeros(graph.n_arcs)
    for v in order:
        arc = entry[v]
        g[arc] = below[v]
        below[graph.tail[arc]] += below[v]
    values[cols["g"]] = g
    n = np.zeros(V)
    np.add.at(n, graph.head, x)
    n += hov
    values[cols["fd"]] = np.minimum(walk.pair_data * n[walk.pair_vertex], visited[walk.pair_vertex])
    values[cols["fe"]] = np.minimum(walk.pair_energy * n[walk.pair_vertex], visited[walk.pair_vertex])
    slack = model.steps - float(graph.moves @ x + hov.sum())
    values[cols["slack"]] = slack
    return not (slack < 0 or (graph.exact and slack > 0))


def _walk_counts(
    model: StepModel, graph: _ReducedGraph, actions: list[int]
) -> tuple[np.ndarray, np.ndarray, int, dict[int, int]] | None:
    """A walk of the grid as the model's arc and hover counts (:func:`_warm_start`), its end
    vertex and the arc of each vertex's first entry (None if it maps to no walk)."""
    V = len(graph.vertices)
    index = {int(c): i for i, c in enumerate(graph.vertices)}
    x = np.zeros(graph.n_arcs)
    hov = np.zeros(V)
    entry: dict[int, int] = {}
    cell, here, since = model.start_cell, 0, 0
    steps = 0
    for a in actions[: model.steps]:
        cell = int(model.next_cell[cell, a])
        steps += 1
        since += 1
        v = index.get(cell)
        if v is None:
            continue
        if v == here and since == 1:
            hov[v] += 1
        else:
            path = _split(graph, here, v)
            if path is None:
                return None
            for arc in path:
                x[arc] += 1
                if graph.head[arc] != 0:
                    entry.setdefault(int(graph.head[arc]), arc)
            hov[here] += since - sum(graph.moves[arc] for arc in path)
        here, since = v, 0
    if graph.exact:
        hov[here] += model.steps - (steps - since)  # fill the episode
    if np.any(hov < 0):
        return None
    return x, hov, here, entry


def _depth(graph: _ReducedGraph, entry: dict[int, int], v: int) -> int:
    depth = 0
    while v != 0:
        v = int(graph.tail[entry[v]])
        depth += 1
    return depth


def _split(graph: _ReducedGraph, u: int, w: int) -> list[int] | None:
    """Arcs of the model forming a shortest stretch from vertex u to w (None if none)."""
    if u == w:
        return []
    arcs = np.flatnonzero(graph.tail == u)
    direct = arcs[graph.head[arcs] == w]
    if direct.size:
        return [int(direct[0])]
    # a pruned pair: through a vertex on a path as short and as cheap (as the pruning found)
    s, e = graph.pair_moves, graph.pair_cost
    if not np.isfinite(s[u, w]):
        return None
    via = (s[u] + s[:, w] == s[u, w]) & (e[u] + e[:, w] <= e[u, w] + 1e-9 * max(abs(e[u, w]), 1e-300))
    via[[u, w]] = False
    hits = np.flatnonzero(via)
    if hits.size == 0:
        return None
    first, second = _split(graph, u, int(hits[0])), _split(graph, int(hits[0]), w)
    return None if first is None or second is None else first + second


class MilpPlanner:
    """The MILP's plan as a policy: solves once per environment, then plays its actions.

    ``predict(obs, deterministic=True)`` and ``begin_episode(env, obs, info)`` like the
    planners of :mod:`planners.policies`, so :func:`swiptopt.evaluate` scores it. The plan is
    open loop: with a stochastic channel it does not react to the draws. ``result_`` holds
    the :class:`OptimumResult` (objective, bound, gap, status).
    """

    def __init__(self, *, budget: MilpBudget | str = "default"):
        self.budget = resolve_budget(budget)
        self._env: Any = None

    def begin_episode(self, env: Any, obs: Any = None, info: Any = None) -> None:
        if env is not self._env:
            self._env = env
            self.result_ = solve_optimum(env.scenario, budget=self.budget, tables=env.tables)
            self._stay = step_model(env.tables).stay_action

    def predict(self, obs: Any, deterministic: bool = True) -> int:
        if self._env is None or self._env.state is None:
            raise RuntimeError("call begin_episode(env, obs, info) after each reset (swiptopt.evaluate does)")
        t = self._env.state.t
        actions = self.result_.actions
        if t < len(actions):
            return int(actions[t])
        return int(self._stay[self._env.state.cell])
