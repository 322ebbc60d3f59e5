# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.6
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Head to head: RL agents against classical planners
#
# A small experiment through the benchmark's public API, into a temporary results
# store: every algorithm on the `paper` preset over a sweep of node counts and a few
# layouts. Then the store is read back for
#
# 1. the comparison table (`swiptopt.benchmark.tables`: Markdown, and a pandas DataFrame from
#    the CSV form);
# 2. a paper-style figure: metrics against the node count with 95 % CI error bars;
# 3. optimality gaps: against the tightest bound the experiment has for each scenario (the
#    MILP's, which the benchmark uses as its reference, else the closed-form upper bound),
#    and against the exact optimum (dynamic programming) on the `tiny` preset;
# 4. a discussion computed from the numbers: which algorithm ranks first per metric,
#    and where RL or the planners win.
#
# Set `SWIPTOPT_NOTEBOOK_QUICK=1` for small settings (the tests do); the quick numbers
# come from very short training and are a smoke test, not a result.

# %%
import os

QUICK = os.environ.get("SWIPTOPT_NOTEBOOK_QUICK", "0") == "1"
SEED = 0
NODE_COUNTS = [6, 10] if QUICK else [10, 20, 30, 40, 50]
LAYOUTS = 2 if QUICK else 6  # node layouts per sweep point (the error bars)
EPISODES = 2 if QUICK else 10  # greedy evaluation episodes per task
TRAIN_EPISODES = 1_000 if QUICK else 20_000  # per RL task
MILP_BUDGET = "quick" if QUICK else "compare"  # a named, deterministic budget of planners.optimal
WORKERS = 1 if QUICK else None  # local processes; None: every core
TINY_EPISODES = 3 if QUICK else 10  # evaluation episodes on the tiny preset

# %matplotlib inline
import io
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from IPython.display import Markdown, display

from planners import exact_optimum, upper_bound
from swiptopt import Scenario, evaluate
from swiptopt.benchmark import tables
from swiptopt.benchmark.algorithms import ALGORITHMS, build_policy
from swiptopt.benchmark.experiment import Experiment
from swiptopt.benchmark.runner import execute
from swiptopt.benchmark.store import ResultStore
from swiptopt.env import AuvSwiptEnv

plt.rcParams.update({"figure.dpi": 90, "axes.grid": True, "grid.alpha": 0.3})
print(f"quick settings: {QUICK}")

# %% [markdown]
# ## 1. Run the experiment
#
# `Experiment.from_dict` takes the same keys as an experiment TOML file. Each
# (node count, layout, algorithm, seed) is one task; `execute` runs the tasks the
# store lacks and commits each as it finishes. Running it a second time finds every
# task stored and runs nothing.

# %%
experiment = Experiment.from_dict({
    "name": "notebook-head-to-head",
    "scenario": {"preset": "paper"},
    "sweep": {"n_nodes": NODE_COUNTS},
    "layouts": LAYOUTS,
    "seeds": 1,
    "episodes": EPISODES,
    "baseline": "random",
    "algorithms": {
        "q_learning": {"train_episodes": TRAIN_EPISODES},
        "sarsa": {"train_episodes": TRAIN_EPISODES},
        "random": {},
        "kmeans_tsp": {},
        "lawnmower": {},
        "greedy": {},
        "rate_greedy": {},
        "milp": {"budget": MILP_BUDGET},
    },
})
workdir = tempfile.TemporaryDirectory(prefix="swiptopt-notebook-")
store_path = Path(workdir.name) / "results.sqlite"
with ResultStore(store_path) as store:
    first = execute(experiment, store, workers=WORKERS)
    again = execute(experiment, store, workers=WORKERS)
print(f"{first.total} tasks: ran {first.ran} in {first.seconds:.1f} s; "
      f"second run: {again.cached} found in the store, {again.ran} ran")

