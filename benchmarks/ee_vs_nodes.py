"""Why the paper's energy efficiency falls with the number of nodes and ours rises.

Runs, on the paper preset at the paper's data setting (Gamma = 1), the random trajectory
and the rate-greedy planner on layouts 0..L-1 for N in {10, 20, 30, 40, 50}, and prints per
N the data collected, the AUV's projector energy under each reading of "P_tau is the sum of
the transmission power from the AUV to node and the navigation power" (Section IV, on
Fig. 9), and the four efficiencies. With ``--outdir`` it draws the figure
docs/paper-fidelity.md shows: the efficiencies normalised to N = 10 (left) and the energies
behind them (right).

    PYTHONPATH=. python benchmarks/ee_vs_nodes.py --layouts 5 --outdir docs
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

# keep this folder off the path: the planners package must not be shadowed by a script here
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

NODES = (10, 20, 30, 40, 50)
READINGS = {
    "energy_efficiency_bit_per_j": "projector while serving",
    "energy_efficiency_always_on_bit_per_j": "projector every step",
    "energy_efficiency_per_node_bit_per_j": "projector per covered node (1 kW each)",
    "mobility_efficiency_bit_per_j": "motion only",
}


def measure(layouts: int, episodes: int) -> dict[str, dict[int, dict[str, float]]]:
    from planners.rate_greedy import RateGreedyPlanner
    from rl import RandomAgent
    from swiptopt import Scenario, evaluate
    from swiptopt.env import AuvSwiptEnv
    from swiptopt.link import auv_power

    out: dict[str, dict[int, dict[str, float]]] = {"random": {}, "rate_greedy": {}}
    for n in NODES:
        for name in out:
            rows = []
            for layout in range(layouts):
                scenario = Scenario.preset("paper", n_nodes=n, layout_seed=layout, reward_weight=1.0)
                env = AuvSwiptEnv(scenario)
                policy = RandomAgent(seed=layout) if name == "random" else RateGreedyPlanner()
                step_j = auv_power(scenario).projector_energy_j
                for r in evaluate(policy, env, episodes, seed=layout).records:
                    motion = r["auv_propulsion_j"] + r["auv_hotel_j"]
                    per_node_projector = (
                        r["data_bits"] / r["energy_efficiency_per_node_bit_per_j"] - motion
                        if r["data_bits"] else np.nan
                    )
                    rows.append({
                        "data_bits": r["data_bits"],
                        "motion_j": motion,
                        "projector_serving_j": r["auv_projector_j"],
                        "projector_always_j": step_j * r["length"],
                        "projector_per_node_j": per_node_projector,
                        **{k: r[k] for k in READINGS},
                    })
            out[name][n] = {k: float(np.nanmean([row[k] for row in rows])) for k in rows[0]}
    return out


def draw(results: dict, outdir: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(7.2, 2.8), constrained_layout=True)
    for name, style in (("rate_greedy", "-"), ("random", "--")):
        per_n = results[name]
        for metric, label in READINGS.items():
            values = np.array([per_n[n][metric] for n in NODES])
            left.plot(NODES, values / values[0], style, marker="o", ms=3, label=f"{label} ({name})")
        for key, label in (("data_bits", "data (bit)"), ("projector_per_node_j", "projector, per covered node (J)"),
                           ("projector_serving_j", "projector while serving (J)"), ("motion_j", "motion (J)")):
            values = np.array([per_n[n][key] for n in NODES])
            right.plot(NODES, values / values[0], style, marker="o", ms=3, label=f"{label} ({name})")
    left.set(xlabel="nodes N", ylabel="efficiency / its value at N = 10", title="energy efficiency readings")
    right.set(xlabel="nodes N", ylabel="value / its value at N = 10", title="what they divide")
    for ax in (left, right):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=4.5)
    outdir.mkdir(parents=True, exist_ok=True)
    path = outdir / "fig-efficiency-readings.png"
    fig.savefig(path, dpi=160)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layouts", type=int, default=5)
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--outdir", type=Path, default=None)
    args = parser.parse_args()
    results = measure(args.layouts, args.episodes)
    for name, per_n in results.items():
        print(f"\n{name} (Gamma = 1, paper preset, {args.layouts} layouts x {args.episodes} episodes)")
        header = [
            "N", "data kbit", "motion kJ", "proj. serving kJ", "proj. per node kJ",
            *[k.replace("_bit_per_j", "") for k in READINGS],
        ]
        print(" | ".join(header))
        for n in NODES:
            v = per_n[n]
            print(" | ".join([
                str(n), f"{v['data_bits'] / 1e3:.0f}", f"{v['motion_j'] / 1e3:.1f}",
                f"{v['projector_serving_j'] / 1e3:.0f}",
                f"{v['projector_per_node_j'] / 1e3:.0f}", *[f"{v[k]:.3g}" for k in READINGS],
            ]))
    if args.outdir is not None:
        print(f"\nfigure -> {draw(results, args.outdir)}")


if __name__ == "__main__":
    main()
