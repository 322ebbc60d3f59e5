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
# # Learning: the paper's agents on the shared simulator
#
# Tabular Q-learning and SARSA (the paper's Table I settings: learning rate 0.75,
# discount 0.99, ε from 1 decaying ×0.999 per episode) and the random trajectory,
# trained with `rl.train` on the compiled backend (numba, the same kernel as the
# Gymnasium environment). This notebook shows
#
# 1. training curves: moving averages of the per-episode return and data collected;
# 2. the effect of the reward weight Γ and of the power-splitting ratio α on the
#    greedy policy (small sweeps with `rl.paper_protocol`, error bars over layouts);
# 3. a learned trajectory in 3D, with the nodes coloured by whether they were served.
#
# Set `SWIPTOPT_NOTEBOOK_QUICK=1` for small settings (the tests do).

# %%
import os

QUICK = os.environ.get("SWIPTOPT_NOTEBOOK_QUICK", "0") == "1"
SEED = 0
N_NODES = 25
TRAIN_EPISODES = 5_000 if QUICK else 20_000  # training curves and the trajectory
WINDOW = 100 if QUICK else 500  # moving-average window, episodes
EVAL_EPISODES = 3 if QUICK else 20  # greedy evaluation episodes
SWEEP_EPISODES = 2_000 if QUICK else 20_000  # training episodes per sweep task
SWEEP_LAYOUTS = 2 if QUICK else 10  # node layouts per sweep point (error bars)
REWARD_WEIGHTS = [0.2, 0.5, 0.8] if QUICK else [0.1, 0.3, 0.5, 0.7, 0.9]
SPLIT_RATIOS = [0.2, 0.5, 0.8] if QUICK else [0.1, 0.3, 0.5, 0.7, 0.9]

# %matplotlib inline
import matplotlib.pyplot as plt
import numpy as np

from rl import QLearningAgent, RandomAgent, SarsaAgent, paper_protocol, train
from swiptopt import Scenario, Summary, evaluate
from swiptopt.env import AuvSwiptEnv
from swiptopt.kernel import is_served

plt.rcParams.update({"figure.dpi": 90, "axes.grid": True, "grid.alpha": 0.3})
scenario = Scenario.preset("paper", n_nodes=N_NODES, layout_seed=SEED)
print(f"quick settings: {QUICK}; {scenario.n_nodes} nodes, {scenario.n_cells} cells, "
      f"{scenario.episode_steps} steps per episode")


# %% [markdown]
# ## 1. Training curves
#
# One layout, one seed per agent. The compiled trainer steps the same kernel as
# `AuvSwiptEnv.step` and draws the same random numbers in the same order, so these
# curves are exactly what the Python loop would produce, only faster.

# %%
def moving_average(values, window):
    window = max(1, min(window, len(values)))
    return np.convolve(values, np.ones(window) / window, mode="valid")

agents, logs, envs = {}, {}, {}
for name, make in (("Q-learning", QLearningAgent), ("SARSA", SarsaAgent), ("random", RandomAgent)):
    env = AuvSwiptEnv(scenario)
    agent = make(env.observation_space.n, seed=SEED)
    logs[name] = train(agent, env, TRAIN_EPISODES, seed=SEED, backend="compiled")
    agents[name], envs[name] = agent, env

fig, (ax_return, ax_data) = plt.subplots(1, 2, figsize=(12, 4.3))
for name, log in logs.items():
    x = np.arange(min(WINDOW, len(log)), len(log) + 1)  # the episode that ends each window
    ax_return.plot(x, moving_average(log["return"], WINDOW), label=name)
    ax_data.plot(x, moving_average(log["data_bits"], WINDOW) / 1e3, label=name)
ax_eps = ax_return.twinx()
ax_eps.plot(np.arange(1, len(logs["Q-learning"]) + 1), logs["Q-learning"]["epsilon"], ":", color="0.4")
ax_eps.set_ylabel("exploration rate epsilon (-), dotted")
ax_eps.set_ylim(0, 1.05)
ax_eps.grid(False)
ax_return.set_xlabel("training episode (-)")
ax_return.set_ylabel(f"return, moving average over {WINDOW} episodes (-)")
ax_return.legend(fontsize=8, loc="upper left")
ax_data.set_xlabel("training episode (-)")
ax_data.set_ylabel(f"data collected, moving average over {WINDOW} episodes (kbit)")
ax_data.legend(fontsize=8)
fig.tight_layout()

# %%
print(f"greedy policy after {TRAIN_EPISODES} training episodes, {EVAL_EPISODES} evaluation episodes (mean +- 95 % CI):")
for name, agent in agents.items():
    s = evaluate(agent, envs[name], EVAL_EPISODES, seed=SEED + 10_000).summary
    print(f"  {name:10s} return {s['return'].mean:6.2f} +- {np.nan_to_num(s['return'].ci95):5.2f}   "
          f"data {s['data_bits'].mean / 1e3:6.0f} kbit   energy {s['energy_delivered_j'].mean * 1e3:6.0f} mJ   "
          f"served {s['nodes_served'].mean:4.1f} nodes")

# %% [markdown]
# ## 2. Reward weight and split ratio
#
# The paper's protocol per layout: train on a fixed node layout under the stochastic
# channel, then evaluate the greedy policy on separate seeds. Each point averages the
# evaluation of `SWEEP_LAYOUTS` layouts; error bars are 95 % confidence intervals over
# layouts (none with a single layout).
#
# Γ weighs data against energy in the reward, so returns at different Γ measure
# different things: compare the data and the energy. The energy reference of the
# reward does not depend on α, so returns across the split-ratio sweep are comparable.