# %% [markdown]
# ## 2. The comparison table
#
# `tables.aggregate` averages each task's evaluation episodes, then summarises over
# layouts (mean ± 95 % CI); the rank is by mean return at each node count. The gap to
# bound is (bound − return) / |bound| per task, against the tightest bound the experiment
# has for that task's scenario; the `bound` column says which (section 4), and the MILP's
# own row adds [best, bound]: the mean of its plans' values in its model and of its bounds.

# %%
with ResultStore(store_path, create=False) as store:
    rows, missing = tables.aggregate(experiment, store)
    provenance = store.runs()[-1]["provenance"]
versions = provenance["versions"]
print(f"{missing} tasks missing; swiptopt {versions['swiptopt']}, numpy {versions['numpy']}")
display(Markdown(tables.to_markdown(rows)))

# %% [markdown]
# With `baseline = "random"`, `tables.paired` divides each algorithm's mean by the
# random trajectory's over the same layouts: the ratio, a seeded 95 % bootstrap
# interval, and on how many layouts the algorithm did better.

# %%
with ResultStore(store_path, create=False) as store:
    pairs = tables.paired(experiment, store)
display(Markdown(tables.render_paired(pairs, "markdown")))

# %%
results = pd.read_csv(io.StringIO(tables.to_csv(rows)))
results["label"] = results["algorithm"].map({name: a.label for name, a in ALGORITHMS.items()})
results["family"] = results["algorithm"].map({name: a.family for name, a in ALGORITHMS.items()})
print("columns:", ", ".join(results.columns))
print("mean data collected (kbit) per algorithm and node count:")
data_kbit = results[results.metric == "data_bits"].pivot(index="label", columns="n_nodes", values="mean") / 1e3
data_kbit.round(0)

# %% [markdown]
# ## 3. Metrics against the number of nodes
#
# The paper's node-count figures for every algorithm at once; error bars are 95 %
# confidence intervals over layouts.

# %%
FIGURE_METRICS = {
    "return": ("return (-)", 1.0),
    "data_bits": ("data collected (kbit)", 1e-3),
    "energy_delivered_j": ("energy delivered to nodes (mJ)", 1e3),
    "mobility_efficiency_bit_per_j": ("energy efficiency, AUV motion (bit/J)", 1.0),
}
fig, axes = plt.subplots(1, len(FIGURE_METRICS), figsize=(17, 3.8))
for ax, (metric, (ylabel, scale)) in zip(axes, FIGURE_METRICS.items()):
    for algorithm in experiment.algorithms:
        mine = results[(results.metric == metric) & (results.algorithm == algorithm)].sort_values("n_nodes")
        ax.errorbar(mine["n_nodes"], mine["mean"] * scale, yerr=mine["ci95"].fillna(0.0) * scale,
                    marker="o", ms=4, capsize=3, label=mine["label"].iloc[0])
    ax.set_xticks(NODE_COUNTS)
    ax.set_xlabel("number of nodes (-)")
    ax.set_ylabel(ylabel)
axes[0].legend(fontsize=7)
fig.tight_layout()

# %% [markdown]
# ## 4. Optimality gaps
#
# **Against the tightest bound.** `planners.bounds.upper_bound` caps what any policy can
# earn: every coverable node's data and storage room, with no travel. It is loose (serving
# takes time and moving costs). The MILP (`planners.solve_optimum`) proves a much tighter
# bound for the same scenario, and the table measures every gap against it where the
# experiment ran the MILP on that layout. What it bounds depends on the channel: with a
# deterministic channel, every policy's return (`milp`); with the `paper` preset's fading
# and link failures, the MILP solves the *expected-rate relaxation* and its bound holds for
# that relaxation of open-loop walks only (`milp (expected)`): a policy that reacts to the
# draws could beat it, and would then show a negative gap.

