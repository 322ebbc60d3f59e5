"""Figures (matplotlib, PNG and PDF sized for one column of a two-column paper) with the
data behind each written beside it as CSV.

Files are named after the experiment (a name :class:`Experiment` restricts to letters,
digits, ``-``, ``_`` and ``.``) and written only inside the output directory given.
"""

from __future__ import annotations

import csv
import json
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from swiptopt.benchmark.experiment import Experiment
from swiptopt.benchmark.store import ResultStore
from swiptopt.errors import ConfigError

#: One column of a two-column paper, inches.
COLUMN_WIDTH_IN = 3.5

_UNITS = {
    "return": ("return", 1.0),
    "data_bits": ("data collected (kbit)", 1e-3),
    "energy_delivered_j": ("energy delivered (mJ)", 1e3),
    "energy_efficiency_bit_per_j": ("energy efficiency, all AUV energy (bit/J)", 1.0),
    "mobility_efficiency_bit_per_j": ("energy efficiency, AUV motion (bit/J)", 1.0),
    "steps_to_data_target": ("steps to 50 % of the data", 1.0),
    "steps_to_energy_target": ("steps to 50 % of the energy", 1.0),
    "nodes_served": ("nodes served", 1.0),
}
_X_LABELS = {"n_nodes": "number of nodes", "split_ratio": "power-splitting ratio alpha"}


def _figure(height_in: float = 2.5):  # type: ignore[no-untyped-def]
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(COLUMN_WIDTH_IN, height_in), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def _output_path(outdir: Path, filename: str) -> Path:
    """``outdir / filename``, refusing any name that would land elsewhere."""
    path = outdir / filename
    if Path(filename).name != filename or filename in (".", "..") or path.resolve().parent != outdir.resolve():
        raise ConfigError(f"{filename!r} is not a plain file name inside {str(outdir)!r}", "name")
    return path


def _save(fig, outdir: Path, stem: str) -> list[Path]:  # type: ignore[no-untyped-def]
    import matplotlib

    with matplotlib.rc_context({"font.size": 8}):
        fig.tight_layout()
    paths = [_output_path(outdir, f"{stem}.png"), _output_path(outdir, f"{stem}.pdf")]
    outdir.mkdir(parents=True, exist_ok=True)
    fig.savefig(paths[0], dpi=200)
    fig.savefig(paths[1])
    return paths


def _write_csv(outdir: Path, filename: str, header: list[str], rows: list[list[Any]]) -> Path:
    path = _output_path(outdir, filename)
    outdir.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(rows)
    return path


