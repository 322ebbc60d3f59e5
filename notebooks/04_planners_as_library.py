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
# # The planners as a library
#
# The classical baselines without the environment: plain numpy arrays and small result
# dataclasses in, result dataclasses out.
#
# 1. `planners.kmeans_hover_points`: k-means of the node positions into hover
#    points, each group covered from one cell;
# 2. `planners.solve_tsp`: the shortest tour (OR-Tools) over the start and the
#    hover points;
# 3. `planners.plan_path_3d`: OMPL paths around obstacles, a sphere in open
#    water and the `harbour` preset (pier, hull, wreck, sloping seabed, current);
# 4. `planners.power_split`: the closed-form optimal split ratio over the reward weight
#    and the distance, and the convex dwell-time and split program on a small instance.
#
# Set `SWIPTOPT_NOTEBOOK_QUICK=1` for small settings (the tests do).

# %%
import os

QUICK = os.environ.get("SWIPTOPT_NOTEBOOK_QUICK", "0") == "1"
SEED = 0
OMPL_SEED = SEED + 1  # OMPL's seed is process-wide, set once, and must be >= 1
N_NODES = 30
OMPL_TIME_LIMIT_S = 0.3 if QUICK else 2.0
GRID_POINTS = 40 if QUICK else 200  # points per axis of the split-ratio map
BUDGET_POINTS = 5 if QUICK else 20  # mission-time budgets of the dwell sweep

# %matplotlib inline
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import LogNorm

from planners import (
    DwellSplitProblem,
    kmeans_hover_points,
    optimal_split_ratio,
    optimise_dwell_and_split,
    plan_path_3d,
    solve_tsp,
    tour_length,
)
from planners.power_split import from_scenario, split_value_rate
from swiptopt import Box, Scenario, Sphere
from swiptopt.link import link_budget, reward_references

plt.rcParams.update({"figure.dpi": 90, "axes.grid": True, "grid.alpha": 0.3})
scenario = Scenario.preset("paper", n_nodes=N_NODES, layout_seed=SEED)
print(f"quick settings: {QUICK}")

# %% [markdown]
# ## 1. Hover points by k-means
#
# With `k=None` the smallest K is chosen for which every group fits one coverage
# footprint: one hover cell covers all of its nodes. Nodes that no cell can cover are
# left out (label −1).

# %%
hover = kmeans_hover_points(scenario, rng=SEED)
nodes_m = scenario.layout.positions_m
hover_m = scenario.cell_centers_m[hover.cells]
print(f"K = {hover.k} hover points cover {hover.covered.any(axis=0).sum()} of {scenario.n_nodes} nodes; "
      f"uncoverable: {(hover.labels < 0).sum()}")

fig, (ax_top, ax_side) = plt.subplots(1, 2, figsize=(12, 5))
colours = plt.cm.tab10(np.arange(hover.k) % 10)
for g in range(hover.k):
    members = nodes_m[hover.covered[g]]
    for ax, (i, j) in ((ax_top, (0, 1)), (ax_side, (0, 2))):
        for node in members:
            ax.plot([hover_m[g, i], node[i]], [hover_m[g, j], node[j]], color=colours[g], lw=0.6, alpha=0.6)
        ax.scatter(nodes_m[hover.labels == g, i], nodes_m[hover.labels == g, j], color=colours[g], s=25)
        ax.scatter(hover_m[g, i], hover_m[g, j], marker="*", s=250, color=colours[g], edgecolor="k")
for ax in (ax_top, ax_side):
    ax.scatter(*nodes_m[hover.labels < 0][:, [0, 1 if ax is ax_top else 2]].T, color="0.6", s=25, label="uncoverable")
    ax.set_xlim(0, scenario.length_m)
    ax.set_xlabel("x (m)")
ax_top.set_ylim(0, scenario.width_m)
ax_top.set_ylabel("y (m)")
ax_top.set_title("top view: groups (colours), hover cells (stars)")
ax_side.set_ylim(scenario.depth_m, 0)
ax_side.set_ylabel("depth (m)")
ax_side.set_title("side view: hover cells sit above their nodes")
fig.tight_layout()