# %%
example = experiment.scenario_for({"n_nodes": NODE_COUNTS[0]}, 0)
bound = upper_bound(example)
milp_bounds = results[(results.metric == tables.SOLVER_BOUND) & (results.algorithm == "milp")].set_index("n_nodes")
print(f"{example.n_nodes} nodes, layout 0: upper bound on the return {bound.return_:.2f}, "
      f"data {bound.data_bits / 1e3:.0f} kbit, energy {bound.energy_delivered_j * 1e3:.0f} mJ")
print("mean MILP bound per node count:", {int(n): round(v, 2) for n, v in milp_bounds["mean"].items()},
      "| bound used per row:", sorted(set(results["bound"])))

gaps = results[results.metric == tables.GAP_BOUND]
labels = [ALGORITHMS[name].label for name in experiment.algorithms]
width = 0.8 / len(NODE_COUNTS)
fig, ax = plt.subplots(figsize=(11, 3.8))
for i, n in enumerate(NODE_COUNTS):
    at_n = gaps[gaps.n_nodes == n].set_index("label").reindex(labels)
    ax.bar(np.arange(len(labels)) + (i - (len(NODE_COUNTS) - 1) / 2) * width, at_n["mean"] * 100, width,
           yerr=at_n["ci95"].fillna(0.0) * 100, capsize=2, label=f"{n} nodes")
ax.set_xticks(np.arange(len(labels)), labels)
ax.set_xlabel("algorithm")
ax.set_ylabel("gap to the tightest bound on the return (%)")
ax.legend(fontsize=8)
fig.tight_layout()

# %% [markdown]
# **Against the exact optimum.** The `tiny` preset (3 nodes, a 3 × 3 × 2 grid,
# 8 steps, no fading, no link failures) is small enough for `exact_optimum` to find the
# best return by dynamic programming over the deterministic MDP. Replaying its actions
# in the environment earns exactly that return. Each algorithm, built with the same
# settings as in the experiment, is scored with `swiptopt.evaluate`; the MILP is exact on
# this deterministic scenario, so with enough budget it finds this optimum too.

# %%
tiny = Scenario.preset("tiny", layout_seed=SEED)
optimum = exact_optimum(tiny)
tiny_bound = upper_bound(tiny)
env = AuvSwiptEnv(tiny)
env.reset(seed=SEED)
replayed = 0.0
for action in optimum.actions:
    _, reward, terminated, truncated, _ = env.step(action)
    replayed += reward
print(f"exact optimum {optimum.return_:.3f} ({optimum.states_explored} states explored); "
      f"replayed in the environment {replayed:.3f}; upper bound {tiny_bound.return_:.3f}")
assert np.isclose(replayed, optimum.return_)

tiny_rows = []
for name, settings in experiment.algorithms.items():
    policy = build_policy(name, env, settings, SEED)
    summary = evaluate(policy, env, TINY_EPISODES, seed=SEED + 1_000).summary["return"]
    tiny_rows.append({"algorithm": name, "label": ALGORITHMS[name].label, "family": ALGORITHMS[name].family,
                      "return": summary.mean, "ci95": summary.ci95,
                      "gap_to_optimum_pct": 100 * (optimum.return_ - summary.mean) / optimum.return_})
tiny_results = pd.DataFrame(tiny_rows)

fig, ax = plt.subplots(figsize=(9, 3.8))
ax.bar(tiny_results["label"], tiny_results["return"], yerr=tiny_results["ci95"].fillna(0.0), capsize=3,
       color=["tab:blue" if f == "rl" else "tab:orange" for f in tiny_results["family"]])
ax.axhline(optimum.return_, color="k", lw=1.5, label="exact optimum")
ax.axhline(tiny_bound.return_, color="k", ls="--", lw=1, label="upper bound")
ax.set_xlabel("algorithm (blue: RL, orange: planner)")
ax.set_ylabel("return on the tiny preset (-)")
ax.legend(fontsize=8)
fig.tight_layout()
tiny_results.round(3)

