"""Power splitting and dwell times at hover points: a closed form and a convex program.

Model (the linear harvester of docs/design.md, 'SWIPT at the node (Section II-C)'). A node
whose link has SNR gamma (linear, before splitting) and available power P_av, served for t
seconds with split ratio alpha, receives ``t B log2(1 + alpha gamma)`` bits and harvests
``t eta (1 - alpha) P_av`` joules. The value of a service is the reward's weighting
(paper eq. 23 without the movement term)::

    Gamma bits / D_ref + (1 - Gamma) joules / E_ref.

**One node, per second** (:func:`optimal_split_ratio`). The value rate

    f(alpha) = Gamma B log2(1 + alpha gamma) / D_ref + (1 - Gamma) eta (1 - alpha) P_av / E_ref

is concave in alpha, with f'(alpha) = Gamma B gamma / (ln2 (1 + alpha gamma) D_ref)
- (1 - Gamma) eta P_av / E_ref. Setting f' = 0 gives 1 + alpha gamma = Gamma B gamma E_ref /
(ln2 (1 - Gamma) eta P_av D_ref), so

    alpha* = clip(Gamma B E_ref / (ln2 (1 - Gamma) eta P_av D_ref) - 1 / gamma, 0, 1)

Concavity makes the clipped stationary point the maximiser on [0, 1]. Limits: Gamma = 1 (or
nothing to harvest) gives 1; Gamma = 0 (or gamma = 0, nothing to decode) gives 0.

**Many hover points and nodes** (:class:`DwellSplitProblem`, :func:`optimise_dwell_and_split`).
Dwell t_k >= 0 at hover point k, split alpha_ik for each covered pair. With beta_ik =
alpha_ik t_k the bits are the perspective ``t B log2(1 + gamma beta / t)`` of a concave
function, hence jointly concave in (t, beta); the energy ``eta P_av (t - beta)`` is linear.
As in the simulator, only data still to deliver and energy still storable count, so each
pair's counted bits and joules are variables bounded above by what the link carries, and
each node's totals are capped. Maximise the weighted value under a dwell-time budget
sum_k t_k <= T and/or an AUV energy budget sum_k P_dwell,k t_k <= E_budget, optionally
with a minimum energy per node. Every constraint is convex, so the optimum is global.

DCP form of the bits: t ln(1 + gamma beta / t) = -rel_entr(t, t + gamma beta). Acoustic
SNRs reach 1e10, which would put coefficients of 1e10 next to 1 in the cone constraints; we
use the same function written with c = max(gamma, 1),

    t ln(1 + gamma beta / t) = t ln c - rel_entr(t, t / c + (gamma / c) beta),

whose coefficients ln c, 1/c and gamma/c are all moderate. The problem is built once with
``cvxpy.Parameter`` s (DPP): re-solving with new SNRs, powers, caps, weights or budgets
skips cvxpy's canonicalisation. What is structural: the coverage pattern (which pairs
exist) and which budgets are present.

Once every cap binds, more dwell adds nothing, so the optimal dwell is not unique; a cost of
:data:`DWELL_TIE_BREAK` times the best pair's value rate per second of dwell selects the
shortest optimal dwell (the reported objective leaves it out). The solver is Clarabel
(interior point, exponential cone) when installed, else SCS; on a numerical failure the
default retries Clarabel at looser tolerances, then SCS, and says so (status
``optimal_inaccurate`` and a message). Conditioning: the program runs in units of the time
budget, caps above what the whole budget could deliver are clipped to it (they cannot bind),
and the minimum-energy rows exist only when a minimum is asked for.

**The split fixed** (``split_ratio=alpha``, as the simulator does with the scenario's split):
each pair's rates per second are then constants, and what remains is a linear program over
the dwells and each node's counted amounts, solved by HiGHS (scipy) in well under a second at
1000 nodes and thousands of covered pairs. The conic program with every split free does not
scale as well: it solves hundreds of pairs in a second or two, but thousands take minutes or
fail numerically (then the status says so).

cvxpy (and scipy) are imported inside the functions that use them, so ``import planners``
stays light.
"""

from __future__ import annotations

import logging
import math
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from swiptopt import fpmath
from swiptopt.acoustics import db_to_linear
from swiptopt.coverage import covered_nodes, slant_distances_m
from swiptopt.errors import ConfigError
from swiptopt.link import auv_power, link_budget, reward_references
from swiptopt.validation import Spec, check_value

if TYPE_CHECKING:
    import cvxpy as cp

    from swiptopt.scenario import Scenario

LN2 = math.log(2.0)

#: Solvers tried in order: both handle the exponential cone. Clarabel (interior point,
#: accurate to ~1e-8) is cvxpy's default; SCS (first order, looser) is the fallback.
PREFERRED_SOLVERS = ("CLARABEL", "SCS")

#: A dwell shorter than this fraction of the longest dwell counts as zero (no split ratio).
ZERO_DWELL_FRACTION = 1e-9

#: Once every cap binds, extra dwell adds nothing and the optimal dwell is not unique; a
#: cost of this fraction of the best pair's value rate per second of dwell picks the
#: shortest optimal dwell. It moves the value by at most this fraction times the budget's
#: worth of the best pair; the reported objective is the value without it.
DWELL_TIE_BREAK = 1e-6

STATUSES = ("optimal", "optimal_inaccurate", "no_coverage", "infeasible", "unbounded", "solver_error")

#: Solvers cvxpy offers for the exponential cone (the bits' perspective form). A ``solver``
#: outside this list, or not installed, is refused with a ConfigError naming it.
EXP_CONE_SOLVERS = ("CLARABEL", "SCS", "ECOS", "MOSEK")

#: Clarabel settings tried in turn when the first attempt (cvxpy's defaults, tolerances 1e-8)
#: fails with numerical trouble ("InsufficientProgress" from about a thousand covered pairs):
#: looser tolerances, then shorter steps. A solution found this way is reported
#: ``optimal_inaccurate``.
CLARABEL_RETRIES = (
    {"tol_gap_abs": 1e-6, "tol_gap_rel": 1e-6, "tol_feas": 1e-6, "tol_ktratio": 1e-4},
    {"max_step_fraction": 0.9},
)

#: A solution whose value, recomputed from its dwells and splits through the model itself
#: (rates, caps, budgets), differs from the solver's by more than this fraction is reported
#: ``optimal_inaccurate``, with both values in the message.
VALUE_CHECK_RTOL = 1e-5


# ------------------------------------------------------------------------ validation



