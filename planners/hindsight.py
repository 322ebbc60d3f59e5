"""The perfect-information bound: what the best walk earns when it knows every draw beforehand.

Give a policy the whole table of draws before the episode (every step's link-failure uniform
and fading normals, for every node) and its best choice is a walk, found by solving a
deterministic problem. No non-anticipative policy can do better on any table, so the mean
over sampled tables of the hindsight-optimal walk's return bounds the expected return of
every such policy, adaptive or not (docs/optimum.md). The kernel reads a fresh draw for each
covered node in each step, so indexing the draws by (step, node) instead of by the order in
which the kernel reads its buffers gives every policy the same law of episodes.

**Each sample** is a time-indexed mixed-integer program on the MILP's reduced graph
(:mod:`planners.optimal`): one unit of flow from the start at step 0 through the vertices'
time copies, along arcs (``moves`` steps) and hovers (one step), ending at the last step or,
when every node can be covered, *stopping* at any step by which every node has been served
(the kernel ends the episode there, and the walk saves the rest of its penalties). Node i
receives ``min(cap_i, sum over its arrivals of X_t,p)``, with X_t,p the amount the kernel's
own :func:`swiptopt.kernel.serve` delivers from pair p with step t's draws (uncapped: the
kernel's sequential caps add up to the cap of the total). Without a current the program's
optimum is the hindsight-optimal walk's return (a walk's detours through cells that cover
nothing become hovers, which cost no more); with one, the arcs are relaxed and it is a bound.

**The bound** is the mean over samples of each program's proven upper bound (HiGHS's dual
bound within the node budget: the optimum when the search closes), with a 95 % t interval;
its upper end, :attr:`HindsightResult.upper_limit`, bounds every non-anticipative policy's
expected return with 97.5 % confidence (one-sided). Samples are drawn from
``numpy.random.SeedSequence(seed).spawn``: sample k is the same whatever the sample count,
and the same seed and budget give the same numbers.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from planners.bounds import ADAPTIVE, HINDSIGHT_NAME, PolicyBound
from planners.service import StepModel, step_model
from swiptopt import kernel as K
from swiptopt.errors import ConfigError
from swiptopt.scenario import Scenario
from swiptopt.validation import Spec, check_value


@dataclass(frozen=True)
class HindsightBudget:
    """How many draw tables and how much search each gets (deterministic limits)."""

    samples: int = 32
    """Draw tables sampled."""
    seed: int = 0
    """Root of the tables' seeds (``SeedSequence(seed).spawn(samples)``)."""
    max_nodes: int = 200
    """Branch-and-bound nodes per table (HiGHS ``mip_max_nodes``); its dual bound counts.
    0: the linear relaxation alone (a weaker bound per table, no walk, far cheaper)."""
    rel_gap: float = 1e-6
    """Stop a table's search when (bound - best) / |best| is below this."""
    time_limit_s: float = 600.0
    """Safety net per table only: hitting it is reported, as results then depend on the machine."""

    #: What each field may hold, checked at construction (:func:`swiptopt.validation.check_value`).
    FIELDS: ClassVar[dict[str, Spec]] = {
        "samples": Spec(kind="int", lo=2, strict=True, doc="at least two: a confidence interval needs two"),
        "seed": Spec(kind="int", lo=0, strict=True),
        "max_nodes": Spec(kind="int", lo=0, strict=True),
        "rel_gap": Spec(lo=0),
        "time_limit_s": Spec(lo=0, lo_open=True, unit="s"),
    }

    def __post_init__(self) -> None:
        for name, spec in self.FIELDS.items():
            check_value(name, getattr(self, name), spec)


