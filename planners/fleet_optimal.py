"""A fleet's episode as one mixed-integer program: a walk per AUV, the service shared.

**Formulation.** The single AUV's program (:mod:`planners.optimal`, whose docstring gives
each family of variables and rows) written once per AUV and joined where the AUVs meet:

- each AUV k has its own walk over its own reduced graph, whose vertex 0 is its own start
  cell: arc counts ``x^k``, hover counts ``h^k``, flow balance to one end vertex ``y^k``,
  visits ``z^k`` and the single-commodity flow ``g^k`` that makes the counts one walk,
  and its duration (moves + hovers + ``slack^k`` = ``episode_steps``); AUVs that start in
  one cell share one graph;
- the service is shared: each AUV's (vertex, node) pairs deliver at most their step counts
  times the per-step amounts (and at most everything, only if visited), and node i
  receives ``u_i <= min(1, sum over AUVs and their pairs of i)`` of its data (``w_i`` of
  its free storage): the fleet's rule, since each AUV's transfer in a step is capped at
  what the node still holds or can store, so the node gets the capped sum;
- the whole fleet stops together: without a current every AUV's slack is the same, and it
  may be positive only when every node is served (the single model's ``q``); with a
  current each AUV keeps its own slack, which there also absorbs the relaxed arcs'
  missing steps (:mod:`planners.optimal`, 'Currents');
- the objective is the fleet's return: the service's worth minus every AUV's movement
  penalty, each AUV paying for its own moves and hovers.

With one AUV the program is the single AUV's, column for column and row for row, so
:func:`solve_fleet_optimum` gives :func:`planners.optimal.solve_optimum`'s numbers.

**What it relaxes.** The model has no time index, so it cannot say where each AUV is at
each step. When the scenario's ``share_cells`` is false, two AUVs may not be in one cell,
and an AUV that tries to enter a cell another occupies stays put and pays for its attempted
move. The model drops that rule: its walks may cross and meet. It stays an upper bound for
fleets that obey the rule, because each AUV's episode is still a walk of the grid in which a
blocked move is one more step in the same cell. The model charges such a step as a hover,
and a hover there costs the cheapest action of its cell, moves included (with shared cells
or one AUV: the cheapest stay, :attr:`~planners.service.StepModel.stay_cost`). Without a
current the two are the same, since every move costs alike and no stay costs more than a
move; with one, a move with the current can be cheaper than holding station against it.
Its walks, though, may be blocked when played: then the plan earns less than the
program's value, the status is at best ``feasible``, and the message counts the blocked
moves.

**The plan as played.** Each AUV follows its walk's actions (:func:`fleet_walk_return` and
:class:`FleetMilpPlanner` apply one rule): while it is where its walk has it, it plays the
walk's next action; when another AUV blocked its last move, it tries that move again, and
the rest of its walk runs a step later (cut off at the episode's end); after its walk, it
takes the cheapest stay. ``objective`` is what the plan earns under the fleet's rules,
blocked moves included (the simulator's return with a deterministic channel, else its value
in the expected-rate relaxation). Two AUVs that each wait for the other's cell stay blocked:
the model knows nothing of time, so its plans are not arranged to avoid that.

**Bounds** (:func:`fleet_policy_bounds`). With a deterministic channel ``bound`` holds for
every fleet policy, open-loop or adaptive, under either rule for cells: each policy's
episode is one set of walks, which the model contains (cell sharing relaxed, blocked moves
charged no more than they cost). What the relaxation can cost is the other side: with
shared cells (or one AUV) and no current the model is exact, so its best plan earns its
value and the gap is the search's alone; when the AUVs must keep apart, the program's best
plan may be unplayable, and the gap between ``bound`` and ``objective`` holds both the
search's gap and the relaxation's. ``optimal`` is reported only when the plan, played
under the scenario's own rule, comes within ``rel_gap`` of ``bound``, which then proves it
optimal among all fleet policies. With a stochastic channel the single model's reasoning
(docs/optimum.md) carries over AUV by AUV: ``lp_bound`` holds for every non-anticipative
fleet policy (their expected step counts lie in the convex hull of the fleet's walks;
Jensen's inequality for the shared caps; the early end as for one AUV); ``bound`` holds for
open-loop fleet plans, the one :class:`FleetMilpPlanner` plays included (where its moves are
blocked does not depend on the draws), when no episode can end early (some node no cell
covers). Every bound assumes what the model assumes: no battery runs out within the
episode (else the scenario is ``unsupported``).

**Symmetry.** AUVs with different start cells are not interchangeable. AUVs that start in
the same cell (possible only when cells are shared) are: any plan with their walks swapped
is as good. For each such pair (k, l), k < l, the program asks AUV k's walk to make at least
as many moves (summed over its arcs) as AUV l's, which removes the swapped copies without
removing any value.

**Solving.** As the single model: rounds of connectivity cuts on the linear relaxation, for
every walk (``lp_bound``), then HiGHS's branch and bound from a warm start within the node
budget of a :class:`~planners.optimal.MilpBudget` (``BUDGETS``: the wall clock only as a safety
net that the status reports). The warm start plans the AUVs one after another: AUV k takes
the single model's warm-start walk (the rate-greedy walk polished by local search, each
with the budget's ``polish_evaluations``) for the data and storage that AUVs 0..k-1 leave;
AUVs that share a start are ordered by their moves to meet the symmetry rows. The program
grows with the AUVs: ``max_arcs`` caps the arcs of all the walks together, and what the
single model refuses (:func:`planners.optimal.unsupported_reason`, with each AUV's own
battery) it refuses too, as status ``unsupported``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from planners.bounds import PolicyBound
from planners.optimal import (
    MilpBudget,
    OptimumResult,
    _branch,
    _final_bound,
    _program,
    _ReducedGraph,
    _relaxation_bound,
    _Rows,
    _size_details,
    _time_note,
    _trail_actions,
    _unsolved,
    _verdict,
    _walk_counts,
    _WalkColumns,
    _warm_point,
    policy_bounds,
    resolve_budget,
    unsupported_reason,
)
from planners.service import StepModel, step_model
from swiptopt import fleet as F
from swiptopt import kernel as K
from swiptopt.scenario import Scenario


@dataclass(frozen=True, eq=False)
class FleetOptimumResult(OptimumResult):
    """The fleet program's best plan (a walk per AUV), its value, a proven bound and how the
    search ended: :class:`~planners.optimal.OptimumResult`'s fields, read for the fleet:

    - ``status``: ``optimal`` only when the model is exact (deterministic channel, no
      current), the plan is played without a blocked move and the gap is within the
      budget's ``rel_gap``;
    - ``objective``: what the plan earns under the fleet's rules (module docstring), blocked
      moves included: the simulator's return with a deterministic channel, else its value in
      the expected-rate relaxation (``details["milp_objective"]`` is the program's own value
      of its plan);
    - ``bound``: a proven upper bound on the fleet's return (:func:`fleet_policy_bounds` says
      for which policies);
    - ``actions``: for each AUV, one action per step (empty when there is no plan);
    - ``exact``: whether the per-step amounts and move costs are the simulator's own;
      ``details["relaxes_cell_sharing"]`` says whether the model also lets AUVs share cells
      that the scenario keeps apart.
    """

    actions: list[list[int]] = field(default_factory=list)  # type: ignore[assignment]


def fleet_policy_bounds(result: FleetOptimumResult) -> list[PolicyBound]:
    """The bounds of ``result`` with the class of fleet policy each holds for (module
    docstring), under the single model's names:

    - deterministic channel: ``bound`` as ``milp``, for every fleet policy (adaptive ones,
      and fleets that keep to their own cells, included);
    - stochastic channel: ``lp_bound`` as ``lp (expected)`` for every non-anticipative fleet
      policy, and ``bound`` as ``milp (expected)`` for open-loop fleet plans, only when no
      episode can end early and only when it is below ``lp_bound``.

    Empty when the solve found no bound.
    """
    return policy_bounds(result)  # type: ignore[arg-type]  # the same fields, the same rules


def solve_fleet_optimum(
    scenario: Scenario, *, budget: MilpBudget | str = "default", tables: K.Tables | None = None
) -> FleetOptimumResult:
    """The best plan of a fleet scenario (a walk per AUV from its own start cell) by
    mixed-integer programming (module docstring).

    Never raises for a scenario: what the model cannot express comes back as status
    ``unsupported`` and a solver failure as ``error``, each with a message naming the reason.
    A bad ``budget`` raises :class:`~swiptopt.errors.ConfigError`. ``tables``: the scenario's
    kernel tables when the caller has them (a fleet env's ``env.fleet.tables``).
    """
    budget = resolve_budget(budget)
    started = time.perf_counter()
    tables = K.build_tables(scenario) if tables is None else tables
    reason = unsupported_reason(scenario, tables, scenario.auv_batteries_j)
    if reason:
        return _refused(reason, started)
    fleet = F.fleet_tables(scenario, tables)
    models = auv_models(step_model(tables), fleet.start_cells)
    graphs = _graphs(models)
    arcs = sum(graph.n_arcs for graph in graphs)
    if arcs > budget.max_arcs:
        return _refused(f"the reduced graphs have {arcs} arcs in all, more than max_arcs = {budget.max_arcs}",
                        started)
    try:
        return _solve(models, graphs, bool(fleet.share_cells), budget, started)
    except Exception as error:  # a solver failure is a status, never a crash
        return FleetOptimumResult("error", f"{type(error).__name__}: {error}", None, None, None, None,
                                  wall_s=time.perf_counter() - started)


def auv_models(model: StepModel, start_cells: Any) -> list[StepModel]:
    """One step model per AUV: ``model`` with each AUV's start cell."""
    return [model if int(c) == model.start_cell else replace(model, start_cell=int(c)) for c in start_cells]


def _refused(reason: str, started: float) -> FleetOptimumResult:
    return FleetOptimumResult("unsupported", reason, None, None, None, None, wall_s=time.perf_counter() - started)


def _graphs(models: list[StepModel]) -> list[_ReducedGraph]:
    """Each AUV's reduced graph, from its own start (one graph for AUVs with one start)."""
    built: dict[int, _ReducedGraph] = {}
    for model in models:
        if model.start_cell not in built:
            built[model.start_cell] = _ReducedGraph.build(model)
    return [built[model.start_cell] for model in models]


def _alike(models: list[StepModel]) -> list[list[int]]:
    """The groups of two or more AUVs that start in one cell, each in AUV order."""
    groups: dict[int, list[int]] = {}
    for k, model in enumerate(models):
        groups.setdefault(model.start_cell, []).append(k)
    return [group for group in groups.values() if len(group) > 1]


def _fleet_rows(
    graphs: list[_ReducedGraph], groups: list[list[int]]
) -> Callable[[_Rows, list[_WalkColumns]], None]:
    """The rows joining the walks beyond the shared service: one end for the whole fleet
    (every slack equal; without a current, where slack is only the early end), and the
    symmetry rows of AUVs that start in one cell (module docstring)."""

    def add(rows: _Rows, walks: list[_WalkColumns]) -> None:
        if graphs[0].exact:
            for walk in walks[1:]:
                rows.put(rows.add(1, 0.0, 0.0), [walk.starts["slack"], walks[0].starts["slack"]], [1.0, -1.0])
        for group in groups:
            for k, later in zip(group, group[1:]):
                row = rows.add(1, 0.0, np.inf)
                rows.put(row, walks[k].starts["x"] + np.arange(graphs[k].n_arcs), graphs[k].moves)
                rows.put(row, walks[later].starts["x"] + np.arange(graphs[later].n_arcs), -graphs[later].moves)

    return add


def _solve(
    models: list[StepModel], graphs: list[_ReducedGraph], share_cells: bool, budget: MilpBudget, started: float
) -> FleetOptimumResult:
    model = models[0]
    relaxed = len(models) > 1 and not share_cells
    groups = _alike(models)
    # a move another AUV blocks costs its attempt: a hover is charged the cheapest action
    stay_cost = model.step_cost.min(axis=1) if relaxed else None
    program = _program(model, graphs, stay_cost=stay_cost, extra_rows=_fleet_rows(graphs, groups))
    exact = bool(model.exact and graphs[0].exact)  # every AUV's graph is exact or none is
    lp_bound, cuts, lp_time = _relaxation_bound(program, graphs, budget)
    warm_plans = _warm_plans(models, graphs, groups, budget)
    warm = _warm_point(program, list(zip(models, graphs, warm_plans)))
    run = _branch(program, budget, started, cuts, warm)
    wall = time.perf_counter() - started
    warm_value, warm_used, warm_blocked = fleet_walk_return(models, warm_plans, share_cells)
    details = {
        **_size_details(program, graphs, cuts, run),
        "warm_start_return": float(warm_value),
        "deterministic": bool(model.exact),
        "can_end_early": bool(model.can_finish_early()),
        "n_auvs": len(models),
        "share_cells": share_cells,
        "relaxes_cell_sharing": relaxed,
        "symmetry_rows": sum(len(group) - 1 for group in groups),
    }
    if run.values is None:
        return _unsolved(FleetOptimumResult, run, lp_bound, lp_time, exact, wall, details)
    plans = [
        _trail_actions(m, graph, np.rint(run.values[walk.blocks["x"]]).astype(np.int64),
                       np.rint(run.values[walk.blocks["h"]]).astype(np.int64))
        for m, graph, walk in zip(models, graphs, program.walks)
    ]
    objective, used, blocked = fleet_walk_return(models, plans, share_cells)
    details["plan"] = "milp"
    if warm_value > objective:  # a current's relaxed arcs, or the program's plan blocked more
        plans, objective, used, blocked, details["plan"] = warm_plans, warm_value, warm_used, warm_blocked, "warm start"
    bound = _final_bound(run, lp_bound)
    details.update(milp_objective=run.objective, highs_objective=run.objective, steps_run=used, blocked_moves=blocked)
    state, message = _verdict(model, graphs[0], budget, objective, bound,
                              run.optimal and blocked == 0 and details["plan"] == "milp")
    if blocked:
        message += (f"; {blocked} moves of the plan are blocked by another AUV when played "
                    "(the model lets AUVs share cells)")
    if run.time_hit:
        message += _time_note(budget)
    return FleetOptimumResult(
        state, message, objective, bound, lp_bound, lp_time, plans, exact, run.nodes, run.time_hit, wall, details
    )


def _warm_plans(
    models: list[StepModel], graphs: list[_ReducedGraph], groups: list[list[int]], budget: MilpBudget
) -> list[list[int]]:
    """Each AUV's warm-start walk (module docstring): the rate-greedy walk polished by local
    search, planned for what the AUVs before it leave; AUVs that share a start then swap
    walks so that the earlier one makes at least as many moves (the symmetry rows)."""
    from planners.rate_greedy import rate_greedy_actions
    from planners.walk_search import polish_walk

    data_left = models[0].data_bits.astype(float).copy()
    room_left = models[0].room_j.astype(float).copy()
    plans = []
    for k, model in enumerate(models):
        residual = model if k == 0 else _residual(model, data_left, room_left)
        greedy = rate_greedy_actions(residual)
        plan = polish_walk(residual, greedy, max_evaluations=budget.polish_evaluations, seed=budget.seed)
        plans.append(plan)
        cell = model.start_cell
        for a in plan[: model.steps]:
            cell = int(model.next_cell[cell, a])
            model.serve(cell, data_left, room_left)
    for group in groups:
        moves = []
        for k in group:
            counts = _walk_counts(models[k], graphs[k], plans[k])
            moves.append(-1.0 if counts is None else float(graphs[k].moves @ counts[0]))
        order = sorted(range(len(group)), key=lambda i: -moves[i])
        chosen = [plans[group[i]] for i in order]
        for k, plan in zip(group, chosen):
            plans[k] = plan
    return plans


def _residual(model: StepModel, data_left: np.ndarray, room_left: np.ndarray) -> StepModel:
    """``model`` for nodes that hold only ``data_left`` and can store only ``room_left``."""
    data, room = data_left.copy(), room_left.copy()
    return replace(
        model, data_bits=data, room_j=room,
        bits=np.minimum(model.bits, data[model.cov_node]), joules=np.minimum(model.joules, room[model.cov_node]),
    )


# --------------------------------------------------------------------------- playing a plan


class _WalkFollower:
    """Plays one AUV's planned walk under the fleet's rules (module docstring): the walk's
    next action while the AUV is where the walk has it, the same move again when another
    AUV blocked it, the cheapest stay after the walk's end."""

    def __init__(self, model: StepModel, actions: list[int]):
        self._actions = [int(a) for a in actions]
        self._stay = model.stay_action
        cells = [model.start_cell]  # the cell before each step of the walk, when nothing blocks it
        for a in self._actions:
            cells.append(int(model.next_cell[cells[-1], a]))
        self._cells = cells
        self._next = 0  # the walk's next step

    def action(self, cell: int) -> int:
        """The action from ``cell``, the AUV's cell now."""
        j = self._next
        if j > 0 and cell != self._cells[j] and cell == self._cells[j - 1]:
            j -= 1  # the last move was blocked: try it again
        if j >= len(self._actions):
            return int(self._stay[cell])
        self._next = j + 1
        return self._actions[j]


def fleet_walk_return(
    models: list[StepModel], plans: list[list[int]], share_cells: bool
) -> tuple[float, int, int]:
    """What a fleet plan (one action list per AUV, ``models[k]`` starting at AUV k's start
    cell) earns under the fleet's rules, the steps it runs and how many moves another AUV
    blocks (never any when ``share_cells``).

    The fleet's step (:func:`swiptopt.fleet.fleet_step`) with the per-step model: each AUV
    in turn moves (blocked when another AUV is in the target cell and cells are not shared)
    and serves; the episode ends after ``steps`` steps or once every node is served. Each
    AUV plays its walk as :class:`FleetMilpPlanner` does. One AUV: the same arithmetic as
    :meth:`~planners.service.StepModel.walk_return`. Deterministic channel: the simulator's
    return (up to float summation order).
    """
    first = models[0]
    data_left = first.data_bits.astype(float).copy()
    room_left = first.room_j.astype(float).copy()
    followers = [_WalkFollower(model, plan) for model, plan in zip(models, plans)]
    cells = [model.start_cell for model in models]
    total, used, blocked = 0.0, 0, 0
    for _ in range(first.steps):
        served = False
        for k, follower in enumerate(followers):
            cell = cells[k]
            a = follower.action(cell)
            target = int(first.next_cell[cell, a])
            if not share_cells and target != cell and target in cells[:k] + cells[k + 1:]:
                target = cell
                blocked += 1
            total -= first.step_cost[cell, a]
            cells[k] = target
            gained = first.serve(target, data_left, room_left)
            total += gained
            served = served or gained > 0.0
        used += 1
        if served and first.all_served(data_left, room_left):
            break
    return float(total), used, blocked


class FleetMilpPlanner:
    """The fleet program's plan as a fleet policy: solves once per layout, then each AUV
    follows its walk (module docstring: a blocked move is tried again).

    ``begin_episode(env, observations, infos)`` after each reset of an
    :class:`~swiptopt.env_fleet.AuvFleetEnv` (solves when ``env.fleet`` is not the one it
    solved for), then ``act(observations)`` gives one action per live agent, as
    :func:`swiptopt.evaluation.evaluate_fleet` expects. The plan is open loop: it reads
    only the AUVs' cells. ``result_`` holds the :class:`FleetOptimumResult` (objective,
    bound, gap, status); :meth:`policy_bounds` its bounds with the policies each holds for.
    """

    def __init__(self, *, budget: MilpBudget | str = "default"):
        self.budget = resolve_budget(budget)
        self._env: Any = None
        self._fleet: Any = None
        self._models: list[StepModel] = []
        self._followers: list[_WalkFollower] = []

    def begin_episode(self, env: Any, observations: Any = None, infos: Any = None) -> None:
        """Solve for ``env``'s layout when it is new, and start every AUV at its walk's start."""
        if env is not self._env or env.fleet is not self._fleet:
            self._env, self._fleet = env, env.fleet
            self.result_ = solve_fleet_optimum(env.scenario, budget=self.budget, tables=env.fleet.tables)
            self._models = auv_models(step_model(env.fleet.tables), env.fleet.start_cells)
        plans = self.result_.actions or [[] for _ in self._models]
        self._followers = [_WalkFollower(model, plan) for model, plan in zip(self._models, plans)]

    def act(self, observations: Any = None) -> dict[str, int]:
        """One action per live agent of the env (``observations`` is not read)."""
        if self._env is None or self._env.fleet_state is None:
            raise RuntimeError("call begin_episode(env, observations, infos) after each reset "
                               "(swiptopt.evaluation.evaluate_fleet does)")
        cells = self._env.fleet_state.cells
        live = set(self._env.agents)
        return {
            agent: follower.action(int(cells[k]))
            for k, (agent, follower) in enumerate(zip(self._env.possible_agents, self._followers))
            if agent in live
        }

    def policy_bounds(self) -> list[PolicyBound]:
        """The bounds of the last solve (:func:`fleet_policy_bounds`)."""
        return fleet_policy_bounds(self.result_)


__all__ = [
    "FleetMilpPlanner",
    "FleetOptimumResult",
    "auv_models",
    "fleet_policy_bounds",
    "fleet_walk_return",
    "solve_fleet_optimum",
]