class _HighsImportNoise(logging.Filter):
    """Drops cvxpy's log record about failing to import its HIGHS interface (see :func:`_cvxpy`)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "importing solver HIGHS" not in record.getMessage()


def _cvxpy():  # type: ignore[no-untyped-def]
    """Import cvxpy so that OR-Tools keeps working in the same process.

    OR-Tools and highspy (a cvxpy dependency) each bundle their own build of the HiGHS
    library, and the one loaded second in a process fails: if highspy comes first,
    ``import ortools`` breaks outright. So OR-Tools' native library is loaded first (a small
    module, when OR-Tools is installed); then only cvxpy's optional HIGHS interface fails,
    which this package never uses, and :class:`_HighsImportNoise` drops cvxpy's log record
    about it.
    """
    try:
        import ortools.init.python.init  # noqa: F401  (loads libortools before highspy)
    except ImportError:
        pass
    logger = logging.getLogger("__cvxpy__")
    if not any(isinstance(f, _HighsImportNoise) for f in logger.filters):
        logger.addFilter(_HighsImportNoise())
    import cvxpy

    return cvxpy

#: What the scalar arguments of the model and the programs may hold, checked by
#: :func:`swiptopt.validation.check_value` (a finite number in the range given).
SCALARS = {
    "reward_weight": Spec(lo=0, hi=1, doc="Gamma, the weight of data against energy"),
    "bandwidth_hz": Spec(lo=0, lo_open=True, unit="Hz", doc="the band B"),
    "efficiency": Spec(lo=0, hi=1, doc="eta, the harvester's efficiency"),
    "data_ref_bits": Spec(lo=0, lo_open=True, unit="bit", doc="D_ref, the reward's data reference"),
    "energy_ref_j": Spec(lo=0, lo_open=True, unit="J", doc="E_ref, the reward's energy reference"),
    "split_ratio": Spec(lo=0, hi=1, doc="alpha, the share of the signal sent to the decoder"),
    "mission_time_s": Spec(lo=0, unit="s", doc="the time budget"),
    "energy_budget_j": Spec(lo=0, unit="J", doc="the energy budget"),
}


def _scalar(name: str, value: Any) -> float:
    """``value`` checked against :data:`SCALARS` ``[name]``, as a float; else ConfigError naming it."""
    return check_value(name, value, SCALARS[name])


def _array(name: str, value: Any, shape: tuple[int, ...] | None = None, *, hi: float = math.inf) -> np.ndarray:
    """A float array of finite values in [0, hi] (of ``shape`` if given), else ConfigError."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be an array of numbers", name) from None
    if shape is not None and a.shape != shape:
        raise ConfigError(f"{name} has shape {a.shape}, expected {shape}", name)
    if not np.all(np.isfinite(a)):
        raise ConfigError(f"{name} must be finite (no NaN or inf)", name)
    if np.any(a < 0) or np.any(a > hi):
        raise ConfigError(f"{name} must lie in [0, {hi:g}], got min {a.min():g}, max {a.max():g}", name)
    return a


def _model_scalars(
    reward_weight: float, bandwidth_hz: float, efficiency: float, data_ref_bits: float, energy_ref_j: float
) -> tuple[float, float, float, float, float]:
    return (
        _scalar("reward_weight", reward_weight),
        _scalar("bandwidth_hz", bandwidth_hz),
        _scalar("efficiency", efficiency),
        _scalar("data_ref_bits", data_ref_bits),
        _scalar("energy_ref_j", energy_ref_j),
    )


# ------------------------------------------------------------------------ closed form


def split_value_rate(
    split_ratio: ArrayLike,
    snr_linear: ArrayLike,
    available_power_w: ArrayLike,
    *,
    reward_weight: float,
    bandwidth_hz: float,
    efficiency: float,
    data_ref_bits: float = 1.0,
    energy_ref_j: float = 1.0,
) -> np.ndarray:
    """Weighted value per second of serving a node with split ``split_ratio``, 1/s (broadcast).

    Gamma B log2(1 + alpha gamma) / D_ref + (1 - Gamma) eta (1 - alpha) P_av / E_ref
    (the rate of eq. 15 and the linear harvester, weighted as the reward of eq. 23); no caps.
    """
    gw, bw, eta, d_ref, e_ref = _model_scalars(reward_weight, bandwidth_hz, efficiency, data_ref_bits, energy_ref_j)
    alpha = _array("split_ratio", split_ratio, hi=1.0)
    gamma = _array("snr_linear", snr_linear)
    p_av = _array("available_power_w", available_power_w)
    bits_per_s = bw * fpmath.log1p(alpha * gamma) / LN2
    joules_per_s = eta * (1.0 - alpha) * p_av
    return gw * bits_per_s / d_ref + (1.0 - gw) * joules_per_s / e_ref


def optimal_split_ratio(
    snr_linear: ArrayLike,
    available_power_w: ArrayLike,
    *,
    reward_weight: float,
    bandwidth_hz: float,
    efficiency: float,
    data_ref_bits: float = 1.0,
    energy_ref_j: float = 1.0,
) -> np.ndarray:
    """The split ratio alpha* in [0, 1] maximising :func:`split_value_rate`, closed form.

    alpha* = clip(Gamma B E_ref / (ln2 (1 - Gamma) eta P_av D_ref) - 1/gamma, 0, 1) (derivation
    in the module docstring). ``snr_linear`` and ``available_power_w`` broadcast
    (e.g. (n_hover, n_nodes)); the result has their broadcast shape. Edge cases: 1 where
    energy is worthless (Gamma = 1, eta = 0 or P_av = 0) and gamma > 0; 0 where data is
    worthless (Gamma = 0) or cannot be decoded (gamma = 0).
    """
    gw, bw, eta, d_ref, e_ref = _model_scalars(reward_weight, bandwidth_hz, efficiency, data_ref_bits, energy_ref_j)
    gamma, p_av = np.broadcast_arrays(_array("snr_linear", snr_linear), _array("available_power_w", available_power_w))
    numerator = gw * bw * e_ref
    denominator = LN2 * (1.0 - gw) * eta * p_av * d_ref
    with np.errstate(divide="ignore", invalid="ignore"):
        # 1 + alpha gamma at the stationary point, divided by gamma
        target = np.where(numerator == 0.0, 0.0, np.where(denominator == 0.0, np.inf, numerator / denominator))
        alpha = np.clip(target - 1.0 / gamma, 0.0, 1.0)
    return np.where(gamma > 0.0, alpha, 0.0)


# ------------------------------------------------------------------------ the program


@dataclass(frozen=True, eq=False)
class PowerSplitResult:
    """Outcome of one solve of the dwell-time and power-split program.

    The arrays and the objective are set only when :attr:`ok`; otherwise they are ``None``.
    """

    status: str
    """One of :data:`STATUSES`: ``"optimal"``, ``"optimal_inaccurate"`` (a solution to a looser
    tolerance than asked, e.g. from a fallback solver), ``"no_coverage"`` (no hover point
    covers any node: nothing to serve, every amount zero), ``"infeasible"``, ``"unbounded"`` or
    ``"solver_error"`` (no solver produced a solution; ``message`` says why)."""
    objective: float | None
    """Weighted value sum Gamma bits / D_ref + (1 - Gamma) joules / E_ref (counted amounts)."""
    dwell_s: np.ndarray | None
    """(n_hover,) dwell time at each hover point, s."""
    split_ratio: np.ndarray | None
    """(n_hover, n_nodes) alpha in [0, 1]; NaN where not covered or where the dwell is zero."""
    bits: np.ndarray | None
    """(n_hover, n_nodes) counted bits collected (within the node's data cap), 0 where not covered."""
    energy_j: np.ndarray | None
    """(n_hover, n_nodes) counted joules delivered (within the node's storage room), 0 where not covered."""
    solve_time_s: float
    """Wall-clock time of the solve (including cvxpy's compilation on a first solve), s; set for every status."""
    solver: str
    """Name of the solver that produced the result (``"HIGHS"`` for the fixed-split linear
    program; ``""`` when no solver was needed or none was available)."""
    message: str = ""
    """What went wrong, or which fallback gave the result (empty on a plain success)."""

    @property
    def ok(self) -> bool:
        """Whether a solution is available (optimal, optimal_inaccurate or no_coverage)."""
        return self.status in ("optimal", "optimal_inaccurate", "no_coverage")