@dataclass(frozen=True, eq=False)
class Draws:
    """One table of draws, indexed by step and node, in the kernel's laws."""

    uniforms: np.ndarray
    """(steps, n_nodes) link-failure uniforms in [0, 1) (ones when no link can fail)."""
    normals: np.ndarray
    """(steps, n_nodes, rows) fading normals (rows = the kernel's ``normal_rows``, at least 1)."""

    @classmethod
    def sample(cls, tables: K.Tables, rng: np.random.Generator | int | None) -> Draws:
        rng = np.random.default_rng(rng)
        steps, n = int(tables.named.steps), tables.n_nodes
        uniforms = rng.random((steps, n)) if tables.draws_uniforms else np.ones((steps, n))
        rows = max(tables.normal_rows, 1)
        normals = rng.standard_normal((steps, n, rows)) if tables.normal_rows else np.zeros((steps, n, rows))
        return cls(uniforms, normals)


def step_amounts(tables: K.Tables, draws: Draws) -> tuple[np.ndarray, np.ndarray]:
    """(steps, nnz) bits and joules each covered pair would deliver in each step with these
    draws, before the node's caps: the kernel's :func:`~swiptopt.kernel.serve` itself, run
    once per step on every pair as a node of its own with unbounded data and storage."""
    serve = K.compiled("serve") if K.numba_available() else K.serve
    nnz = len(tables.cov_node)
    steps = draws.uniforms.shape[0]
    rows = max(tables.normal_rows, 1)
    bits = np.zeros((steps, nnz))
    joules = np.zeros((steps, nnz))
    pseudo = np.arange(nnz, dtype=np.int64)
    unbounded = np.full(nnz, np.inf)
    fail = tables.fail_prob[tables.cov_node].astype(float)
    params = K.replace_params(tables.params, drain_j=0.0)  # no pseudo-node drains (drain is refused anyway)
    gate = tables.named.gate_j
    for t in range(steps):
        uniforms = np.ascontiguousarray(draws.uniforms[t, tables.cov_node])
        normals = np.ascontiguousarray(draws.normals[t, tables.cov_node, :rows].ravel())
        where = np.zeros(4, dtype=np.int64)
        data_left, energy = unbounded.copy(), np.full(nnz, gate)  # at the gate: it never blocks
        delivered, collected = np.zeros(nnz), np.zeros(nnz)
        acc, parts = np.zeros(K.N_ACC), np.zeros(3)
        serve(0.0, 0, nnz, uniforms, normals, pseudo, tables.cov_snr, tables.cov_pav, unbounded, fail, params,
              where, data_left, energy, delivered, collected, acc, parts)
        bits[t], joules[t] = collected, delivered
    return bits, joules


def replay(tables: K.Tables, actions: list[int], draws: Draws) -> float:
    """The kernel's return of ``actions`` when step t's draws for node i are the table's
    (t, i) entries: the buffers are filled in the order the kernel reads them."""
    state = K.new_state(tables)
    n = max(tables.n_nodes, 1)
    rows = tables.normal_rows
    uniforms, normals = np.ones(n), np.zeros(n * max(rows, 1))
    for t, a in enumerate(actions[: draws.uniforms.shape[0]]):
        cell = int(tables.next_cell[state.cell, a])
        nodes = tables.covered(cell)
        uniforms[: len(nodes)] = draws.uniforms[t, nodes]
        if rows:
            normals[: len(nodes) * rows] = draws.normals[t, nodes, :rows].ravel()
        state.where[K.W_UPTR] = state.where[K.W_ZPTR] = 0
        if K.step(int(a), uniforms, normals, K.step_args(tables, state)) != K.RUNNING:
            break
    return float(state.acc[K.A_RETURN])


# --------------------------------------------------------------------------- one table


@dataclass(eq=False)
class _TimeProgram:
    """The time-indexed program of one table: columns, rows and how to read a walk back."""

    cost: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    integer: np.ndarray
    a_rows: Any
    row_lower: np.ndarray
    row_upper: np.ndarray
    arc_col: dict[tuple[int, int], int]
    """(arc, departure step) -> column."""
    hover_col: dict[tuple[int, int], int]
    stop_col: dict[tuple[int, int], int]