@dataclass(frozen=True)
class FigureResult:
    """What drawing one experiment's figure did: the files written, or why none were."""

    experiment: str
    paths: list[Path]
    skipped: str = ""
    """Why no figure was drawn (empty when it was)."""


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def experiment_figure(experiment: Experiment, store: ResultStore, outdir: str | Path) -> FigureResult:
    """Metric against the sweep variable, one line per algorithm (and per value of any other
    swept key), 95 % CI error bars; files named after the experiment inside ``outdir``.

    A numeric sweep variable is drawn on a numeric axis, any other (names, choices) as
    categories in the sweep's order. Nothing is drawn, and ``skipped`` says why, when the
    store holds none of the experiment's results.
    """
    import matplotlib

    from swiptopt.benchmark import tables

    outdir = Path(outdir)
    metric = experiment.figure.get("metric", "return")
    x_key = experiment.figure.get("x") or next(iter(experiment.sweep), None)
    if x_key is None:  # Experiment refuses a figure without a sweep; a plain result says so too
        return FigureResult(experiment.name, [], "the experiment has no sweep to plot against")
    rows, _ = tables.aggregate(experiment, store)
    if not rows:
        return FigureResult(experiment.name, [], "the store holds none of its results")
    x_values = experiment.sweep[x_key]
    numeric = all(_is_number(v) for v in x_values)
    others = [k for k in experiment.sweep if k != x_key]
    ylabel, scale = _UNITS.get(metric, (metric, 1.0))
    data_rows = []
    with matplotlib.rc_context({"font.size": 8}):
        fig = _figure()
        ax = fig.add_subplot(1, 1, 1)
        for algorithm in experiment.algorithms:
            mine = [r for r in rows if r.algorithm == algorithm]
            series: dict[str, list[tables.Row]] = {}
            for r in mine:
                series.setdefault(json.dumps([r.point[k] for k in others]), []).append(r)
            for group in series.values():
                group.sort(key=lambda r: x_values.index(r.point[x_key]))
                if numeric:
                    group.sort(key=lambda r: r.point[x_key])
                    x = np.array([r.point[x_key] for r in group], dtype=float)
                else:
                    x = np.array([x_values.index(r.point[x_key]) for r in group], dtype=float)
                s = [r.summaries[metric] for r in group]
                y = np.array([v.mean for v in s]) * scale
                err = np.nan_to_num(np.array([v.ci95 for v in s]) * scale)
                fixed = [group[0].point[k] for k in others]
                label = ", ".join([group[0].label] + [f"{k}={v}" for k, v in zip(others, fixed)])
                ax.errorbar(x, y, yerr=err, marker="o", ms=3, capsize=2, lw=1, label=label)
                data_rows += [
                    [algorithm, *fixed, r.point[x_key], v.mean, v.ci95, v.min, v.max, v.n, v.missing]
                    for r, v in zip(group, s)
                ]
        if not numeric:
            ax.set_xticks(range(len(x_values)), [str(v) for v in x_values])
        ax.set_xlabel(experiment.figure.get("xlabel", _X_LABELS.get(x_key, x_key)))
        ax.set_ylabel(experiment.figure.get("ylabel", ylabel))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6, ncol=2)
        paths = _save(fig, outdir, experiment.name)
    header = ["algorithm", *others, x_key, metric + "_mean", "ci95", "min", "max", "n", "missing"]
    paths.append(_write_csv(outdir, f"{experiment.name}.csv", header, data_rows))
    return FigureResult(experiment.name, paths)


def coverage_figure(outdir: str | Path, *, quick: bool = False) -> list[Path]:
    """The paper's coverage figure: P(at least one of n nodes covered) against the AUV's
    start position along the area's centre line at the surface, analytic and simulated."""
    import matplotlib

    from swiptopt.coverage import analytic_coverage_probability, simulated_coverage_probability
    from swiptopt.scenario import Scenario

    outdir = Path(outdir)
    scenario = Scenario.preset("paper")
    xs = np.linspace(5.0, 95.0, 7 if quick else 19)
    trials = 300 if quick else 3000
    data_rows = []
    with matplotlib.rc_context({"font.size": 8}):
        fig = _figure()
        ax = fig.add_subplot(1, 1, 1)
        for i, n in enumerate((10, 25, 50)):
            analytic, simulated = [], []
            for x in xs:
                position = (x, 50.0, 0.0)
                a = analytic_coverage_probability(scenario, position, n, 1, rng=i)
                s = simulated_coverage_probability(scenario, position, n, 1, trials=trials, rng=100 + i)
                analytic.append(a)
                simulated.append(s)
                data_rows.append([n, x, a, s, trials])
            line = ax.plot(xs, analytic, lw=1, label=f"n = {n} (analytic)")[0]
            ax.plot(xs, simulated, "o", ms=3, color=line.get_color(), label=f"n = {n} (simulated)")
        ax.set_xlabel("AUV start position x (m), surface, y = 50 m")
        ax.set_ylabel("P(at least 1 node covered)")
        ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6, ncol=2)
        paths = _save(fig, outdir, "fig-coverage")
    heads = ["n_nodes", "x_m", "analytic", "simulated", "trials"]
    paths.append(_write_csv(outdir, "fig-coverage.csv", heads, data_rows))
    return paths


