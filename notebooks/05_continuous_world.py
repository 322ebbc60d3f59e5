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
# # The continuous world: OMPL tours and deep RL around the harbour's obstacles
#
# The paper's grid moves the AUV in 10 m unit steps; the continuous world
# (`swiptopt/AuvSwiptContinuous-v0`) lets it move anywhere, along straight segments
# stopped by the obstacles, with the same physics and reward. This notebook runs the
# harbour suite's contenders on one layout and draws their paths:
#
# - the **OMPL tour** (`planners.OmplTourPlanner`): hover points placed in continuous
#   space, a tour whose legs are OMPL paths of least AUV energy around the pier, the hull,
#   the wreck and the seabed, against the current;
# - the **straight-line** planner: the same kind of plan with straight legs that ignore
#   obstacles and the current, giving up a stop when a leg runs into something;
# - **PPO** and **SAC** with the harbour suite's settings (Stable-Baselines3), loaded from
#   `results/models/` when `swiptopt compare` has trained them, else trained here.
#
# Set `SWIPTOPT_NOTEBOOK_QUICK=1` for small settings (the tests do).

# %%
import os
from pathlib import Path

QUICK = os.environ.get("SWIPTOPT_NOTEBOOK_QUICK", "0") == "1"
LAYOUT = 3  # a layout with nodes on both sides of the pier
EPISODE_SEED = 1_000_003 + 1000 * LAYOUT  # the suite's first evaluation seed for this layout

# %matplotlib inline
import matplotlib.pyplot as plt

import swiptopt
from swiptopt import evaluate
from swiptopt.benchmark.algorithms import BuildContext, build_policy
from swiptopt.benchmark.experiment import builtin_experiments
from swiptopt.env_continuous import AuvSwiptContinuousEnv
from swiptopt.plotting import draw_world

suite = builtin_experiments()["harbour"]
if QUICK:
    suite = suite.quick()
scenario = suite.scenario_for({}, LAYOUT)
env = AuvSwiptContinuousEnv(scenario)
print(suite.description)

# %% [markdown]
# Each contender is built as the benchmark builds it (`build_policy` with the suite's
# settings), then runs one greedy episode; `env.path` holds the positions it visited.

# %%
models = Path("results/models")
policies, paths, returns = {}, {}, {}
for name in ("ompl_tour", "straight_line", "ppo", "sac"):
    context = BuildContext(scenario, 0, suite.training_layouts, str(models) if models.is_dir() else None,
                           world=suite.world)
    policy = policies[name] = build_policy(name, env, suite.algorithms[name], seed=1000 * LAYOUT, context=context)
    result = evaluate(policy, env, 1, seed=EPISODE_SEED)
    paths[name] = env.path
    returns[name] = result.records[0]["return"]
    print(f"{name:>14}: return {returns[name]:7.2f}, data {result.records[0]['data_bits'] / 1e3:6.1f} kbit, "
          f"AUV energy {result.records[0]['auv_energy_j'] / 1e3:6.1f} kJ")

# %% [markdown]
# The plan of the OMPL tour: its stops and where its legs came from (a straight segment
# when it is free, OMPL's path when it is not).

# %%
plan = policies["ompl_tour"].plan_
print("stops (m):", plan.hover_points_m.round(1).tolist())
print("dwell steps:", plan.dwell_steps.tolist())
print("legs:", [leg.source for leg in plan.legs])

# %%
fig, (top, side) = plt.subplots(1, 2, figsize=(13, 5), gridspec_kw={"width_ratios": [1, 1.3]})
labels = {"ompl_tour": "OMPL tour", "straight_line": "straight line", "ppo": "PPO", "sac": "SAC"}
draw_world(scenario, top, side, {f"{labels[k]} ({returns[k]:.1f})": v for k, v in paths.items()})
top.legend(loc="upper right", fontsize=8)
fig.suptitle(f"harbour layout {LAYOUT}: paths of one episode (return in brackets); grey: obstacles")
fig.tight_layout()
if not QUICK:
    fig.savefig(Path(swiptopt.__file__).resolve().parent.parent / "docs" / "fig-harbour-paths.png", dpi=110)