class _Triplets:
    """Collects sparse constraint rows one at a time, as (row, column, value) triplets."""

    def __init__(self) -> None:
        self.r: list[int] = []
        self.c: list[int] = []
        self.v: list[float] = []
        self.lo: list[float] = []
        self.hi: list[float] = []

    def row(self, entries: list[tuple[int, float]], low: float, high: float) -> None:
        """Append the row ``low <= sum of value * column <= high`` over ``entries``."""
        k = len(self.lo)
        for col, val in entries:
            self.r.append(k)
            self.c.append(col)
            self.v.append(val)
        self.lo.append(low)
        self.hi.append(high)


class _Layout:
    """The columns and rows shared by every table of a scenario (only the amounts change)."""

    def __init__(self, model: StepModel, graph: Any):
        self.model, self.graph = model, graph
        T = model.steps
        V = len(graph.vertices)
        reach = np.where(np.isfinite(graph.from_start), graph.from_start, T + 1).astype(np.int64)
        reach[0] = 0
        self.reach = reach
        self.nodes = np.flatnonzero(model.coverable())
        self.can_stop = bool(model.can_finish_early())
        self.energy_nodes = self.nodes[model.room_j[self.nodes] > 0]
        cols: list[tuple[str, Any]] = []
        self.arc_col: dict[tuple[int, int], int] = {}
        self.hover_col: dict[tuple[int, int], int] = {}
        self.stop_col: dict[tuple[int, int], int] = {}
        self.arr_col: dict[tuple[int, int], int] = {}
        for a in range(graph.n_arcs):
            u, s = int(graph.tail[a]), int(graph.moves[a])
            for tau in range(reach[u], T - s + 1):
                self.arc_col[(a, tau)] = len(cols)
                cols.append(("x", a))
        for v in range(V):
            for tau in range(reach[v], T):
                self.hover_col[(v, tau)] = len(cols)
                cols.append(("h", v))
            if self.can_stop:
                for tau in range(max(1, reach[v]), T):
                    self.stop_col[(v, tau)] = len(cols)
                    cols.append(("st", v))
            for tau in range(max(1, reach[v]), T + 1):
                self.arr_col[(v, tau)] = len(cols)
                cols.append(("arr", v))
        N = len(self.nodes)
        self.cum_data = len(cols)  # cum_data + i * T + (tau - 1): data fraction delivered by step tau
        cols.extend(("cb", i) for i in range(N * T))
        self.cum_energy = len(cols)
        cols.extend(("ce", i) for i in range(N * T))
        self.served = len(cols)  # u_i then w_i: the data and storage fractions delivered
        cols.extend(("u", i) for i in range(N))
        cols.extend(("w", i) for i in range(N))
        self.n_cols = len(cols)
        kinds = np.array([k for k, _ in cols])
        self.cost = np.zeros(self.n_cols)
        for (a, _), c in self.arc_col.items():
            self.cost[c] = -graph.cost[a]
        for (v, _), c in self.hover_col.items():
            self.cost[c] = -model.stay_cost[graph.vertices[v]]
        data, room = model.data_bits[self.nodes], model.room_j[self.nodes]
        self.cost[self.served : self.served + N] = model.data_weight * data
        self.cost[self.served + N : self.served + 2 * N] = model.energy_weight * room
        self.lower = np.zeros(self.n_cols)
        self.upper = np.where(np.isin(kinds, ("x", "h", "st", "arr")), 1.0, np.inf)
        self.upper[self.served : self.served + N] = 1.0
        self.upper[self.served + N : self.served + 2 * N] = (room > 0).astype(float)
        self.integer = np.isin(kinds, ("x", "h", "st"))
        # which pairs each node is served by: (vertex, pair index in the kernel's lists)
        vertex_of_cell = np.full(model.n_cells, -1, dtype=np.int64)
        vertex_of_cell[graph.vertices] = np.arange(V)
        self.pair_vertex = vertex_of_cell[model.cell_of_pair()]
        node_index = np.full(model.n_nodes, -1, dtype=np.int64)
        node_index[self.nodes] = np.arange(N)
        self.pair_node = node_index[model.cov_node]

    def program(self, bits: np.ndarray, joules: np.ndarray) -> _TimeProgram:
        """The program for one table's (steps, nnz) uncapped amounts."""
        from scipy.sparse import coo_matrix

        rows = _Triplets()
        self._flow_rows(rows)
        self._service_rows(rows, bits, joules)
        self._stop_rows(rows)
        matrix = coo_matrix((rows.v, (rows.r, rows.c)), shape=(len(rows.lo), self.n_cols)).tocsc()
        matrix.sum_duplicates()
        return _TimeProgram(
            self.cost, self.lower, self.upper, self.integer, matrix, np.array(rows.lo), np.array(rows.hi),
            self.arc_col, self.hover_col, self.stop_col,
        )

    def _flow_rows(self, rows: _Triplets) -> None:
        """Flow: what leaves (v, tau) is what arrived, one unit from the start at step 0."""
        graph = self.graph
        T, V = self.model.steps, len(graph.vertices)
        out: dict[tuple[int, int], list[int]] = {}
        into: dict[tuple[int, int], list[int]] = {}
        for (a, tau), col in self.arc_col.items():
            out.setdefault((int(graph.tail[a]), tau), []).append(col)
            into.setdefault((int(graph.head[a]), tau + int(graph.moves[a])), []).append(col)
        for (v, tau), col in self.hover_col.items():
            out.setdefault((v, tau), []).append(col)
            into.setdefault((v, tau + 1), []).append(col)
        for (v, tau), col in self.stop_col.items():
            out.setdefault((v, tau), []).append(col)
        for v in range(V):
            for tau in range(self.reach[v], T):
                entries = [(col, 1.0) for col in out.get((v, tau), [])]
                if tau >= 1:
                    entries.append((self.arr_col[(v, tau)], -1.0))
                supply = 1.0 if (v == 0 and tau == 0) else 0.0
                rows.row(entries, supply, supply)
            for tau in range(max(1, self.reach[v]), T + 1):
                rows.row([(self.arr_col[(v, tau)], 1.0)] + [(col, -1.0) for col in into.get((v, tau), [])], 0.0, 0.0)

    def _service_rows(self, rows: _Triplets, bits: np.ndarray, joules: np.ndarray) -> None:
        """The cumulative service fractions, step by step, and what each node is served in all."""
        model = self.model
        T, N = model.steps, len(self.nodes)
        data, room = model.data_bits[self.nodes], model.room_j[self.nodes]
        ok = self.pair_vertex >= 0
        for block, amounts, caps in ((self.cum_data, bits, data), (self.cum_energy, joules, room)):
            for tau in range(1, T + 1):
                per_node: dict[int, list[tuple[int, float]]] = {i: [] for i in range(N)}
                for p in np.flatnonzero(ok & (amounts[tau - 1] > 0)):
                    i = int(self.pair_node[p])
                    arrival = (int(self.pair_vertex[p]), tau)
                    if caps[i] > 0 and arrival in self.arr_col:
                        per_node[i].append((self.arr_col[arrival], -amounts[tau - 1, p] / caps[i]))
                for i in range(N):
                    entries = [(block + i * T + tau - 1, 1.0)] + per_node[i]
                    if tau > 1:
                        entries.append((block + i * T + tau - 2, -1.0))
                    rows.row(entries, 0.0, 0.0)
        for i in range(N):
            rows.row([(self.served + i, 1.0), (self.cum_data + i * T + T - 1, -1.0)], -np.inf, 0.0)
            if room[i] > 0:
                rows.row([(self.served + N + i, 1.0), (self.cum_energy + i * T + T - 1, -1.0)], -np.inf, 0.0)

    def _stop_rows(self, rows: _Triplets) -> None:
        """A walk stops at tau only once every node is served: its data, and its storage full
        (to the kernel's tolerance) when Gamma < 1."""
        if not self.can_stop:
            return
        model = self.model
        T, N = model.steps, len(self.nodes)
        room = model.room_j[self.nodes]
        tolerance = 1e-12 * model.capacity_j[self.nodes] / np.where(room > 0, room, 1.0)
        for tau in range(1, T):
            stops = [(col, 1.0) for (v, t), col in self.stop_col.items() if t == tau]
            if not stops:
                continue
            for i in range(N):
                rows.row(stops + [(self.cum_data + i * T + tau - 1, -1.0)], -np.inf, 0.0)
                if model.needs_energy and room[i] > 0:
                    rows.row([(col, 1.0 - tolerance[i]) for col, _ in stops]
                             + [(self.cum_energy + i * T + tau - 1, -1.0)], -np.inf, 0.0)

    def walk(self, values: np.ndarray) -> list[int]:
        """The walk of an integer solution, as one action per step (stays after a stop)."""
        from planners.optimal import _move

        model, graph = self.model, self.graph
        T = model.steps
        chosen = {key for key, col in self.arc_col.items() if values[col] > 0.5}
        hovers = {key for key, col in self.hover_col.items() if values[col] > 0.5}
        stops = {key for key, col in self.stop_col.items() if values[col] > 0.5}
        actions: list[int] = []
        v, tau = 0, 0
        cell = int(graph.vertices[0])
        while tau < T and (v, tau) not in stops:
            arc = next((a for a, t in chosen if t == tau and int(graph.tail[a]) == v), None)
            if arc is not None:
                for nxt in graph.arc_cells(arc):
                    actions.append(_move(model, cell, nxt))
                    cell = nxt
                v, tau = int(graph.head[arc]), tau + int(graph.moves[arc])
            elif (v, tau) in hovers:
                actions.append(int(model.stay_action[cell]))
                tau += 1
            else:
                raise RuntimeError(f"the solution's flow breaks off at vertex {v}, step {tau}")
        actions.extend([int(model.stay_action[cell])] * (T - len(actions)))
        return actions