# %% [markdown]
# ## 2. A TSP tour over the hover points
#
# Distances between the start cell and the hover cells in 3D. `solve_tsp` uses CP-SAT
# (a proof of optimality) on small instances and OR-Tools routing with guided local
# search on large ones. Each search stops on a budget of work (CP-SAT's deterministic
# time, a number of routing solutions), not of seconds, so the order is the same on any
# machine; the result reports whether it is proven optimal. A closed tour returns to the
# start; an open path ends at the last hover point.

# %%
start_m = scenario.cell_centers_m[scenario.start_cell_index]
stops_m = np.vstack([start_m, hover_m])
distance_m = np.linalg.norm(stops_m[:, None, :] - stops_m[None, :, :], axis=-1)
tour = solve_tsp(distance_m, start=0, closed=True)
path = solve_tsp(distance_m, start=0, closed=False)
for name, result in (("closed tour", tour), ("open path", path)):
    if not result.order:
        raise RuntimeError(f"{name}: no solution ({result.status})")
    print(f"{name:11s}: {result.length:6.1f} m, status {result.status}, proven optimal {result.proven_optimal}, "
          f"method {result.method}, {result.solve_time_s:.2f} s")
shuffled = [0, *np.random.default_rng(SEED).permutation(np.arange(1, len(stops_m)))]
print(f"a random order of the same stops: {tour_length(distance_m, shuffled, closed=True):.1f} m (closed)")

fig = plt.figure(figsize=(13, 5))
ax2d = fig.add_subplot(1, 2, 1)
ax3d = fig.add_subplot(1, 2, 2, projection="3d")
closed_m = stops_m[list(tour.order) + [tour.order[0]]]
open_m = stops_m[list(path.order)]
ax2d.plot(closed_m[:, 0], closed_m[:, 1], "-", color="tab:blue", label=f"closed tour, {tour.length:.0f} m")
ax2d.plot(open_m[:, 0], open_m[:, 1], "--", color="tab:red", label=f"open path, {path.length:.0f} m")
ax2d.scatter(nodes_m[:, 0], nodes_m[:, 1], s=10, color="0.5", label="nodes")
ax2d.scatter(hover_m[:, 0], hover_m[:, 1], marker="*", s=150, color="tab:orange", edgecolor="k", label="hover points")
ax2d.scatter(*start_m[:2], marker="^", s=120, color="k", label="start")
for rank, stop in enumerate(tour.order[1:], start=1):
    ax2d.annotate(str(rank), stops_m[stop, :2], textcoords="offset points", xytext=(6, 6), fontsize=8)
ax2d.set_xlim(0, scenario.length_m)
ax2d.set_ylim(0, scenario.width_m)
ax2d.set_xlabel("x (m)")
ax2d.set_ylabel("y (m)")
ax2d.set_title("top view (numbers: visiting order of the tour)")
ax2d.legend(fontsize=7, loc="lower left")

ax3d.plot(*closed_m.T, "-", color="tab:blue")
ax3d.scatter(*nodes_m.T, s=8, color="0.5")
ax3d.scatter(*hover_m.T, marker="*", s=120, color="tab:orange", edgecolor="k")
ax3d.scatter(*start_m, marker="^", s=100, color="k")
ax3d.set_xlim(0, scenario.length_m)
ax3d.set_ylim(0, scenario.width_m)
ax3d.set_zlim(scenario.depth_m, 0)
ax3d.set_box_aspect(scenario.extent_m)  # metres equal on every axis
ax3d.set_xlabel("x (m)")
ax3d.set_ylabel("y (m)")
ax3d.set_zlabel("depth (m)")
ax3d.set_title("the closed tour in 3D")
fig.tight_layout()