# %% [markdown]
# ## 5. Where RL wins and where the planners win
#
# Computed from the table above, not written in advance: for every metric and node
# count, the best RL agent against the best planner. A win is "clear" when the
# difference of the means exceeds the sum of their 95 % CI half-widths. Steps to 50 %
# of the data count only for algorithms that reached the target on every layout (the
# table's "n/r" marks the others); a family with none loses that comparison clearly.

# %%
LOWER_IS_BETTER = {"steps_to_data_target", tables.GAP_BOUND}
# a mean over only the layouts where a target happened to be reached flatters the
# algorithm, so a steps-to-target value counts only when every layout reached it
EVERY_LAYOUT = {"steps_to_data_target"}

def best(frame, higher):
    frame = frame.dropna(subset=["mean"])
    if frame.empty:
        return None
    return frame.loc[frame["mean"].idxmax() if higher else frame["mean"].idxmin()]

def shown(row, scale, digits):
    return "not reached on every layout" if row is None else f"{row['label']} ({row['mean'] * scale:.{digits}f})"

lines = ["| metric | nodes | first overall | best RL | best planner | winner |", "|---|---|---|---|---|---|"]
wins = {"rl": [], "planner": []}
compared = 0
for metric, heading, scale, digits in tables.DISPLAY:  # the columns of the table above
    higher = metric not in LOWER_IS_BETTER
    for n in NODE_COUNTS:
        at = results[(results.metric == metric) & (results.n_nodes == n)]
        if metric in EVERY_LAYOUT:
            at = at[at["missing"] == 0]
        top = best(at, higher)
        rl, planner = best(at[at.family == "rl"], higher), best(at[at.family == "planner"], higher)
        if top is None:
            continue  # no algorithm has a value (a target nobody reached)
        compared += 1
        if rl is None or planner is None:
            family, clear = ("planner" if rl is None else "rl"), True  # only one family has a value
        elif rl["mean"] == planner["mean"]:
            family, clear = None, False
        else:
            family = "rl" if (rl["mean"] > planner["mean"]) == higher else "planner"
            ci = rl["ci95"] + planner["ci95"]  # NaN with a single layout: never clear
            clear = bool(abs(rl["mean"] - planner["mean"]) > ci)
        if family is None:
            verdict = "tie"
        else:
            wins[family].append((heading, n, clear))
            verdict = ("RL" if family == "rl" else "planner") + (" (clear)" if clear else "")
        lines.append(f"| {heading} | {n} | {top['label']} | {shown(rl, scale, digits)} | "
                     f"{shown(planner, scale, digits)} | {verdict} |")

def summary_of(family):
    found = wins[family]
    if not found:
        return f"none of {compared} comparisons"
    clear = sorted({heading for heading, _, c in found if c})
    return (f"{len(found)} of {compared} comparisons"
            + (f"; clearly on {', '.join(clear)}" if clear else "; none of them clearly"))

best_tiny = tiny_results.loc[tiny_results["return"].idxmax()]
rl_tiny = tiny_results[tiny_results.family == "rl"]["gap_to_optimum_pct"].min()
planner_tiny = tiny_results[tiny_results.family == "planner"]["gap_to_optimum_pct"].min()
text = "\n".join(lines) + "\n\n" + "\n".join([
    f"- **RL wins** {summary_of('rl')}.",
    f"- **Planners win** {summary_of('planner')}.",
    f"- On the `tiny` preset the best return is {best_tiny['label']}'s; the best RL agent is "
    f"{rl_tiny:.0f} % below the exact optimum, the best planner {planner_tiny:.0f} %.",
    f"- Settings: {TRAIN_EPISODES} training episodes per RL task, {LAYOUTS} layouts, {EPISODES} evaluation "
    f"episodes{' (quick settings: too short for RL to converge)' if QUICK else ''}.",
])
display(Markdown(text))

# %%
workdir.cleanup()  # the store was temporary