@dataclass(frozen=True, eq=False)
class HindsightSample:
    """One table's program: its proven bound, its best walk and how the search ended."""

    bound: float
    best: float | None
    actions: list[int]
    optimal: bool
    nodes: int
    time_limit_hit: bool
    wall_s: float


def hindsight_walk(
    scenario: Scenario, draws: Draws, *, budget: HindsightBudget | None = None, tables: K.Tables | None = None
) -> HindsightSample:
    """The best walk of ``scenario`` when the draws are known to be ``draws`` (one table's
    program, module docstring). Raises :class:`~swiptopt.errors.ConfigError` for a scenario
    the program cannot express."""
    from planners.optimal import _ReducedGraph, unsupported_reason

    tables = K.build_tables(scenario) if tables is None else tables
    reason = unsupported_reason(scenario, tables)
    if reason:
        raise ConfigError(reason)
    model = step_model(tables)
    layout = _Layout(model, _ReducedGraph.build(model))
    return _solve_table(layout, tables, draws, HindsightBudget() if budget is None else budget)


def _solve_table(layout: _Layout, tables: K.Tables, draws: Draws, budget: HindsightBudget) -> HindsightSample:
    import highspy

    from planners.optimal import MilpBudget, _highs

    started = time.perf_counter()
    program = layout.program(*step_amounts(tables, draws))
    milp = MilpBudget(max_nodes=budget.max_nodes, rel_gap=budget.rel_gap, time_limit_s=budget.time_limit_s,
                      sub_mip_heuristics=False, polish_evaluations=0, cut_rounds=0)
    h = _highs(program, milp, relax=budget.max_nodes == 0, time_limit_s=budget.time_limit_s)
    h.run()
    status = h.getModelStatus()
    info = h.getInfo()
    if budget.max_nodes == 0:
        if status != highspy.HighsModelStatus.kOptimal:
            raise RuntimeError(f"the linear relaxation did not solve ({h.modelStatusToString(status)})")
        return HindsightSample(float(info.objective_function_value), None, [], False, 0, False,
                               time.perf_counter() - started)
    bound = float(info.mip_dual_bound)
    if not math.isfinite(bound):
        raise RuntimeError(f"HiGHS gave no dual bound ({h.modelStatusToString(status)})")
    best, actions = None, []
    if info.primal_solution_status == highspy.kSolutionStatusFeasible:
        values = np.asarray(h.getSolution().col_value)
        actions = layout.walk(values)
        best = float(info.objective_function_value)
    return HindsightSample(
        bound, best, actions, status == highspy.HighsModelStatus.kOptimal, int(info.mip_node_count),
        status == highspy.HighsModelStatus.kTimeLimit, time.perf_counter() - started,
    )


