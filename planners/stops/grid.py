"""The grid world's stop-choice environment: the action is the next stop and its dwell.

The candidate stops of a layout (:func:`build_grid_stops`), the executor of one decision
(:class:`GridMove`: the planners' shortest grid paths, then hovers) and the environment
(:class:`StopChoiceEnv`) over :class:`swiptopt.env.AuvSwiptEnv`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from planners.grid import bfs_distances
from planners.policies import _REVERSE, reachable
from planners.service import step_model
from planners.stops.base import (
    DWELLS,
    MASKED_ACTIONS,
    Dwell,
    StopEnvBase,
    check_dwells,
    node_worth,
)
from swiptopt import kernel as K
from swiptopt.scenario import Scenario
from swiptopt.validation import Spec, check_value

#: Which stops are candidates: ``"own"``: one per node, the reachable cell where one step earns
#: the most from that node; ``"own+shared"``: those, then one more per node, the cell that
#: earns the most from all nodes among those earning at least ``shared_fraction`` of the own
#: stop's amount from that node.
CANDIDATES = ("own", "own+shared")


@dataclass(frozen=True)
class GridStopSettings:
    """The choices of :class:`StopChoiceEnv` (see its docstring, Arguments)."""

    dwells: tuple[Dwell, ...] = DWELLS
    """The dwell choices, in action order."""
    candidates: str = "own+shared"
    """:data:`CANDIDATES`."""
    shared_fraction: float = 0.5
    """A node's shared stop earns at least this fraction of its own stop's one-step amount from it."""
    masked_action: str = "raise"
    """:data:`planners.stops.base.MASKED_ACTIONS`."""

    #: What the settings other than ``dwells`` may hold, checked at construction.
    FIELDS: ClassVar[dict[str, Spec]] = {
        "candidates": Spec(kind="str", choices=CANDIDATES),
        "shared_fraction": Spec(lo=0, lo_open=True, hi=1),
        "masked_action": Spec(kind="str", choices=MASKED_ACTIONS),
    }

    def __post_init__(self) -> None:
        object.__setattr__(self, "dwells", check_dwells(self.dwells))
        for name, spec in self.FIELDS.items():
            check_value(name, getattr(self, name), spec)

    @property
    def candidates_per_node(self) -> int:
        return 2 if self.candidates == "own+shared" else 1


@dataclass(frozen=True, eq=False)
class GridStops:
    """The candidate stops of one layout and what deciding among them needs, built once."""

    cells: np.ndarray
    """(C,) each candidate's cell (the start cell where the stop does not exist)."""
    nodes: np.ndarray
    """(C,) the node each candidate was chosen for (candidate c serves node c % n_nodes)."""
    valid: np.ndarray
    """(C,) bool: the stop exists (its node is covered from a reachable cell; not a copy of an
    earlier candidate's cell)."""
    why_invalid: tuple[str, ...]
    """Per candidate, why it does not exist ("" when it does)."""
    pair_cand: np.ndarray
    """(P,) the covered pairs of the candidates' cells: candidate of each pair..."""
    pair_node: np.ndarray
    """(P,) ... its node ..."""
    pair_bits: np.ndarray
    """(P,) ... bits one step there delivers from it (the per-step model's, expected) ..."""
    pair_joules: np.ndarray
    """(P,) ... and joules one step there delivers to it."""
    dist_to: np.ndarray
    """(C, n_cells) int32: moves from every cell to each candidate (-1: no way)."""
    via_to: np.ndarray
    """(C, n_cells) int8: the move into every cell on a shortest path grown from the candidate
    (the executor walks it backwards, as :class:`planners.policies.PlanExecutor` does)."""
    data_weight: float
    energy_weight: float
    worth: float
    """The observation's scale of earnings (:func:`planners.stops.base.node_worth`)."""
    capacity: np.ndarray
    params: np.ndarray
    cells_norm: np.ndarray
    """(n_cells, 3) cell centres over the extent (the kernel's vector observation)."""
    nodes_norm: np.ndarray
    """(n_nodes, 3) node positions over the extent."""

    #: The grid needs no record of where the AUV is beyond the kernel's cell.
    start_site = None

    @staticmethod
    def hover() -> int:
        return K.HOVER

    @property
    def n_candidates(self) -> int:
        return len(self.cells)

    def reach_steps(self, env: Any, site: Any) -> np.ndarray:
        """(C,) moves from the AUV's cell to each candidate (-1: no way)."""
        return self.dist_to[:, int(env.state.where[K.W_CELL])].astype(np.int64)

    def move(self, env: Any, site: Any, candidate: int, dwell: Dwell) -> GridMove:
        cell = int(self.cells[candidate])
        return GridMove(cell, self.via_to[candidate], env.tables.covered(cell), dwell)

    def base_observation(self, env: Any) -> np.ndarray:
        """The kernel's vector observation of the env's state (whatever observation it returns)."""
        t, s = env.tables, env.state
        out = np.empty(4 + K.VECTOR_NODE_FEATURES * t.n_nodes, dtype=np.float32)
        K.vector_observation(
            s.where[K.W_CELL], s.where[K.W_T], t.cov_ptr, t.cov_node, s.data_left, s.energy, t.data0, t.capacity,
            t.params, self.cells_norm, self.nodes_norm, out,
        )
        return out