def _failed(status: str, solve_time_s: float, solver: str, message: str = "") -> PowerSplitResult:
    return PowerSplitResult(status, None, None, None, None, None, solve_time_s, solver, message)


def _nothing_covered(shape: tuple[int, int]) -> PowerSplitResult:
    """The answer when no hover point covers any node: no dwell, nothing delivered."""
    nothing = np.zeros(shape)
    return PowerSplitResult(
        "no_coverage", 0.0, np.zeros(shape[0]), np.full(shape, np.nan), nothing, nothing.copy(), 0.0, "",
        "no hover point covers any node",
    )


def _checked_solver(solver: Any) -> str | None:
    """``solver`` if cvxpy has it installed and it handles the exponential cone (None: the
    default), else ConfigError naming the allowed ones."""
    if solver is None:
        return None
    cp = _cvxpy()
    usable = [name for name in EXP_CONE_SOLVERS if name in cp.installed_solvers()]
    if not isinstance(solver, str) or solver.upper() not in usable:
        raise ConfigError(
            f"solver = {solver!r} is not an installed cvxpy solver for the exponential cone; "
            f"choose one of {', '.join(usable) or '(none installed: pip install clarabel)'}",
            "solver",
        )
    return solver.upper()


def default_solver() -> str | None:
    """The first of :data:`PREFERRED_SOLVERS` that cvxpy has installed (``None`` if neither)."""
    cp = _cvxpy()
    installed = set(cp.installed_solvers())
    return next((s for s in PREFERRED_SOLVERS if s in installed), None)


def _status(cvxpy_status: str) -> str:
    cp = _cvxpy()

    if cvxpy_status == cp.OPTIMAL:
        return "optimal"
    if cvxpy_status == cp.OPTIMAL_INACCURATE:
        return "optimal_inaccurate"
    if cvxpy_status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE):
        return "infeasible"
    if cvxpy_status in (cp.UNBOUNDED, cp.UNBOUNDED_INACCURATE):
        return "unbounded"
    return "solver_error"  # user limit, numerical trouble, anything unknown