# --------------------------------------------------------------------------- the bound


@dataclass(frozen=True, eq=False)
class HindsightResult:
    """The perfect-information bound over sampled draw tables."""

    status: str
    """``ok``, ``unsupported`` (``message`` says why) or ``error`` (a solver failure)."""
    message: str
    mean: float | None
    """Mean over tables of each table's proven bound: an unbiased estimate of a number at or
    above every non-anticipative policy's expected return."""
    ci95: float | None
    """Half-width of its 95 % t interval."""
    best_mean: float | None
    """Mean over tables of the best walk found (the hindsight optimum where proven)."""
    samples: list[HindsightSample] = field(default_factory=list, repr=False)
    wall_s: float = 0.0

    @property
    def upper_limit(self) -> float | None:
        """mean + ci95: at or above every non-anticipative policy's expected return with
        97.5 % confidence."""
        return None if self.mean is None or self.ci95 is None else self.mean + self.ci95

    def policy_bound(self) -> PolicyBound | None:
        """The upper confidence limit as a bound for every non-anticipative policy (``hindsight``)."""
        limit = self.upper_limit
        if limit is None or not math.isfinite(limit):
            return None
        return PolicyBound(float(limit), HINDSIGHT_NAME, ADAPTIVE)

    @property
    def proven(self) -> int:
        """Tables whose search closed (the bound is the hindsight optimum there)."""
        return sum(s.optimal for s in self.samples)

    @property
    def time_limit_hit(self) -> bool:
        return any(s.time_limit_hit for s in self.samples)