#: The links of :func:`links_figure`: (label, preset overrides of the paper preset).
LINK_CURVES = (
    ("acoustic", {}),
    *((f"optical, {water.replace('_', ' ')}", {"technology": "optical", "water_type": water})
      for water in ("pure_sea", "clear_ocean", "coastal", "turbid_harbour")),
    ("magnetic induction", {"technology": "magnetic_induction"}),
)


def links_figure(outdir: str | Path) -> list[Path]:
    """The three link technologies against distance on the paper preset's defaults
    (docs/links.md): link SNR, data rate (with the scenario's split) and the power a node
    harvests, each to 60 m; the service range is where the SNR crosses the threshold. The
    data go beside it as CSV (``fig-links.csv``)."""
    import matplotlib

    from swiptopt.link import link_budget, service_range_m
    from swiptopt.scenario import Scenario

    outdir = Path(outdir)
    distances = np.linspace(1.0, 60.0, 119)
    rows = []
    with matplotlib.rc_context({"font.size": 8}):
        fig = _figure(height_in=5.2)
        snr_ax, rate_ax, power_ax = (fig.add_subplot(3, 1, i) for i in (1, 2, 3))
        for label, overrides in LINK_CURVES:
            scenario = Scenario.preset("paper", **overrides)
            budget = link_budget(scenario, distances)
            reach = service_range_m(scenario)
            line = snr_ax.plot(distances, budget.snr_db, lw=1, label=f"{label} (range {reach:.0f} m)")[0]
            rate_ax.plot(distances, budget.rate_bps / 1e3, lw=1, color=line.get_color())
            harvested = np.where(budget.harvested_power_w > 0, budget.harvested_power_w, np.nan)
            power_ax.plot(distances, harvested, lw=1, color=line.get_color())
            rows += [[label, d, snr, rate, p_h, reach] for d, snr, rate, p_h in
                     zip(distances, budget.snr_db, budget.rate_bps, budget.harvested_power_w)]
        threshold = Scenario.preset("paper").snr_threshold_db
        snr_ax.axhline(threshold, color="grey", lw=0.6, ls="--")
        snr_ax.set_ylim(-20, 160)
        snr_ax.set_ylabel("SNR (dB)")
        snr_ax.legend(fontsize=5)
        rate_ax.set_yscale("log")
        rate_ax.set_ylabel("rate (kbit/s)")
        power_ax.set_yscale("log")
        power_ax.set_ylabel("harvested (W)")
        power_ax.set_xlabel("distance AUV-node (m)")
        for ax in (snr_ax, rate_ax, power_ax):
            ax.grid(alpha=0.3)
        paths = _save(fig, outdir, "fig-links")
    heads = ["link", "distance_m", "snr_db", "rate_bps", "harvested_w", "service_range_m"]
    paths.append(_write_csv(outdir, "fig-links.csv", heads, rows))
    return paths