# %% [markdown]
# ## 3. OMPL paths around obstacles
#
# `plan_path_3d` runs OMPL in a 3D real-vector space over the scenario's volume with a
# validity checker for its boxes, spheres and seabed, always under a time limit, and
# reports whether the path is exact. The seed is OMPL's process-wide seed: set once, on
# the first call, and the same on every later call. The default planner (Informed RRT*)
# is anytime and stops at the wall-clock limit, so path lengths can differ slightly from
# run to run even with a seed.
#
# In the harbour each trip is planned twice: for the shortest path and for the
# least AUV energy (`objective="energy"`, Informed RRT*), which accounts for the tidal
# current that weakens with depth. Both are anytime planners cut off at the time limit;
# with the short limits of the quick settings the energy planner may not yet beat the
# shortest path even on energy, as the printed numbers show.
#
# Each path is checked here against the scenario's own obstacle test
# (`Scenario.is_blocked`) at points every 0.1 m along its segments.

# %%
def densify(waypoints_m, step_m=0.1):
    # points every step_m along a polyline (k, 3)
    pieces = [np.linspace(a, b, max(2, int(np.ceil(np.linalg.norm(b - a) / step_m)) + 1))
              for a, b in zip(waypoints_m[:-1], waypoints_m[1:])]
    return np.vstack(pieces)

def check(result, scenario_, start, goal):
    if not result.exact:
        print(f"  {result.planner}: no exact path within the limit ({result.status})")
        return
    clear = not scenario_.is_blocked(densify(result.waypoints)).any()
    print(f"  {result.planner}, objective {result.objective}: {result.status}, {result.length_m:.1f} m "
          f"(straight line {np.linalg.norm(np.subtract(goal, start)):.1f} m), {len(result.waypoints)} waypoints, "
          f"AUV energy {result.energy_j / 1e3:.2f} kJ, collision-free: {clear}")
    assert clear

def sphere_mesh(sphere, n=16):
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n), np.linspace(0, np.pi, n))
    c, r = sphere.center_m, sphere.radius_m
    return c[0] + r * np.cos(u) * np.sin(v), c[1] + r * np.sin(u) * np.sin(v), c[2] + r * np.cos(v)

def box_edges(box):
    lo, hi = np.asarray(box.min_m), np.asarray(box.max_m)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return [(corners[i], corners[j]) for i in range(8) for j in range(i + 1, 8)
            if np.count_nonzero(corners[i] != corners[j]) == 1]

def draw_obstacles(ax, scenario_, depth_exaggeration=1.0):
    for obstacle in scenario_.obstacles:
        if isinstance(obstacle, Sphere):
            ax.plot_wireframe(*sphere_mesh(obstacle), color="0.5", lw=0.5)
        elif isinstance(obstacle, Box):
            for a, b in box_edges(obstacle):
                ax.plot(*np.stack([a, b]).T, color="0.3", lw=1)
    if scenario_.seabed_height_m is not None:
        gx, gy = np.meshgrid(np.linspace(0, scenario_.length_m, 12), np.linspace(0, scenario_.width_m, 12))
        ax.plot_surface(gx, gy, scenario_.seabed_depth_m(gx, gy), color="tan", alpha=0.3)
    ax.set_xlim(0, scenario_.length_m)
    ax.set_ylim(0, scenario_.width_m)
    ax.set_zlim(scenario_.depth_m, 0)
    ax.set_box_aspect(scenario_.extent_m * (1.0, 1.0, depth_exaggeration))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("depth (m)")

# a sphere in open water
rock = Sphere(center_m=(50.0, 50.0, 25.0), radius_m=18.0)
open_water = Scenario.preset("paper", obstacles=(rock,))
a, b = (8.0, 50.0, 25.0), (92.0, 50.0, 25.0)
around_rock = plan_path_3d(a, b, open_water, time_limit_s=OMPL_TIME_LIMIT_S, seed=OMPL_SEED)
print("sphere:")
check(around_rock, open_water, a, b)

# the harbour: around the pier, and past the moored hull, by length and by AUV energy
harbour = Scenario.preset("harbour")
trips = {"around the pier": ((30.0, 60.0, 20.0), (30.0, 140.0, 20.0)),
         "past the hull": ((100.0, 50.0, 4.0), (180.0, 50.0, 4.0))}
