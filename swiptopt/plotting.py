"""Drawing the world: obstacles, seabed, nodes and paths in a top view and a depth view.

matplotlib is imported by the caller (it owns the figure); this module only draws on the
axes it is given, so ``import swiptopt`` stays free of it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from swiptopt.scenario import Box, Scenario, Sphere


def draw_world(scenario: Scenario, top: Any, side: Any, paths: Mapping[str, np.ndarray] = {}) -> None:
    """Draw ``scenario``'s obstacles and nodes on ``top`` (x, y) and ``side`` (x, depth)
    matplotlib axes, with each of ``paths`` (label -> (k, 3) positions, m) as a line."""
    from matplotlib.patches import Circle, Rectangle

    nodes = scenario.layout.positions_m
    # the depth view projects every obstacle across the width: lighter, so that paths beside
    # them (at other y) stay visible through them
    for ax, j, ylabel, alpha in ((top, 1, "y (m)", 1.0), (side, 2, "depth (m)", 0.4)):
        for obstacle in scenario.obstacles:
            if isinstance(obstacle, Box):
                lo, hi = obstacle.min_m, obstacle.max_m
                ax.add_patch(
                    Rectangle((lo[0], lo[j]), hi[0] - lo[0], hi[j] - lo[j], color="0.6", alpha=alpha, zorder=1)
                )
            elif isinstance(obstacle, Sphere):
                c = obstacle.center_m
                ax.add_patch(Circle((c[0], c[j]), obstacle.radius_m, color="0.6", alpha=alpha, zorder=1))
        ax.scatter(nodes[:, 0], nodes[:, j], s=14, c="tab:blue", zorder=3, label="nodes")
        for k, (label, path) in enumerate(paths.items()):
            path = np.asarray(path, dtype=float).reshape(-1, 3)
            ax.plot(path[:, 0], path[:, j], "-", lw=1.3, color=f"C{k + 1}", zorder=4, label=label)
            if len(path):
                ax.scatter(path[:1, 0], path[:1, j], marker="^", s=50, color=f"C{k + 1}", zorder=5)
        ax.set_xlim(0, scenario.length_m)
        ax.set_xlabel("x (m)")
        ax.set_ylabel(ylabel)
    top.set_ylim(0, scenario.width_m)
    top.set_aspect("equal")
    top.set_title("top view")
    x = np.linspace(0, scenario.length_m, 200)
    mid_y = np.full_like(x, scenario.width_m / 2)
    side.fill_between(x, scenario.seabed_depth_m(x, mid_y), scenario.depth_m, color="tan", zorder=0)
    side.set_ylim(scenario.depth_m, 0)
    side.set_title("depth view (obstacles projected across y; seabed at mid-width)")