def build_grid_stops(tables: K.Tables, scenario: Scenario, settings: GridStopSettings,
                     starts: Iterable[int] | None = None) -> GridStops:
    """The candidate stops of ``scenario``'s layout (``tables`` its kernel tables), over the
    cells reachable from ``tables.start_cell`` (or, given ``starts``, from any of those cells:
    a fleet's start cells).

    Node i's own stop is the reachable cell where one step earns the most reward from node i
    in the per-step model (:func:`planners.service.step_model`: the kernel's amounts, expected
    under fading and link failures, capped at what the node holds), ties to the cell that earns
    more from every node, then the lower index. Its shared stop (``"own+shared"``) is the
    cell earning the most from every node among those that earn at least ``shared_fraction``
    of that from node i, ties to more from node i, then the lower index. A node no reachable
    cell covers has no stop; a stop on the cell of an earlier candidate is a copy and does not
    exist either (so no two actions do the same thing).
    """
    where = reachable(tables, starts)
    model = step_model(where.tables)
    n = tables.n_nodes
    own, shared = _best_cells(model, n, settings.shared_fraction)
    chosen = own if settings.candidates == "own" else np.concatenate([own, shared])
    nodes = np.tile(np.arange(n), settings.candidates_per_node)

    count = len(chosen)
    valid = chosen >= 0
    why = ["" if v else f"no reachable cell covers node {nodes[c]}" for c, v in enumerate(valid)]
    seen: dict[int, int] = {}
    for c in range(count):
        if valid[c]:
            first = seen.setdefault(int(chosen[c]), c)
            if first != c:
                valid[c] = False
                why[c] = f"its cell is stop {first}'s"
    cells = np.where(valid, chosen, tables.start_cell)
    dist_to, via_to = _paths_to(tables, cells, valid)

    pair_cand, pair_index = [], []
    for c in np.flatnonzero(valid):
        lo, hi = model.cov_ptr[cells[c]], model.cov_ptr[cells[c] + 1]
        pair_cand.append(np.full(hi - lo, c, dtype=np.int64))
        pair_index.append(np.arange(lo, hi))
    index = np.concatenate(pair_index) if pair_index else np.zeros(0, dtype=np.int64)
    p = tables.params
    return GridStops(
        cells=cells.astype(np.int64),
        nodes=nodes,
        valid=valid,
        why_invalid=tuple(why),
        pair_cand=np.concatenate(pair_cand) if pair_cand else np.zeros(0, dtype=np.int64),
        pair_node=model.cov_node[index],
        pair_bits=model.bits[index],
        pair_joules=model.joules[index],
        dist_to=dist_to,
        via_to=via_to,
        data_weight=model.data_weight,
        energy_weight=model.energy_weight,
        worth=node_worth(K.named(p), scenario.data_bits, scenario.storage_capacity_j),
        capacity=tables.capacity,
        params=p,
        cells_norm=np.ascontiguousarray(scenario.cell_centers_m / scenario.extent_m),
        nodes_norm=np.ascontiguousarray(scenario.layout.positions_m / scenario.extent_m),
    )