harbour_paths = {}
for trip, (start, goal) in trips.items():
    print(f"harbour, {trip}:")
    for objective in ("length", "energy"):
        result = plan_path_3d(start, goal, harbour, objective=objective, time_limit_s=OMPL_TIME_LIMIT_S, seed=OMPL_SEED)
        check(result, harbour, start, goal)
        harbour_paths[trip, objective] = result

# %%
fig = plt.figure(figsize=(19, 5.5))
ax_rock = fig.add_subplot(1, 3, 1, projection="3d")
draw_obstacles(ax_rock, open_water)
if around_rock.exact:
    ax_rock.plot(
        *around_rock.waypoints.T, "o-", color="tab:red", ms=3, label=f"OMPL path, {around_rock.length_m:.0f} m"
    )
ax_rock.plot(*np.stack([a, b]).T, "k:", label="straight line (blocked)")
ax_rock.set_title("around a sphere")
ax_rock.legend(fontsize=8)

ax_harbour = fig.add_subplot(1, 3, 2, projection="3d")
draw_obstacles(ax_harbour, harbour, depth_exaggeration=2.5)
ax_top = fig.add_subplot(1, 3, 3)
for obstacle in harbour.obstacles:
    if isinstance(obstacle, Box):
        (x0, y0, z0), (x1, y1, z1) = obstacle.min_m, obstacle.max_m
        ax_top.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, color="0.6", alpha=0.6))
        ax_top.annotate(f"depth {z0:g}-{z1:g} m", (x0, y1), textcoords="offset points", xytext=(2, 3), fontsize=7)
    elif isinstance(obstacle, Sphere):
        (cx, cy, cz), r = obstacle.center_m, obstacle.radius_m
        ax_top.add_patch(plt.Circle((cx, cy), r, color="0.6", alpha=0.6))
        ax_top.annotate(f"wreck, top at {cz - r:g} m", (cx - r, cy + r), textcoords="offset points", xytext=(0, 3),
                        fontsize=7)
styles = {"length": "-", "energy": "--"}
colours = dict(zip(trips, ("tab:red", "tab:blue")))
for (trip, objective), result in harbour_paths.items():
    if result.exact:
        label = f"{trip}, min {objective}: {result.length_m:.0f} m, {result.energy_j / 1e3:.2f} kJ"
        ax_harbour.plot(*result.waypoints.T, styles[objective], color=colours[trip], lw=2, label=label)
        ax_top.plot(*result.waypoints[:, :2].T, styles[objective], color=colours[trip], lw=2, label=label)
current = harbour.current_mps
ax_top.annotate("", xy=(185 + 40 * current[0], 15 + 40 * current[1]), xytext=(185, 15),
                arrowprops={"arrowstyle": "->", "color": "tab:cyan", "lw": 2})
ax_top.annotate("surface current", (150, 5), fontsize=7, color="tab:cyan")
ax_harbour.set_title("the harbour preset (depth exaggerated 2.5 x)")
ax_top.set_xlim(0, harbour.length_m)
ax_top.set_ylim(0, harbour.width_m)
ax_top.set_aspect("equal")
ax_top.set_xlabel("x (m)")
ax_top.set_ylabel("y (m)")
ax_top.set_title("the harbour from above (obstacles grey)")
ax_top.legend(fontsize=7, loc="lower left")
fig.tight_layout(w_pad=4)

# %% [markdown]
# ## 4. The power-split trade-off
#
# Serving a node with split ratio α for one second earns
# Γ · B log2(1 + α γ) / D_ref + (1 − Γ) · η (1 − α) P_av / E_ref (the reward's weighting,
# linear harvester). It is concave in α, and its maximiser has a closed form:
# α* = clip(Γ B E_ref / (ln 2 (1 − Γ) η P_av D_ref) − 1/γ, 0, 1). With a 1 kW
# projector γ is huge, so α* depends on the ratio of the information weight to the
# harvestable power: far nodes, which harvest little, get more of the signal for data.