def fleet_routes_figure(outdir: str | Path, layout_seed: int = 0, sizes: tuple[int, ...] = (1, 2, 4)) -> list[Path]:
    """The fleet suite's field (:data:`~swiptopt.benchmark.experiment.FLEET_SCENARIO`,
    layout ``layout_seed``) seen from above, one panel per fleet size: the nodes (filled when
    served at the end), each AUV's executed path under k-means + vehicle routing
    (:class:`planners.fleet.FleetRoutingPlanner`, its default settings) in its own colour
    from its start (a triangle), and the fleet's data and makespan in the title. The paths
    go beside it as CSV (``fig-fleet-routes.csv``)."""
    import matplotlib

    from planners.fleet import FleetRoutingPlanner
    from swiptopt import kernel as K
    from swiptopt.benchmark.experiment import FLEET_SCENARIO
    from swiptopt.env_fleet import AuvFleetEnv
    from swiptopt.evaluation import evaluate_fleet
    from swiptopt.scenario import Scenario

    outdir = Path(outdir)
    rows = []
    with matplotlib.rc_context({"font.size": 7}):
        fig = _figure(height_in=2.0)
        for i, n_auvs in enumerate(sizes):
            ax = fig.add_subplot(1, len(sizes), i + 1)
            scenario = Scenario.from_dict({**FLEET_SCENARIO, "n_auvs": n_auvs, "layout_seed": layout_seed})
            env = AuvFleetEnv(scenario)
            record = evaluate_fleet(FleetRoutingPlanner(seed=0), env, 1, seed=0).records[0]
            state, tables = env.fleet_state, env.fleet.tables
            served = K.served_mask(state.data_left, state.energy, tables.capacity, tables.named.reward_weight)
            nodes = scenario.layout.positions_m
            ax.scatter(nodes[~served, 0], nodes[~served, 1], s=6, facecolors="none", edgecolors="0.4", lw=0.5)
            ax.scatter(nodes[served, 0], nodes[served, 1], s=6, c="0.4")
            for k, path in enumerate(env.paths):
                xy = scenario.cell_centers_m[np.asarray(path, dtype=np.int64)]
                line = ax.plot(xy[:, 0], xy[:, 1], lw=0.8)[0]
                ax.scatter(xy[:1, 0], xy[:1, 1], marker="^", s=14, color=line.get_color())
                rows += [[n_auvs, k, t, *map(float, p)] for t, p in enumerate(xy)]
            ax.set_xlim(0, scenario.length_m)
            ax.set_ylim(0, scenario.width_m)
            ax.set_aspect("equal")
            ax.set_xlabel("x (m)")
            if i == 0:
                ax.set_ylabel("y (m)")
            ax.set_title(f"{n_auvs} AUV{'s' if n_auvs > 1 else ''}: {record['data_bits'] / 1e6:.2f} Mbit,\n"
                         f"makespan {record['makespan_s']:.0f} s", fontsize=6)
        paths = _save(fig, outdir, "fig-fleet-routes")
    paths.append(_write_csv(outdir, "fig-fleet-routes.csv", ["n_auvs", "auv", "step", "x_m", "y_m", "depth_m"], rows))
    return paths


def _budget_units(experiment: Any) -> str:
    """What the budgets of a learning curve's algorithms count, for its x axis: steps (deep
    RL), decisions (a stop-choosing agent: a stop and its dwell, several steps) or episodes
    (tabular RL, whose budgets set ``train_episodes``); the most common first, the others
    named by their algorithm's label, as the tables name them."""
    from swiptopt.benchmark.algorithms import labels

    names = labels()
    units = {name: experiment.budget_unit(name) for name in experiment.budgets}
    counts = Counter(units.values())
    main = max(counts, key=lambda unit: (counts[unit], unit == "steps"))
    others = [f"{names.get(name, name)}: {unit}" for name, unit in units.items() if unit != main]
    return "; ".join([main, *others])


#: A learning curve's colour for each algorithm (matplotlib's default cycle), the same in
#: every panel and figure: an algorithm and its fleet counterpart share one, the learners
#: and the planners that appear beside them take different ones.
_CURVE_COLOURS = {
    "ppo": "C0", "shared_ppo": "C0", "dqn": "C1", "sac": "C2", "stop_ppo": "C3", "fleet_stop_ppo": "C3",
    "q_learning": "C4", "fleet_q_learning": "C4", "sarsa": "C5", "random": "C7", "fleet_random": "C7",
    "kmeans_tsp": "C6", "fleet_routing": "C6", "ompl_tour": "C6", "rate_greedy": "C8", "straight_line": "C8",
    "milp": "C9", "fleet_milp": "C9",
}


def _curve_colours(names: list[str]) -> dict[str, str]:
    """The colour of each of one panel's algorithms (:data:`_CURVE_COLOURS`); one without a
    colour of its own, or whose colour another has taken in the panel, gets the first one
    left of the cycle's ten."""
    out: dict[str, str] = {}
    for name in names:
        wanted = _CURVE_COLOURS.get(name)
        if wanted is not None and wanted not in out.values():
            out[name] = wanted
    free = [f"C{i}" for i in range(10) if f"C{i}" not in out.values()]
    for name in names:
        if name not in out:
            out[name] = free.pop(0) if free else "k"
    return out