# %%
METRICS = {
    "return": ("return (-)", 1.0),
    "data_bits": ("data collected (kbit)", 1e-3),
    "energy_delivered_j": ("energy delivered (mJ)", 1e3),
    "nodes_served": ("nodes served (-)", 1.0),
}

def sweep(field, values, algorithm):
    # Summary over layouts of each layout's mean greedy evaluation, per value
    out = {metric: [] for metric in METRICS}
    for value in values:
        per_layout = {metric: [] for metric in METRICS}
        for layout in range(SWEEP_LAYOUTS):
            s = Scenario.preset("paper", n_nodes=N_NODES, layout_seed=layout, **{field: value})
            result = paper_protocol(s, algorithm, train_episodes=SWEEP_EPISODES, eval_episodes=EVAL_EPISODES,
                                    seed=SEED + layout)
            for metric in METRICS:
                per_layout[metric].append(result.evaluation.summary[metric].mean)
        for metric in METRICS:
            out[metric].append(Summary.of(per_layout[metric]))
    return out

def plot_sweep(field, values, xlabel):
    fig, axes = plt.subplots(1, len(METRICS), figsize=(16, 3.6))
    for algorithm, label in (("q_learning", "Q-learning"), ("sarsa", "SARSA")):
        result = sweep(field, values, algorithm)
        for ax, (metric, (ylabel, scale)) in zip(axes, METRICS.items()):
            mean = np.array([s.mean for s in result[metric]]) * scale
            ci = np.nan_to_num(np.array([s.ci95 for s in result[metric]])) * scale
            ax.errorbar(values, mean, yerr=ci, marker="o", capsize=3, label=label)
            ax.set_xlabel(xlabel)
            ax.set_ylabel(ylabel)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    return fig

fig = plot_sweep("reward_weight", REWARD_WEIGHTS, "reward weight Gamma (-)")

# %%
fig = plot_sweep("split_ratio", SPLIT_RATIOS, "power-splitting ratio alpha (-)")

# %% [markdown]
# ## 3. A learned trajectory in 3D
#
# The Q-learning agent trained above, rolled out greedily once in the environment.
# `env.path` holds the cell of every step; `scenario.cell_centers_m` turns cells into
# metres. A node counts as served when its data is delivered and its storage is full
# (the environment's own definition); "partly served" nodes got data or energy but not
# all of it.

# %%
env = AuvSwiptEnv(scenario)
agent = agents["Q-learning"]
obs, info = env.reset(seed=SEED + 20_000)
parts = []
while True:
    obs, reward, terminated, truncated, info = env.step(agent.predict(obs, deterministic=True))
    parts.append(info["reward_parts"])
    if terminated or truncated:
        break
episode = info["episode_metrics"]
path_m = scenario.cell_centers_m[np.asarray(env.path)]
state = env.state
nodes_m = scenario.layout.positions_m
served = np.array([is_served(state.data_left, state.energy, env.tables.capacity, scenario.reward_weight, i)
                   for i in range(scenario.n_nodes)])
partly = ~served & ((state.collected > 0) | (state.delivered > 0))
untouched = ~served & ~partly
print(f"{episode['length']} steps: {episode['data_bits'] / 1e3:.0f} kbit collected, "
      f"{episode['energy_delivered_j'] * 1e3:.0f} mJ delivered, {episode['nodes_served']} nodes served, "
      f"return {episode['return']:.2f}")

fig = plt.figure(figsize=(15, 5))
ax3d = fig.add_subplot(1, 3, (1, 2), projection="3d")
ax3d.plot(*path_m.T, "-", color="k", lw=1.5, alpha=0.7, label="AUV path")
cells, dwell = np.unique(np.asarray(env.path), return_counts=True)
ax3d.scatter(*scenario.cell_centers_m[cells].T, s=12 * dwell, color="k", alpha=0.4)  # area: steps spent there
ax3d.scatter(*path_m[0], marker="^", s=120, color="tab:red", label="start")
for mask, colour, label in ((served, "tab:green", "served"), (partly, "tab:orange", "partly served"),
                            (untouched, "tab:blue", "not served")):
    ax3d.scatter(*nodes_m[mask].T, color=colour, s=25, depthshade=False, label=f"{label} ({mask.sum()})")
ax3d.set_xlim(0, scenario.length_m)
ax3d.set_ylim(0, scenario.width_m)
ax3d.set_zlim(scenario.depth_m, 0)  # depth grows downwards
ax3d.set_box_aspect(scenario.extent_m)  # metres equal on every axis
ax3d.set_xlabel("x (m)")
ax3d.set_ylabel("y (m)")
ax3d.set_zlabel("depth (m)")
ax3d.set_title("greedy Q-learning trajectory (grey discs: steps spent in a cell)")
ax3d.legend(fontsize=7, loc="upper left")

ax_parts = fig.add_subplot(1, 3, 3)
steps = np.arange(1, len(parts) + 1)
for key in ("throughput", "harvest", "movement"):
    ax_parts.plot(steps, np.cumsum([p[key] for p in parts]), label=key)
ax_parts.plot(steps, np.cumsum([sum(p.values()) for p in parts]), "k", lw=2, label="return")
ax_parts.set_xlabel("step of the episode (-)")
ax_parts.set_ylabel("cumulative reward part (-)")
ax_parts.set_title("the reward, part by part")
ax_parts.legend(fontsize=8)
fig.tight_layout()