# %%
refs = reward_references(scenario)
distances_m = np.linspace(2.0, scenario.cone_range_m, GRID_POINTS)
weights = np.linspace(0.0, 1.0, GRID_POINTS)
budget = link_budget(scenario, distances_m)
snr = 10.0 ** (budget.snr_db / 10.0)
model = dict(bandwidth_hz=scenario.bandwidth_hz, efficiency=scenario.harvest_efficiency,
             data_ref_bits=refs.data_ref_bits, energy_ref_j=refs.energy_ref_j)
alpha_star = np.array([optimal_split_ratio(snr, budget.available_power_w, reward_weight=w, **model) for w in weights])

fig, (ax_map, ax_lines, ax_rate) = plt.subplots(1, 3, figsize=(16, 4.3))
mesh = ax_map.pcolormesh(distances_m, weights, alpha_star, shading="auto", cmap="viridis", vmin=0, vmax=1)
contours = ax_map.contour(
    distances_m, weights, alpha_star, levels=[0.1, 0.25, 0.5, 0.75, 0.9], colors="w", linewidths=0.8
)
ax_map.clabel(contours, fontsize=7)
ax_map.set_xlabel("distance AUV to node (m)")
ax_map.set_ylabel("reward weight Gamma (-)")
fig.colorbar(mesh, ax=ax_map, label="optimal split ratio alpha* (-)")

for d in (5.0, 10.0, 20.0, 40.0):
    at_d = link_budget(scenario, d)
    line = [float(optimal_split_ratio(10.0 ** (at_d.snr_db / 10.0), at_d.available_power_w, reward_weight=w, **model))
            for w in weights]
    ax_lines.plot(weights, line, label=f"{d:g} m")
ax_lines.set_xlabel("reward weight Gamma (-)")
ax_lines.set_ylabel("optimal split ratio alpha* (-)")
ax_lines.legend(fontsize=8, title="distance")

# the closed form against a brute-force grid, one node at 10 m
alphas = np.linspace(0.0, 1.0, 2001)
at_10 = link_budget(scenario, 10.0)
snr_10 = 10.0 ** (at_10.snr_db / 10.0)
for w in (0.3, 0.5, 0.7):
    rate = split_value_rate(alphas, snr_10, at_10.available_power_w, reward_weight=w, **model)
    best = float(optimal_split_ratio(snr_10, at_10.available_power_w, reward_weight=w, **model))
    line = ax_rate.plot(alphas, rate, label=f"Gamma = {w}")[0]
    ax_rate.plot(best, split_value_rate(best, snr_10, at_10.available_power_w, reward_weight=w, **model), "o",
                 color=line.get_color())
    print(f"Gamma = {w}: closed form alpha* = {best:.4f}, grid argmax = {alphas[np.argmax(rate)]:.4f}")
ax_rate.set_xlabel("split ratio alpha (-)")
ax_rate.set_ylabel("value rate, node at 10 m (1/s)")
ax_rate.legend(fontsize=8)
fig.tight_layout()

# %% [markdown]
# ## 5. Dwell times and split ratios at several hover points
#
# The joint program: a dwell time t_k at each hover point and a split α_ik for every
# covered node, maximising the same weighted value under a mission-time budget, with
# each node's data and storage room as caps. The bits are written in perspective form
# so the problem is convex (exponential cone, solved by cvxpy). `from_scenario` builds
# the inputs for a scenario and its hover cells; the result carries the solver status,
# and arrays only when the solve succeeded.
#
# With link SNRs of 80-100 dB a split of 10⁻⁴ of the signal already carries tens of
# kbit/s, so the program sends almost everything to the harvester: the split ratios are
# drawn on a log scale.

# %%
small = Scenario.preset("paper", n_nodes=8, layout_seed=SEED + 1, episode_steps=20)
small_hover = kmeans_hover_points(small, rng=SEED)
inputs = from_scenario(small, small_hover.cells)
result = optimise_dwell_and_split(**inputs.as_kwargs())
print(f"{small_hover.k} hover points, {small.n_nodes} nodes, budget {inputs.mission_time_s:.0f} s: "
      f"status {result.status}, solver {result.solver}, {result.solve_time_s:.2f} s")