def _best_cells(model: Any, n: int, shared_fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """(n,) each node's own stop cell and (n,) its shared stop cell (-1: none), as
    :func:`build_grid_stops` chooses them."""
    per_pair = model.data_weight * model.bits + model.energy_weight * model.joules
    pair_cell = model.cell_of_pair()
    total = np.bincount(pair_cell, weights=per_pair, minlength=model.n_cells)
    by_node = np.argsort(model.cov_node, kind="stable")
    bounds = np.searchsorted(model.cov_node[by_node], np.arange(n + 1))
    own = np.full(n, -1, dtype=np.int64)
    shared = np.full(n, -1, dtype=np.int64)
    for i in range(n):
        pairs = by_node[bounds[i] : bounds[i + 1]]
        if pairs.size == 0:
            continue
        cells, value = pair_cell[pairs], per_pair[pairs]
        own[i] = cells[np.lexsort((cells, -total[cells], -value))[0]]
        near = value >= shared_fraction * value.max()
        cells, value = cells[near], value[near]
        shared[i] = cells[np.lexsort((cells, -value, -total[cells]))[0]]
    return own, shared


def _paths_to(tables: K.Tables, cells: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(C, n_cells) moves between each valid candidate's cell and every cell (-1: no way),
    and (C, n_cells) the move into each cell on the BFS tree grown from the candidate's cell
    (which :class:`GridMove` walks backwards)."""
    count = len(cells)
    dist_to = np.full((count, tables.n_cells), -1, dtype=np.int32)
    via_to = np.full((count, tables.n_cells), -1, dtype=np.int8)
    trees: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for c in np.flatnonzero(valid):
        cell = int(cells[c])
        if cell not in trees:
            dist, tree = bfs_distances(tables.next_cell, cell)
            trees[cell] = (dist, tree[0])
        dist_to[c], via_to[c] = trees[cell]
    return dist_to, via_to


class GridMove:
    """Carries out one decision on the grid, one kernel action per call: the moves of a
    shortest path to the stop's cell (the executor's: the BFS tree grown from the target,
    walked backwards), then hovers until the dwell is done."""

    site_after = None

    def __init__(self, target: int, via: np.ndarray, covered: np.ndarray, dwell: Dwell):
        self.target = target
        self.via = via
        self.covered = covered
        self.dwell = dwell
        self.moved = False
        self.service = 0  # service steps at the stop so far, the arrival counted

    def _dwell_over(self, env: Any) -> bool:
        s = env.state
        if self.dwell.until == "data":
            return not bool(np.any(s.data_left[self.covered] > 0.0))
        unserved = ~K.served_mask(s.data_left[self.covered], s.energy[self.covered], env.tables.capacity[self.covered],
                                  env.tables.named.reward_weight)
        return not bool(unserved.any())

    def next_action(self, env: Any) -> int | None:
        cell = int(env.state.where[K.W_CELL])
        if cell != self.target:
            self.moved = True
            return int(_REVERSE[self.via[cell]])
        if self.moved and self.service == 0:
            self.service = 1  # the arrival step served
        if self.service >= self.dwell.steps:
            return None
        if self.service >= 1 and self.dwell.until is not None and self._dwell_over(env):
            return None
        self.service += 1
        return K.HOVER


class StopChoiceEnv(StopEnvBase):
    """
    ## Description

    The grid world of ``swiptopt/AuvSwipt-v1`` decided one stop at a time, as the tour
    planners decide: each action picks the next stop among fixed candidates and how long to
    serve there; the AUV then moves along a shortest grid path to it (the planners' executor's
    moves, :mod:`planners.policies`) and hovers for the dwell, each move and hover a step of
    the wrapped :class:`swiptopt.env.AuvSwiptEnv` (the same kernel, the same draws). Actions
    that cannot help are masked (:meth:`action_masks`, read by ``sb3_contrib.MaskablePPO``).

    The candidates of a layout (:func:`build_grid_stops`): per node, its *own* stop, the
    reachable cell where one step earns the most reward from it; with ``candidates =
    "own+shared"`` (the default) also its *shared* stop, the cell earning the most from all
    nodes among those that still earn at least ``shared_fraction`` of that from it (a hover
    point for a group, as k-means + TSP picks them). Candidate c belongs to node c % n_nodes:
    the count is fixed by ``n_nodes``, so the spaces stay the same across layouts.

    ## Action Space

    ``Discrete(C * D + 1)`` with C candidates (n_nodes or 2 n_nodes) and D dwell choices
    (default :data:`planners.stops.base.DWELLS`: 1, 2, 3, 5, 8 service steps, until the
    stop's nodes hold no data (at most 8), until they are served (at most 12)). Action
    ``c * D + d`` goes to candidate c and dwells ``dwells[d]`` (the arrival step is the first
    service step; at the stop the AUV is already at, every service step is a hover). The last
    action hovers one step (the fallback). A flat action rather than ``MultiDiscrete``:
    MaskablePPO masks each part of a ``MultiDiscrete`` on its own, so a dwell's mask could not
    depend on the stop's distance.

    ## Masks

    Action (c, d) is allowed when candidate c exists (its node is covered from a cell the AUV
    can reach; not a copy of an earlier candidate's cell), one of the nodes its cell covers
    still needs something (the kernel's ``is_served``), and the moves there plus the dwell's
    fewest service steps fit in the steps left. The fallback is allowed exactly when nothing
    else is, so the mask is never all false. A masked action is refused with a ``ValueError``
    saying why (``masked_action="raise"``, the default), or executed as the fallback
    (``masked_action="hover"``, flagged in ``info["masked"]``).

    ## Observation Space

    ``Box(-1, 1, (4 + 6 n_nodes + 4 C,), float32)``: the grid's ``vector`` observation at the
    decision (AUV position, fraction of the episode left, per node its relative position,
    data left, state of charge, covered now: nodes in the order of candidates 0..n_nodes-1),
    then per candidate: the moves to reach it over ``episode_steps`` (1 when there is no
    way), what one step there earns now from the nodes it covers and what the longest fixed
    dwell there earns now (expected amounts of the per-step model capped at what each node
    still holds and can store, x / (1 + x) of the amount over one node's full worth), and
    whether some dwell there is allowed.

    ## Starting State, Rewards, Episode End, Layouts

    The wrapped env's. The reward of a step is the sum of the kernel rewards of its moves and
    hovers, so an episode's return is the kernel episode's; ``info`` holds ``kernel_steps``,
    the summed ``reward_parts``, the ``stop`` and ``dwell`` indices of the decision (-1 for the
    fallback), ``masked`` and ``given_up`` (a move stopped at contact: the continuous world's
    straight legs; never on the grid). The episode ends when the kernel episode ends, possibly in the middle of a
    decision (``terminated``/``truncated`` as the kernel's, ``info["episode_metrics"]`` at
    the end). ``layout_seeds`` and ``reset(options={"layout_seed": k})`` as the wrapped
    env's; the candidates and the distances to them are built once per layout (the last 64
    kept). ``reset(seed=s)`` resets the wrapped env with seed s, the only randomness, so the
    same seed and actions give the same episode bit for bit. :attr:`kernel_actions` lists the
    episode's kernel actions.

    ## Arguments

    ``StopChoiceEnv(scenario=None, *, preset="paper", layout_seeds=None, backend="auto",
    render_mode=None, dwells=DWELLS, candidates="own+shared", shared_fraction=0.5,
    masked_action="raise", **overrides)``: the scenario, preset, overrides, layouts, backend
    and render mode of the wrapped :class:`~swiptopt.env.AuvSwiptEnv`; the choices of
    :class:`GridStopSettings`.

    ## Version History

    - v0: initial version.
    """

    def __init__(
        self,
        scenario: Scenario | None = None,
        *,
        preset: str = "paper",
        layout_seeds: Sequence[int] | None = None,
        backend: str = "auto",
        render_mode: str | None = None,
        dwells: Sequence[Dwell | int] = DWELLS,
        candidates: str = "own+shared",
        shared_fraction: float = 0.5,
        masked_action: str = "raise",
        **overrides: Any,
    ):
        from swiptopt.env import AuvSwiptEnv

        self.settings = GridStopSettings(tuple(dwells), candidates, shared_fraction, masked_action)
        self.env = AuvSwiptEnv(scenario, preset=preset, observation="vector", render_mode=render_mode,
                               backend=backend, layout_seeds=layout_seeds, **overrides)
        self._init_spaces()

    @property
    def n_candidates(self) -> int:
        return self.env.scenario.n_nodes * self.settings.candidates_per_node

    @classmethod
    def build_layout(cls, env: Any, settings: GridStopSettings) -> GridStops:
        return build_grid_stops(env.tables, env.scenario, settings)