def learning_curve_figure(experiments: list[Experiment], store: ResultStore, outdir: str | Path,
                          stem: str = "fig-learning-curve") -> FigureResult:
    """Return against training budget (log x), one panel per experiment with ``budgets``:
    a line with 95 % CI error bars per learning algorithm, each planner of the experiment as
    a band (its mean ± 95 % CI over the same layouts). The data go beside it as CSV. Only
    complete rows are drawn (every task of the budget, or of the planner, has a result): a
    mean over some layouts is not a point of the curve; a panel with none says so."""
    import matplotlib

    from swiptopt.benchmark import tables

    curves = [e for e in experiments if e.budgets]
    if not curves:
        return FigureResult(stem, [], "none of the experiments has budgets")
    outdir = Path(outdir)
    data_rows: list[list[Any]] = []
    with matplotlib.rc_context({"font.size": 7}):
        cols = 2 if len(curves) > 1 else 1
        nrows = -(-len(curves) // cols)
        fig = _figure(2.3 * nrows)
        fig.set_size_inches(2 * COLUMN_WIDTH_IN if cols == 2 else COLUMN_WIDTH_IN, 2.3 * nrows)
        drawn = False
        for i, experiment in enumerate(curves):
            ax = fig.add_subplot(nrows, cols, i + 1)
            stored = tables.load_results(experiment, store)
            rows, _ = tables.aggregate(experiment, stored)
            rows = [r for r in rows if stored.complete((0, r.algorithm))]
            by_row = {r.algorithm: r for r in rows}
            lo = min(min(b) for b in experiment.budgets.values())
            hi = max(max(b) for b in experiment.budgets.values())
            planners = [r for r in rows if "@" not in r.algorithm and r.algorithm not in experiment.budgets]
            colour = _curve_colours([*experiment.budgets, *(r.algorithm for r in planners)])
            for r in planners:
                s = r.summaries["return"]
                band = np.nan_to_num(s.ci95)
                ax.plot([lo, hi], [s.mean, s.mean], lw=0.8, ls=":", color=colour[r.algorithm], label=r.label)
                ax.fill_between([lo, hi], s.mean - band, s.mean + band, color=colour[r.algorithm], alpha=0.15, lw=0)
                data_rows.append([experiment.name, r.algorithm, "", s.mean, s.ci95, s.n])
            for name, budgets in experiment.budgets.items():
                found = [(b, by_row.get(f"{name}@{b}")) for b in budgets]
                found = [(b, r) for b, r in found if r is not None]
                if not found:
                    continue
                x = np.array([b for b, _ in found], dtype=float)
                s = [r.summaries["return"] for _, r in found]
                ax.errorbar(x, [v.mean for v in s], yerr=np.nan_to_num([v.ci95 for v in s]), marker="o", ms=2.5,
                            capsize=2, lw=1, color=colour[name], label=found[0][1].label.split(" @ ")[0])
                data_rows += [[experiment.name, name, b, v.mean, v.ci95, v.n] for b, v in zip(x.astype(int), s)]
                drawn = True
            if not rows:
                ax.text(0.5, 0.5, "not complete in this store", ha="center", va="center", transform=ax.transAxes)
            ax.set_xscale("log", base=2)
            ax.set_xlabel(f"training budget ({_budget_units(experiment)})")
            ax.set_ylabel("return")
            ax.set_title(f"{experiment.name} ({experiment.world})")
            ax.grid(alpha=0.3)
            if rows:
                ax.legend(fontsize=5, ncol=2)
        if not drawn:
            return FigureResult(stem, [], "the store holds none of the curves' results")
        paths = _save(fig, outdir, stem)
    paths.append(_write_csv(outdir, f"{stem}.csv", ["experiment", "algorithm", "budget", "return_mean", "ci95", "n"],
                            data_rows))
    return FigureResult(stem, paths)