if not result.ok:
    raise RuntimeError(f"the dwell/split program did not solve: {result.status}")
print(f"objective {result.objective:.3f}; total dwell {result.dwell_s.sum():.1f} s")

fig, (ax_dwell, ax_split, ax_nodes) = plt.subplots(1, 3, figsize=(16, 4.3),
                                                   gridspec_kw={"width_ratios": [1, 1.4, 1.6]})
ax_dwell.bar(np.arange(small_hover.k), result.dwell_s)
ax_dwell.set_xticks(np.arange(small_hover.k))
ax_dwell.set_xlabel("hover point (-)")
ax_dwell.set_ylabel("dwell time (s)")

served_split = result.split_ratio[np.isfinite(result.split_ratio)]
print(f"split ratios of the served pairs: {served_split.min():.2g} .. {served_split.max():.2g}")
# with link SNRs of 80-100 dB a tiny share of the signal carries the data: log colours
image = ax_split.imshow(np.ma.masked_invalid(np.maximum(result.split_ratio, 1e-9)), aspect="auto", cmap="viridis",
                        norm=LogNorm(vmin=max(1e-9, served_split.min()), vmax=1.0))
ax_split.set_xlabel("node (-)")
ax_split.set_ylabel("hover point (-)")
ax_split.set_yticks(np.arange(small_hover.k))
ax_split.grid(False)
fig.colorbar(image, ax=ax_split, label="split ratio alpha (-, log scale), blank: not served")

idx = np.arange(small.n_nodes)
ax_nodes.bar(idx - 0.2, result.bits.sum(axis=0) / 1e3, 0.4, label="data collected (kbit)")
ax_nodes.bar(idx + 0.2, result.energy_j.sum(axis=0) * 1e3, 0.4, label="energy delivered (mJ)")
ax_nodes.plot(idx - 0.2, inputs.data_bits / 1e3, "k_", ms=14, label="data cap (kbit)")
ax_nodes.plot(idx + 0.2, inputs.storage_room_j * 1e3, "r_", ms=14, label="storage room (mJ)")
for i in np.flatnonzero(~inputs.coverage_mask.any(axis=0)):
    ax_nodes.annotate("not covered", (i, 0), textcoords="offset points", xytext=(0, 4), ha="center",
                      rotation=90, fontsize=7)
ax_nodes.set_xticks(idx)
ax_nodes.set_xlabel("node (-)")
ax_nodes.set_ylabel("data (kbit) / energy (mJ)")
ax_nodes.legend(fontsize=7)
fig.tight_layout()

# %% [markdown]
# The program is built once with cvxpy `Parameter`s (DPP), so a sweep over the
# mission-time budget re-solves without rebuilding. The value grows with the budget
# and flattens once every cap binds.

# %%
problem = DwellSplitProblem(inputs.coverage_mask)
budgets_s = np.linspace(0.05, 3.0, BUDGET_POINTS) * inputs.mission_time_s  # up to 3 episodes of dwell
values, used = [], []
for budget_s in budgets_s:
    r = problem.solve(**{**inputs.as_kwargs(), "mission_time_s": float(budget_s)})
    values.append(r.objective if r.ok else np.nan)
    used.append(r.dwell_s.sum() if r.ok else np.nan)
    if not r.ok:
        print(f"budget {budget_s:.0f} s: {r.status}")

fig, ax = plt.subplots(figsize=(7, 4))
ax.plot(budgets_s, values, "o-", label="optimal value")
ax.set_xlabel("mission-time budget (s)")
ax.set_ylabel("weighted value (-)")
ax_used = ax.twinx()
ax_used.plot(budgets_s, used, "s--", color="tab:orange", label="dwell used")
ax_used.set_ylabel("total dwell used (s), dashed")
ax_used.grid(False)
ax.legend(loc="upper left", fontsize=8)
fig.tight_layout()