class DwellSplitProblem:
    """The joint dwell-time / power-split program for one coverage pattern, built once.

    ``coverage_mask`` (n_hover, n_nodes) bool says which hover point covers which node; it
    and the presence of each budget are structural. Everything else is a ``cvxpy.Parameter``
    set by :meth:`solve`, so repeated solves (new SNRs, powers, remaining data, budgets,
    weights) skip canonicalisation. The cvxpy problem is built on first use
    (:attr:`problem`). An instance holds one set of parameter values at a time: do not
    share it between threads.

    Arguments:
        coverage_mask: (n_hover, n_nodes) bool.
        time_budget: include sum_k t_k <= mission_time_s.
        energy_budget: include sum_k dwell_power_w[k] t_k <= energy_budget_j.
        solver: a cvxpy solver for the exponential cone (:data:`EXP_CONE_SOLVERS`, installed;
            else ConfigError); default :func:`default_solver` (Clarabel, else SCS), which on
            numerical failure is retried with :data:`CLARABEL_RETRIES`, then SCS (a solution
            so found is ``optimal_inaccurate``). A solver named here is used alone.
        solver_options: keyword arguments passed to the solver (e.g. tolerances, iteration limits).
        parametrized: compile once for fast re-solves (cvxpy's DPP; the default). False
            compiles the values as constants at every solve, which is much faster for one
            solve of a large problem (DPP's compilation grows far faster with the number of
            covered pairs than a plain one): :func:`optimise_dwell_and_split` does so.

    Conditioning: the program is solved in units of a time scale (the time budget, else the
    longest dwell the energy budget allows), so dwell, split time, information and energy
    variables are all of order one whatever the mission's length; and the minimum-energy
    rows exist only when a minimum is asked for (zero rows there, redundant with the
    variables' signs, made Clarabel fail from a few hundred pairs).
    """

    def __init__(
        self,
        coverage_mask: ArrayLike,
        *,
        time_budget: bool = True,
        energy_budget: bool = False,
        solver: str | None = None,
        solver_options: Mapping[str, Any] | None = None,
        parametrized: bool = True,
    ) -> None:
        mask = np.asarray(coverage_mask)
        if mask.ndim != 2 or mask.dtype != bool:
            raise ConfigError(
                f"coverage_mask must be a 2-D bool array (n_hover, n_nodes), got {mask.dtype} {mask.shape}",
                "coverage_mask",
            )
        if mask.shape[0] < 1 or mask.shape[1] < 1:
            raise ConfigError(
                f"coverage_mask needs at least one hover point and one node, got {mask.shape}", "coverage_mask"
            )
        if not (time_budget or energy_budget):
            raise ConfigError("give a time budget, an energy budget or both", "time_budget")
        self.coverage_mask = mask.copy()
        self.coverage_mask.setflags(write=False)
        self.time_budget = bool(time_budget)
        self.energy_budget = bool(energy_budget)
        self.solver = _checked_solver(solver)
        self.solver_options = dict(solver_options or {})
        self.parametrized = bool(parametrized)
        self._hover_of_pair, self._node_of_pair = np.nonzero(self.coverage_mask)
        self._served_nodes = np.flatnonzero(self.coverage_mask.any(axis=0))
        # built on first use, without and with the minimum-energy rows
        self._built: dict[bool, tuple[Any, dict[str, Any], dict[str, Any]]] = {}

    @property
    def n_hover(self) -> int:
        return int(self.coverage_mask.shape[0])

    @property
    def n_nodes(self) -> int:
        return int(self.coverage_mask.shape[1])

    @property
    def n_pairs(self) -> int:
        """Number of covered (hover point, node) pairs."""
        return int(self._hover_of_pair.size)

    @property
    def problem(self) -> cp.Problem:
        """The parametrised cvxpy problem without minimum-energy rows, built on first access
        (needs at least one covered pair)."""
        return self._problem(False)[0]

    def _problem(self, with_minimum: bool) -> tuple[Any, dict[str, Any], dict[str, Any]]:
        """(problem, variables, parameters), with or without the minimum-energy rows."""
        if self.n_pairs == 0:
            raise ConfigError("no hover point covers any node: there is nothing to optimise", "coverage_mask")
        if with_minimum not in self._built:
            self._built[with_minimum] = self._build(with_minimum)
        return self._built[with_minimum]

    def _build(self, with_minimum: bool) -> tuple[Any, dict[str, Any], dict[str, Any]]:
        """The program in units of the time scale T_s: dwell tau = t / T_s, split time b =
        beta / T_s, information and energy per T_s; budgets and caps are divided by T_s when
        the parameters are set."""
        cp = _cvxpy()
        import scipy.sparse as sp

        n_pairs, n_served = self.n_pairs, self._served_nodes.size
        # sums a per-pair vector into per-served-node totals
        node_row = np.searchsorted(self._served_nodes, self._node_of_pair)
        per_node = sp.csr_matrix((np.ones(n_pairs), (node_row, np.arange(n_pairs))), shape=(n_served, n_pairs))

        dwell = cp.Variable(self.n_hover, nonneg=True, name="dwell")  # t / T_s
        beta = cp.Variable(n_pairs, nonneg=True, name="split_time")  # alpha t / T_s
        info = cp.Variable(n_pairs, nonneg=True, name="info")  # counted bits ln2 / (B T_s)
        energy = cp.Variable(n_pairs, nonneg=True, name="energy")  # counted joules / (E_ref T_s)

        p = {
            "log_c": cp.Parameter(n_pairs, name="log_c"),
            "inv_c": cp.Parameter(n_pairs, nonneg=True, name="inv_c"),
            "snr_over_c": cp.Parameter(n_pairs, nonneg=True, name="snr_over_c"),
            "harvest_rate": cp.Parameter(n_pairs, nonneg=True, name="harvest_rate_per_s"),
            "info_cap": cp.Parameter(n_served, nonneg=True, name="info_cap"),
            "room": cp.Parameter(n_served, nonneg=True, name="room"),
            "w_info": cp.Parameter(nonneg=True, name="w_info"),
            "w_energy": cp.Parameter(nonneg=True, name="w_energy"),
            "tie_break": cp.Parameter(nonneg=True, name="dwell_tie_break"),
        }
        t_pair = dwell[self._hover_of_pair]
        # t ln(1 + gamma beta / t) = t ln c - rel_entr(t, t/c + (gamma/c) beta), c = max(gamma, 1)
        capacity = cp.multiply(p["log_c"], t_pair) - cp.rel_entr(
            t_pair, cp.multiply(p["inv_c"], t_pair) + cp.multiply(p["snr_over_c"], beta)
        )
        constraints = [
            beta <= t_pair,
            info <= capacity,
            energy <= cp.multiply(p["harvest_rate"], t_pair - beta),
            per_node @ info <= p["info_cap"],
            per_node @ energy <= p["room"],
        ]
        if with_minimum:
            p["min_energy"] = cp.Parameter(n_served, nonneg=True, name="min_energy")
            constraints.append(per_node @ energy >= p["min_energy"])
        if self.time_budget:
            p["time_budget"] = cp.Parameter(nonneg=True, name="mission_time")
            constraints.append(cp.sum(dwell) <= p["time_budget"])
        if self.energy_budget:
            p["dwell_power"] = cp.Parameter(self.n_hover, nonneg=True, name="dwell_power_w")
            p["energy_budget"] = cp.Parameter(nonneg=True, name="energy_budget")
            constraints.append(p["dwell_power"] @ dwell <= p["energy_budget"])
        value = p["w_info"] * cp.sum(info) + p["w_energy"] * cp.sum(energy)
        objective = cp.Maximize(value - p["tie_break"] * cp.sum(dwell))
        problem = cp.Problem(objective, constraints)
        return problem, {"dwell": dwell, "beta": beta, "info": info, "energy": energy, "value": value}, p

    def solve(
        self,
        *,
        snr_linear: ArrayLike,
        available_power_w: ArrayLike,
        data_bits: ArrayLike,
        storage_room_j: ArrayLike,
        reward_weight: float,
        bandwidth_hz: float,
        efficiency: float,
        mission_time_s: float | None = None,
        energy_budget_j: float | None = None,
        dwell_power_w: float | ArrayLike | None = None,
        min_energy_j: ArrayLike | None = None,
        data_ref_bits: float = 1.0,
        energy_ref_j: float = 1.0,
        split_ratio: float | None = None,
    ) -> PowerSplitResult:
        """Set the parameters and solve; see :func:`optimise_dwell_and_split` for the arguments.

        ``available_power_w`` must be 0 outside the coverage mask the problem was built for,
        and ``snr_linear`` > 0 inside it (values outside are ignored).
        """
        shape = self.coverage_mask.shape
        gamma, p_av, data, room, min_energy = self._checked_amounts(
            snr_linear, available_power_w, data_bits, storage_room_j, min_energy_j
        )
        gw, bw, eta, d_ref, e_ref = _model_scalars(reward_weight, bandwidth_hz, efficiency, data_ref_bits, energy_ref_j)
        budgets = self._budgets(mission_time_s, energy_budget_j, dwell_power_w)

        unserved = np.ones(shape[1], dtype=bool)
        unserved[self._served_nodes] = False
        if np.any(min_energy[unserved] > 0):
            # no cone constraint needed to see that an uncovered node receives nothing
            return _failed("infeasible", 0.0, "", "a node no hover point covers has a minimum energy")
        if self.n_pairs == 0:
            return _nothing_covered(shape)
        if split_ratio is not None:
            alpha = _scalar("split_ratio", split_ratio)
            return self._solve_fixed_split(
                alpha, gamma, p_av, data, room, min_energy, budgets, gw, bw, eta, d_ref, e_ref
            )

        solver = self.solver or default_solver()
        if solver is None:
            return _failed("solver_error", 0.0, "", "no installed cvxpy solver handles the exponential cone")
        with_minimum = bool(np.any(min_energy > 0))
        problem, v, pr = self._problem(with_minimum)
        scale = _time_scale(budgets)
        g = gamma[self._hover_of_pair, self._node_of_pair]
        self._set_parameters(pr, g, p_av, data, room, min_energy, budgets, scale, gw, bw, eta, d_ref, e_ref)

        attempts = self._attempts(solver)
        start = time.perf_counter()
        status, note, solver = self._run_attempts(problem, attempts, solver)
        elapsed = time.perf_counter() - start
        if status not in ("optimal", "optimal_inaccurate"):
            return _failed(status, elapsed, solver, note)
        return self._result(
            status, float(v["value"].value) * scale, v, scale, bw, e_ref, elapsed, solver, note, (pr, g, budgets, scale)
        )

    def _checked_amounts(
        self, snr_linear: ArrayLike, available_power_w: ArrayLike, data_bits: ArrayLike, storage_room_j: ArrayLike,
        min_energy_j: ArrayLike | None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The per-pair and per-node arrays of :meth:`solve`, checked against the coverage mask."""
        shape = self.coverage_mask.shape
        gamma = _array("snr_linear", snr_linear, shape)
        p_av = _array("available_power_w", available_power_w, shape)
        if np.any(p_av[~self.coverage_mask] > 0):
            raise ConfigError(
                "available_power_w is positive at a pair outside the coverage mask the problem was built for",
                "available_power_w",
            )
        if np.any(gamma[self.coverage_mask] <= 0):
            raise ConfigError("snr_linear must be > 0 at every covered pair", "snr_linear")
        data = _array("data_bits", data_bits, shape[1:])
        room = _array("storage_room_j", storage_room_j, shape[1:])
        min_energy = np.zeros(shape[1]) if min_energy_j is None else _array("min_energy_j", min_energy_j, shape[1:])
        return gamma, p_av, data, room, min_energy

    def _set_parameters(
        self, pr: dict[str, Any], g: np.ndarray, p_av: np.ndarray, data: np.ndarray, room: np.ndarray,
        min_energy: np.ndarray, budgets: dict[str, Any], scale: float, gw: float, bw: float, eta: float,
        d_ref: float, e_ref: float,
    ) -> None:
        """The values of the conic program's parameters ``pr`` for this solve (``g``: each
        pair's SNR), in units of the time scale ``scale``."""
        shape = self.coverage_mask.shape
        k_of, i_of = self._hover_of_pair, self._node_of_pair
        c = np.maximum(g, 1.0)
        served = self._served_nodes
        pr["log_c"].value = fpmath.log(c)
        pr["inv_c"].value = 1.0 / c
        pr["snr_over_c"].value = g / c
        pr["harvest_rate"].value = eta * p_av[k_of, i_of] / e_ref
        # caps beyond what the whole budget could deliver never bind: clip them to that, so
        # that no variable's range dwarfs what it can reach (exact, and better conditioned)
        longest = _longest_dwell_s(budgets)
        reach_info = np.zeros(shape[1])
        np.maximum.at(reach_info, i_of, fpmath.log1p(g) * longest)
        reach_room = np.zeros(shape[1])
        np.maximum.at(reach_room, i_of, eta * p_av[k_of, i_of] / e_ref * longest)
        pr["info_cap"].value = np.minimum(data * LN2 / bw, reach_info)[served] / scale
        pr["room"].value = np.minimum(room / e_ref, reach_room)[served] / scale
        if "min_energy" in pr:  # the problem was built with the minimum-energy rows
            pr["min_energy"].value = min_energy[served] / e_ref / scale
        pr["w_info"].value = gw * bw / (LN2 * d_ref)
        pr["w_energy"].value = 1.0 - gw
        best_rate = float(
            np.max(pr["w_info"].value * fpmath.log1p(g) + pr["w_energy"].value * pr["harvest_rate"].value)
        )
        pr["tie_break"].value = DWELL_TIE_BREAK * best_rate
        for name, value in budgets.items():
            pr[name].value = value / scale if name in ("time_budget", "energy_budget") else value

    def _attempts(self, solver: str) -> list[tuple[str, Mapping[str, Any], str]]:
        """(solver, options, fallback) in the order tried: ``solver`` with the problem's
        options, then, by default, the numerical-failure retries (``fallback`` says which)."""
        attempts = [(solver, self.solver_options, "")]
        if self.solver is None:  # the default: retry numerical failures, looser, then with SCS
            if solver == "CLARABEL":
                attempts += [("CLARABEL", options, f"Clarabel with {options}") for options in CLARABEL_RETRIES]
            if solver != "SCS" and "SCS" in _cvxpy().installed_solvers():
                attempts.append(("SCS", {}, "SCS after Clarabel failed"))
        return attempts

    def _run_attempts(
        self, problem: Any, attempts: list[tuple[str, Mapping[str, Any], str]], solver: str
    ) -> tuple[str, str, str]:
        """(status, note, solver) of the first attempt that counts: the first that does not
        fail, or a fallback that converged; else ``solver_error`` with every attempt's note."""
        status, note = "solver_error", ""
        notes = []
        for name, options, fallback in attempts:
            status, note = _run(problem, name, {**options, "ignore_dpp": not self.parametrized})
            if not fallback and status != "solver_error":
                solver = name
                break
            if fallback and status == "optimal":  # a fallback counts only when it converged
                status, note, solver = "optimal_inaccurate", f"solved by {fallback}", name
                break
            notes.append(note or f"{name}: {status}")
            status = "solver_error"
            if OPTIONS_REFUSED in note:  # the user's options are wrong: fallbacks would drop them
                break
        if status == "solver_error":
            note = "; ".join(notes)
        return status, note, solver

    def _solve_fixed_split(
        self, alpha: float, gamma: np.ndarray, p_av: np.ndarray, data: np.ndarray, room: np.ndarray,
        min_energy: np.ndarray, budgets: dict[str, Any], gw: float, bw: float, eta: float, d_ref: float,
        e_ref: float,
    ) -> PowerSplitResult:
        """The program with every split ratio fixed at ``alpha``: a linear program (HiGHS).

        Each pair then carries fixed rates per second of dwell, ln(1 + alpha gamma) nats/Hz
        and eta (1 - alpha) P_av / E_ref, so what remains is which hover points to dwell at
        and how long: variables the dwells and each served node's counted information and
        energy (bounded by its caps, the energy from below by its minimum), rows the two
        per-node links between them and the budgets. In units of the time scale, as the
        conic program. A node's counted amounts are shared among its pairs in proportion
        to what each pair delivers.
        """
        from scipy import sparse
        from scipy.optimize import linprog

        k_of, i_of = self._hover_of_pair, self._node_of_pair
        served = self._served_nodes
        node_row = np.searchsorted(served, i_of)
        n_hover, n_served = self.n_hover, served.size
        scale = _time_scale(budgets)
        info_rate = fpmath.log1p(alpha * gamma[k_of, i_of])
        energy_rate = eta * (1.0 - alpha) * p_av[k_of, i_of] / e_ref
        w_info, w_energy = gw * bw / (LN2 * d_ref), 1.0 - gw
        tie = DWELL_TIE_BREAK * float(np.max(w_info * info_rate + w_energy * energy_rate))

        # columns: dwell (K), information (S), energy (S); rows: information and energy links
        info_col, energy_col = n_hover + np.arange(n_served), n_hover + n_served + np.arange(n_served)
        rows = np.concatenate([node_row, n_served + node_row, np.arange(n_served), n_served + np.arange(n_served)])
        cols = np.concatenate([k_of, k_of, info_col, energy_col])
        vals = np.concatenate([-info_rate, -energy_rate, np.ones(n_served), np.ones(n_served)])
        links = sparse.csr_array((vals, (rows, cols)), shape=(2 * n_served, n_hover + 2 * n_served))
        budget_rows, budget_caps = [], []
        if "time_budget" in budgets:
            budget_rows.append(np.concatenate([np.ones(n_hover), np.zeros(2 * n_served)]))
            budget_caps.append(budgets["time_budget"] / scale)
        if "energy_budget" in budgets:
            budget_rows.append(np.concatenate([budgets["dwell_power"], np.zeros(2 * n_served)]))
            budget_caps.append(budgets["energy_budget"] / scale)
        a_ub = sparse.vstack([links, sparse.csr_array(np.array(budget_rows))]).tocsr()
        b_ub = np.concatenate([np.zeros(2 * n_served), budget_caps])
        cost = np.concatenate([np.full(n_hover, tie), np.full(n_served, -w_info), np.full(n_served, -w_energy)])
        lower = np.concatenate([np.zeros(n_hover + n_served), min_energy[served] / e_ref / scale])
        upper = np.concatenate(
            [np.full(n_hover, np.inf), data[served] * LN2 / bw / scale, room[served] / e_ref / scale]
        )
        if np.any(lower > upper):
            return _failed("infeasible", 0.0, "HIGHS", "a node's minimum energy exceeds its storage room")

        start = time.perf_counter()
        lp = linprog(cost, A_ub=a_ub, b_ub=b_ub, bounds=np.column_stack([lower, upper]), method="highs")
        elapsed = time.perf_counter() - start
        if lp.status != 0:
            status = {2: "infeasible", 3: "unbounded"}.get(lp.status, "solver_error")
            return _failed(status, elapsed, "HIGHS", f"HiGHS: {lp.message}")

        x = np.maximum(lp.x, 0.0)
        dwell = x[:n_hover] * scale
        counted_info, counted_energy = x[info_col], x[energy_col]
        raw_info, raw_energy = info_rate * x[k_of], energy_rate * x[k_of]
        node_info = np.bincount(node_row, weights=raw_info, minlength=n_served)
        node_energy = np.bincount(node_row, weights=raw_energy, minlength=n_served)
        with np.errstate(invalid="ignore", divide="ignore"):
            info_share = np.where(node_info[node_row] > 0, raw_info / node_info[node_row], 0.0)
            energy_share = np.where(node_energy[node_row] > 0, raw_energy / node_energy[node_row], 0.0)
        shape = self.coverage_mask.shape
        bits, energy, split = np.zeros(shape), np.zeros(shape), np.full(shape, np.nan)
        bits[k_of, i_of] = info_share * counted_info[node_row] * scale * bw / LN2
        energy[k_of, i_of] = energy_share * counted_energy[node_row] * scale * e_ref
        used = dwell[k_of] > ZERO_DWELL_FRACTION * max(float(dwell.max()), np.finfo(float).tiny)
        split[k_of[used], i_of[used]] = alpha
        objective = float(w_info * counted_info.sum() + w_energy * counted_energy.sum()) * scale
        return PowerSplitResult("optimal", objective, dwell, split, bits, energy, elapsed, "HIGHS")

    def _budgets(self, mission_time_s: Any, energy_budget_j: Any, dwell_power_w: Any) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.time_budget:
            if mission_time_s is None:
                raise ConfigError("this problem was built with a time budget: give mission_time_s", "mission_time_s")
            out["time_budget"] = _scalar("mission_time_s", mission_time_s)
        elif mission_time_s is not None:
            raise ConfigError(
                "this problem was built without a time budget: rebuild it to use mission_time_s", "mission_time_s"
            )
        if self.energy_budget:
            if energy_budget_j is None:
                raise ConfigError(
                    "this problem was built with an energy budget: give energy_budget_j", "energy_budget_j"
                )
            out["energy_budget"] = _scalar("energy_budget_j", energy_budget_j)
            if dwell_power_w is None:
                raise ConfigError("an energy budget needs dwell_power_w (AUV power while serving, W)", "dwell_power_w")
            power = _array("dwell_power_w", dwell_power_w)
            if power.ndim == 0:
                power = np.full(self.n_hover, float(power))
            elif power.shape != (self.n_hover,):
                raise ConfigError(
                    f"dwell_power_w has shape {power.shape}, expected a scalar or ({self.n_hover},)", "dwell_power_w"
                )
            if np.any(power <= 0):
                raise ConfigError("dwell_power_w must be > 0: a free dwell leaves the dwell unbounded", "dwell_power_w")
            out["dwell_power"] = power
        elif energy_budget_j is not None:
            raise ConfigError(
                "this problem was built without an energy budget: rebuild it to use energy_budget_j", "energy_budget_j"
            )
        return out

    def _result(
        self, status: str, objective: float, v: dict[str, Any], scale: float, bw: float, e_ref: float,
        elapsed: float, solver: str, note: str, check: tuple[Any, ...],
    ) -> PowerSplitResult:
        k_of, i_of = self._hover_of_pair, self._node_of_pair
        shape = self.coverage_mask.shape
        dwell = np.maximum(np.asarray(v["dwell"].value, dtype=float), 0.0) * scale
        t_pair = dwell[k_of]
        beta = np.clip(np.asarray(v["beta"].value, dtype=float) * scale, 0.0, t_pair)
        positive = t_pair > ZERO_DWELL_FRACTION * max(float(dwell.max()), np.finfo(float).tiny)
        split = np.full(shape, np.nan)
        split[k_of[positive], i_of[positive]] = np.clip(beta[positive] / t_pair[positive], 0.0, 1.0)
        bits = np.zeros(shape)
        bits[k_of, i_of] = np.maximum(np.asarray(v["info"].value, dtype=float), 0.0) * scale * bw / LN2
        energy = np.zeros(shape)
        energy[k_of, i_of] = np.maximum(np.asarray(v["energy"].value, dtype=float), 0.0) * scale * e_ref
        achieved = self._achievable_value(dwell, split, *check)
        if abs(achieved - objective) > VALUE_CHECK_RTOL * max(1.0, abs(objective)):
            status = "optimal_inaccurate"
            note = (f"{note + '; ' if note else ''}the solver's value {objective:.9g}, "
                    f"its dwells and splits give {achieved:.9g}")
        return PowerSplitResult(status, objective, dwell, split, bits, energy, elapsed, solver, note)

    def _achievable_value(self, dwell: np.ndarray, split: np.ndarray, pr: dict[str, Any], g: np.ndarray,
                          budgets: Mapping[str, Any], scale: float) -> float:
        """The value that ``dwell`` (K,) s and ``split`` (K, N) earn in the model itself (the
        parameters ``pr`` as set for this solve, SNRs ``g`` per pair): rates per pair, caps
        per node, the dwells scaled down into the budgets should they overshoot."""
        k_of = self._hover_of_pair
        node_row = np.searchsorted(self._served_nodes, self._node_of_pair)
        fits = 1.0
        if "time_budget" in budgets:
            fits = min(fits, float(budgets["time_budget"]) / max(float(dwell.sum()), 1e-300))
        if "energy_budget" in budgets:
            spent = float(fpmath.dot(budgets["dwell_power"], dwell))
            fits = min(fits, float(budgets["energy_budget"]) / max(spent, 1e-300))
        t = dwell[k_of] * min(1.0, fits) / scale  # in the program's unit of time
        alpha = np.nan_to_num(split[k_of, self._node_of_pair])
        n = self._served_nodes.size
        info = np.bincount(node_row, weights=t * fpmath.log1p(alpha * g), minlength=n)
        joules = np.bincount(node_row, weights=t * (1.0 - alpha) * pr["harvest_rate"].value, minlength=n)
        info = np.minimum(info, pr["info_cap"].value)
        joules = np.minimum(joules, pr["room"].value)
        return float(pr["w_info"].value * info.sum() + pr["w_energy"].value * joules.sum()) * scale


def _longest_dwell_s(budgets: Mapping[str, Any]) -> float:
    """The most dwell any one hover point can get under the budgets, s."""
    longest = math.inf
    if "time_budget" in budgets:
        longest = float(budgets["time_budget"])
    if "energy_budget" in budgets:
        longest = min(longest, float(budgets["energy_budget"]) / float(np.min(budgets["dwell_power"])))
    return longest


def _time_scale(budgets: Mapping[str, Any]) -> float:
    """The program's unit of time, s: the time budget, else the longest dwell the energy
    budget pays for (1 s if that is zero)."""
    if "time_budget" in budgets:
        scale = float(budgets["time_budget"])
    else:
        scale = float(budgets["energy_budget"]) / float(np.min(budgets["dwell_power"]))
    return scale if scale > 0 else 1.0


#: The note of a solve whose solver refused ``solver_options``.
OPTIONS_REFUSED = "solver_options refused"


def _run(problem: Any, solver: str, options: Mapping[str, Any]) -> tuple[str, str]:
    """Solve ``problem`` with ``solver``; (status, message)."""
    cp = _cvxpy()
    try:
        with warnings.catch_warnings():
            # an inaccurate solution is reported by the status "optimal_inaccurate"
            warnings.filterwarnings("ignore", message="Solution may be inaccurate", category=UserWarning)
            problem.solve(solver=solver, **options)
    except cp.error.SolverError as exc:
        return "solver_error", f"{solver}: {str(exc).splitlines()[0]}"
    except TypeError as exc:  # the solver refuses an option: no other attempt would use them
        return "solver_error", f"{solver}: {OPTIONS_REFUSED}: {(str(exc).splitlines() or [''])[0][:200]}"
    except (ValueError, ArithmeticError) as exc:
        # a solver that cannot set up numbers this large (SCS's allocation ValueError) has
        # failed to solve: a status, like SolverError
        return "solver_error", f"{solver}: {type(exc).__name__}: {(str(exc).splitlines() or [''])[0][:200]}"
    status = _status(problem.status)
    return status, ("" if status == "optimal" else f"{solver}: {problem.status}")


def optimise_dwell_and_split(
    snr_linear: ArrayLike,
    available_power_w: ArrayLike,
    data_bits: ArrayLike,
    storage_room_j: ArrayLike,
    *,
    reward_weight: float,
    bandwidth_hz: float,
    efficiency: float,
    mission_time_s: float | None = None,
    energy_budget_j: float | None = None,
    dwell_power_w: float | ArrayLike | None = None,
    min_energy_j: ArrayLike | None = None,
    data_ref_bits: float = 1.0,
    energy_ref_j: float = 1.0,
    solver: str | None = None,
    solver_options: Mapping[str, Any] | None = None,
    split_ratio: float | None = None,
) -> PowerSplitResult:
    """Optimal dwell times and split ratios for K hover points and N nodes (build and solve once).

    Arguments:
        snr_linear: (K, N) link SNR before splitting, linear; > 0 where covered.
        available_power_w: (K, N) available power at the node, W; 0 means not covered.
        data_bits: (N,) data each node still has to deliver, bit.
        storage_room_j: (N,) energy each node can still store, J.
        reward_weight: Gamma in [0, 1].
        bandwidth_hz: B > 0.
        efficiency: harvester efficiency eta in [0, 1] (linear model).
        mission_time_s: total dwell time allowed, s (a budget: sum_k t_k <= it).
        energy_budget_j: AUV energy allowed for dwelling, J (sum_k dwell_power_w t_k <= it).
        dwell_power_w: AUV power while hovering and serving, W, scalar or (K,); needed with
            ``energy_budget_j``.
        min_energy_j: (N,) minimum energy each node must receive, J (default none).
        data_ref_bits, energy_ref_j: the reward's references D_ref and E_ref.
        solver: a cvxpy solver for the exponential cone (default Clarabel, with fallbacks;
            see :class:`DwellSplitProblem`); an unknown or unsuitable name is a ConfigError.
        solver_options: keyword arguments passed to the solver.
        split_ratio: fix every split ratio at this alpha in [0, 1] (as the simulator does,
            with the scenario's ``split_ratio``): only the dwells remain, a linear program
            solved by HiGHS at any size (``solver`` does not apply). ``None``: optimise the
            splits too (the conic program).

    At least one budget is required. Bad input raises :class:`~swiptopt.errors.ConfigError`
    naming the argument; an infeasible or failed solve returns a result with that status.
    """
    gamma = _array("snr_linear", snr_linear)
    if gamma.ndim != 2:
        raise ConfigError(f"snr_linear must be (n_hover, n_nodes), got shape {gamma.shape}", "snr_linear")
    p_av = _array("available_power_w", available_power_w, gamma.shape)
    if mission_time_s is None and energy_budget_j is None:
        raise ConfigError("give a budget: mission_time_s and/or energy_budget_j", "mission_time_s")
    problem = DwellSplitProblem(
        p_av > 0, time_budget=mission_time_s is not None, energy_budget=energy_budget_j is not None,
        solver=solver,
        solver_options=solver_options,
        parametrized=False,  # one solve: compiling for re-solves would only cost time
    )
    return problem.solve(
        snr_linear=gamma,
        available_power_w=p_av,
        data_bits=data_bits,
        storage_room_j=storage_room_j,
        reward_weight=reward_weight,
        bandwidth_hz=bandwidth_hz,
        efficiency=efficiency,
        mission_time_s=mission_time_s,
        energy_budget_j=energy_budget_j,
        dwell_power_w=dwell_power_w,
        min_energy_j=min_energy_j,
        data_ref_bits=data_ref_bits,
        energy_ref_j=energy_ref_j,
        split_ratio=split_ratio,
    )


# ------------------------------------------------------------------------ from a scenario


@dataclass(frozen=True, eq=False)
class DwellSplitInputs:
    """The program's inputs for a scenario and its hover points (:func:`from_scenario` for
    grid cells, :func:`stop_inputs` for links already computed, e.g. at points of the
    continuous world).

    ``optimise_dwell_and_split(**inputs.as_kwargs())`` solves it;
    ``DwellSplitProblem(inputs.coverage_mask, ...)`` builds it for repeated solves;
    :func:`dwell_steps` solves it and rounds the dwells to whole steps.
    """

    hover_cells: np.ndarray | None
    """(K,) flat cell indices of the hover points (``None``: points that are not cells)."""
    snr_linear: np.ndarray
    """(K, N) mean link SNR, linear; 0 where not covered."""
    available_power_w: np.ndarray
    """(K, N) available power, W; 0 where not covered."""
    data_bits: np.ndarray
    """(N,) data still to deliver, bit."""
    storage_room_j: np.ndarray
    """(N,) storable energy, J."""
    mission_time_s: float
    energy_budget_j: float | None
    dwell_power_w: float
    """AUV power while hovering and serving: hotel + station keeping + projector, W."""
    reward_weight: float
    bandwidth_hz: float
    efficiency: float
    data_ref_bits: float
    energy_ref_j: float

    @property
    def coverage_mask(self) -> np.ndarray:
        """(K, N) bool, the covered pairs."""
        return self.available_power_w > 0

    def as_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :func:`optimise_dwell_and_split` (without ``solver``)."""
        return {
            "snr_linear": self.snr_linear,
            "available_power_w": self.available_power_w,
            "data_bits": self.data_bits,
            "storage_room_j": self.storage_room_j,
            "reward_weight": self.reward_weight,
            "bandwidth_hz": self.bandwidth_hz,
            "efficiency": self.efficiency,
            "mission_time_s": self.mission_time_s,
            "energy_budget_j": self.energy_budget_j,
            "dwell_power_w": self.dwell_power_w if self.energy_budget_j is not None else None,
            "data_ref_bits": self.data_ref_bits,
            "energy_ref_j": self.energy_ref_j,
        }


def from_scenario(
    scenario: Scenario,
    hover_cells: Sequence[int] | ArrayLike,
    *,
    data_bits: ArrayLike | None = None,
    stored_energy_j: ArrayLike | None = None,
    mission_time_s: float | None = None,
    energy_budget_j: float | None = None,
) -> DwellSplitInputs:
    """The program's inputs for hovering at ``hover_cells`` in ``scenario`` (linear harvester).

    SNR and available power of each pair come from the scenario's mean (unfaded) link
    (:func:`swiptopt.link.link_budget`) at the slant distance, for the pairs that
    :func:`swiptopt.coverage.covered_nodes` covers; fading, link failures and the energy
    gate are not modelled. Data and storage room come from the layout, or from
    ``data_bits`` (N,) still to deliver and ``stored_energy_j`` (N,) already stored when
    re-planning mid-episode. The references are :func:`swiptopt.link.reward_references`;
    the time budget defaults to the whole episode, ``episode_steps * step_duration_s``
    (travel between hover points is not subtracted: pass ``mission_time_s`` to do so). Dwell
    times come out continuous; the simulator serves in whole steps of ``step_duration_s``.
    """
    if scenario.harvester != "linear":
        raise ConfigError(
            f"the convex program models the linear harvester, the scenario uses {scenario.harvester!r}", "harvester"
        )
    cells = np.asarray(hover_cells)
    if cells.ndim != 1 or cells.size == 0 or not np.issubdtype(cells.dtype, np.integer):
        raise ConfigError(
            f"hover_cells must be a non-empty list of flat cell indices, got {hover_cells!r}", "hover_cells"
        )
    if np.any((cells < 0) | (cells >= scenario.n_cells)):
        raise ConfigError(f"hover_cells must lie in 0..{scenario.n_cells - 1}", "hover_cells")
    if np.any(scenario.blocked_cells[cells]):
        raise ConfigError("a hover cell lies inside an obstacle or below the seabed", "hover_cells")

    layout = scenario.layout
    n = scenario.n_nodes
    auv_m = scenario.cell_centers_m[cells]
    covered = covered_nodes(scenario, auv_m)
    budget = link_budget(scenario, slant_distances_m(auv_m, layout.positions_m))
    snr = np.where(covered, db_to_linear(budget.snr_db), 0.0)
    p_av = np.where(covered, budget.available_power_w, 0.0)
    data = None if data_bits is None else _array("data_bits", data_bits, (n,))
    stored = None if stored_energy_j is None else _array("stored_energy_j", stored_energy_j, (n,))
    mission = scenario.episode_steps * scenario.step_duration_s if mission_time_s is None else mission_time_s
    return stop_inputs(scenario, snr, p_av, mission_time_s=mission, data_bits=data, stored_energy_j=stored,
                       energy_budget_j=energy_budget_j, hover_cells=cells.astype(np.int64))


def stop_inputs(
    scenario: Scenario,
    snr_linear: np.ndarray,
    available_power_w: np.ndarray,
    *,
    mission_time_s: float,
    data_bits: np.ndarray | None = None,
    stored_energy_j: np.ndarray | None = None,
    energy_budget_j: float | None = None,
    hover_cells: np.ndarray | None = None,
) -> DwellSplitInputs:
    """The program's inputs for hover points whose links are given: ``snr_linear`` and
    ``available_power_w`` (K, N), zero where a node is not covered; the layout's data and
    storage room (or ``data_bits`` still to deliver and ``stored_energy_j`` already stored);
    the scenario's reward weight, bandwidth, harvester efficiency, references
    (:func:`swiptopt.link.reward_references`) and AUV power while serving."""
    layout = scenario.layout
    data = layout.data_bits.copy() if data_bits is None else np.asarray(data_bits, dtype=float)
    stored = layout.initial_energy_j if stored_energy_j is None else np.asarray(stored_energy_j, dtype=float)
    refs = reward_references(scenario)
    power = auv_power(scenario)
    return DwellSplitInputs(
        hover_cells=hover_cells,
        snr_linear=snr_linear,
        available_power_w=available_power_w,
        data_bits=data,
        storage_room_j=np.maximum(layout.capacity_j - stored, 0.0),
        mission_time_s=_scalar("mission_time_s", mission_time_s),
        energy_budget_j=None if energy_budget_j is None else _scalar("energy_budget_j", energy_budget_j),
        dwell_power_w=power.hotel_w + scenario.station_keeping_power_w + power.projector_w,
        reward_weight=scenario.reward_weight,
        bandwidth_hz=scenario.bandwidth_hz,
        efficiency=scenario.harvest_efficiency,
        data_ref_bits=refs.data_ref_bits,
        energy_ref_j=refs.energy_ref_j,
    )


def whole_steps(wanted: ArrayLike, total: int) -> np.ndarray:
    """Whole service steps per stop, at least one each, summing to ``total`` (largest
    remainder): ``wanted`` (K,) the shares in steps, continuous."""
    n = len(wanted)
    if total <= n:
        return np.ones(n, dtype=np.int64)
    share = np.maximum(np.asarray(wanted, dtype=float), 0.0)
    share = share / share.sum() * (total - n) if share.sum() > 0 else np.full(n, (total - n) / n)
    steps = np.floor(share).astype(np.int64)
    rest = total - n - int(steps.sum())
    steps[np.argsort(-(share - steps), kind="stable")[:rest]] += 1
    return steps + 1


def dwell_steps(
    inputs: DwellSplitInputs, step_s: float, service_steps: int, total_steps: int, *, split_ratio: float | None,
) -> tuple[np.ndarray, PowerSplitResult]:
    """Whole service steps per hover point (:func:`whole_steps`, summing to ``total_steps``)
    from the program's dwells in steps of ``step_s``, at the simulator's fixed
    ``split_ratio`` (``None``: the program chooses the splits too); ``service_steps`` shared
    evenly when the solve fails. Returns the steps and the program's result (its status says
    whether the solve succeeded)."""
    result = optimise_dwell_and_split(**inputs.as_kwargs(), split_ratio=split_ratio)
    k = len(inputs.snr_linear)
    if result.dwell_s is not None:
        wanted = np.asarray(result.dwell_s) / step_s
    else:
        wanted = np.full(k, service_steps / k)
    return whole_steps(wanted, total_steps), result