def hindsight_bound(
    scenario: Scenario, *, budget: HindsightBudget | None = None, tables: K.Tables | None = None
) -> HindsightResult:
    """The perfect-information bound of ``scenario`` (module docstring).

    Never raises for a scenario: what the time-indexed program cannot express (the MILP's
    own limits: the uplink, drain, a gate some node starts below, a battery that may run
    out) comes back as status ``unsupported``, a solver failure as ``error``.
    """
    from planners.optimal import _ReducedGraph, unsupported_reason
    from swiptopt.evaluation import Summary

    budget = HindsightBudget() if budget is None else budget
    started = time.perf_counter()
    tables = K.build_tables(scenario) if tables is None else tables
    reason = unsupported_reason(scenario, tables)
    if reason:
        return HindsightResult("unsupported", reason, None, None, None, wall_s=time.perf_counter() - started)
    model = step_model(tables)
    layout = _Layout(model, _ReducedGraph.build(model))
    samples = []
    try:
        for seq in np.random.SeedSequence(budget.seed).spawn(budget.samples):
            samples.append(_solve_table(layout, tables, Draws.sample(tables, np.random.default_rng(seq)), budget))
    except Exception as error:  # a solver failure is a status, never a crash
        return HindsightResult("error", f"{type(error).__name__}: {error}", None, None, None, samples,
                               time.perf_counter() - started)
    summary = Summary.of([s.bound for s in samples])
    mean, ci = summary.mean, summary.ci95
    best = [s.best for s in samples]
    best_mean = float(np.mean(best)) if all(b is not None for b in best) else None
    message = f"{sum(s.optimal for s in samples)}/{len(samples)} tables solved to optimality"
    if any(s.time_limit_hit for s in samples):
        message += (f"; the safety time limit ({budget.time_limit_s:g} s) was hit, "
                    "so this result depends on the machine's speed")
    return HindsightResult("ok", message, mean, ci, best_mean, samples, time.perf_counter() - started)
