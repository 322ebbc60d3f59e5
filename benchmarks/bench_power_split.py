"""Time of the power-split planners: the closed form, a cvxpy build + solve, a DPP re-solve,
and the linear program with the split fixed (on the same instance and on a large one).

All run in this one process, interleaved over the repeats so they see the same machine
load; the median of each is reported, with the ratios, after the machine. The program's
instance is the ``paper`` scenario with one hover cell a level above each of the first
``--hover`` nodes; each re-solve draws new values for the same coverage pattern (3 dB
log-normal shadowing on SNR and power, a random share of the data already collected). The
large instance: ``--large-nodes`` nodes and a hover cell above each of the first
``--large-hover``. Usage:

    python benchmarks/bench_power_split.py [--closed-form-nodes 100000] [--nodes 50] [--hover 10] [--repeats 7]
        [--large-nodes 1000] [--large-hover 300]
"""

from __future__ import annotations

import sys
from pathlib import Path

# keep this folder off the path: the planners package must not be shadowed by a script here
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import argparse
import importlib.util
import statistics
import time
from typing import Any

import numpy as np

from planners import power_split as ps
from swiptopt.scenario import Scenario


def hover_cells_above_nodes(scenario: Scenario, count: int) -> list[int]:
    """One cell a level above each node (deduplicated), for the first ``count`` distinct cells."""
    cells: list[int] = []
    for x, y, z in scenario.layout.positions_m:
        c = scenario.cell_size_m
        cell = (int(x // c), int(y // c), max(int(z // c) - 1, 0))
        index = int(scenario.cell_index(cell))
        if index not in cells:
            cells.append(index)
        if len(cells) == count:
            break
    return cells


def perturbed(base: dict[str, Any], rng: np.random.Generator) -> dict[str, Any]:
    """The same problem with new channel values and remaining data (same coverage)."""
    shape = base["snr_linear"].shape
    shadow = 10.0 ** (rng.normal(0.0, 3.0, shape) / 10.0)
    return {
        **base,
        "snr_linear": base["snr_linear"] * shadow,
        "available_power_w": base["available_power_w"] * shadow,
        "data_bits": base["data_bits"] * rng.uniform(0.2, 1.0, base["data_bits"].shape),
    }


def timed(fn) -> tuple[float, Any]:  # type: ignore[no-untyped-def]
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--closed-form-nodes", type=int, default=100_000)
    parser.add_argument("--nodes", type=int, default=50)
    parser.add_argument("--hover", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--large-nodes", type=int, default=1000)
    parser.add_argument("--large-hover", type=int, default=300)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)

    scenario = Scenario.preset("paper", n_nodes=args.nodes)
    inputs = ps.from_scenario(scenario, hover_cells_above_nodes(scenario, args.hover))
    base = inputs.as_kwargs()
    model = {k: base[k] for k in ("reward_weight", "bandwidth_hz", "efficiency", "data_ref_bits", "energy_ref_j")}
    # many nodes for the closed form: the program's links, tiled and shadowed
    covered = inputs.coverage_mask
    n = args.closed_form_nodes
    pick = rng.integers(0, int(covered.sum()), n)
    shadow = 10.0 ** (rng.normal(0.0, 3.0, n) / 10.0)
    snr_many = inputs.snr_linear[covered][pick] * shadow
    p_many = inputs.available_power_w[covered][pick] * shadow

    large_scenario = Scenario.preset("paper", n_nodes=args.large_nodes)
    large = ps.from_scenario(large_scenario, hover_cells_above_nodes(large_scenario, args.large_hover)).as_kwargs()
    large_pairs = int((large["available_power_w"] > 0).sum())
    alpha = scenario.split_ratio

    built = ps.DwellSplitProblem(covered)
    built.solve(**base)  # the first solve canonicalises; re-solves below reuse it
    ps.optimal_split_ratio(snr_many, p_many, **model)  # warm up
    times: dict[str, list[float]] = {"closed": [], "build": [], "resolve": [], "lp": [], "lp_large": []}
    statuses: list[str] = []
    for _ in range(args.repeats):
        values = perturbed(base, rng)
        t, _ = timed(lambda: ps.optimal_split_ratio(snr_many, p_many, **model))
        times["closed"].append(t)
        t, fresh = timed(lambda values=values: ps.optimise_dwell_and_split(**values))
        times["build"].append(t)
        t, again = timed(lambda values=values: built.solve(**values))
        times["resolve"].append(t)
        t, fixed = timed(lambda values=values: ps.optimise_dwell_and_split(**values, split_ratio=alpha))
        times["lp"].append(t)
        t, fixed_large = timed(lambda: ps.optimise_dwell_and_split(**large, split_ratio=alpha))
        times["lp_large"].append(t)
        statuses += [fresh.status, again.status, fixed.status, fixed_large.status]
    med = {k: statistics.median(v) for k, v in times.items()}
    k, pairs = covered.shape[0], int(covered.sum())
    solver = fresh.solver
    spec = importlib.util.spec_from_file_location("machine", Path(__file__).resolve().parent / "machine.py")
    machine = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(machine)
    print(machine.describe())
    print(f"power split timings, median of {args.repeats} (statuses: {sorted(set(statuses))}, solver {solver})")
    rows = [
        (f"closed form, {n:,} nodes", med["closed"]),
        (f"cvxpy build + solve, {k} hover x {args.nodes} nodes ({pairs} covered pairs)", med["build"]),
        ("cvxpy re-solve of the built problem (DPP)", med["resolve"]),
        (f"split fixed at {alpha:g}: linear program (HiGHS), same instance", med["lp"]),
        (f"split fixed: linear program, {args.large_hover} hover x {args.large_nodes} nodes ({large_pairs} pairs)",
         med["lp_large"]),
    ]
    width = max(len(label) for label, _ in rows)
    for label, seconds in rows:
        print(f"  {label:<{width}}  {seconds * 1e3:9.3f} ms")
    print(f"  ratio build+solve / re-solve:    {med['build'] / med['resolve']:8.2f}")
    print(f"  ratio build+solve / closed form: {med['build'] / med['closed']:8.1f}")
    print(f"  ratio re-solve / closed form:    {med['resolve'] / med['closed']:8.1f}")
    print(f"  ratio build+solve / fixed-split LP: {med['build'] / med['lp']:5.1f}")


if __name__ == "__main__":
    main()
