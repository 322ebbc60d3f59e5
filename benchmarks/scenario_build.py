"""Time and peak memory of building a scenario's tables, beside the dense construction it replaced.

Each measurement runs in a fresh process (peak memory is per process): the scenario, then

- ``tables``: :func:`swiptopt.kernel.build_tables` (coverage from each node's cone, only the
  covered pairs in memory);
- ``env + bound``: the environment and :func:`planners.upper_bound` on its tables (shared,
  as the benchmark runner does);
- ``dense reference``: the construction as it was, written out here: the cone test and the
  link budget over the full cells x nodes matrices, the harvester called once per pair
  through ``np.frompyfunc`` (skip it with ``--no-reference``: at 2.5 m and 1000 nodes it
  needs minutes and GiBs).

Peak memory is the process's peak resident set above what it held after the imports. The
machine is printed first; the ratios are measured in this one run. Usage:

    python benchmarks/scenario_build.py [--cell 2.5] [--nodes 1000] [--no-reference]
"""

from __future__ import annotations

import sys
from pathlib import Path

# keep this folder off the path: the planners package must not be shadowed by a script here
HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != HERE]

import argparse
import importlib.util
import json
import resource
import subprocess
import time

STAGES = ("tables", "env + bound", "dense reference")


def dense_reference(scenario) -> int:  # type: ignore[no-untyped-def]
    """The coverage part of the tables as first built: every cell against every node."""
    import numpy as np

    from swiptopt import harvesting
    from swiptopt.coverage import cone_mask, slant_distances_m
    from swiptopt.link import link_budget

    # the per-pair harvester of that construction
    harvesting._harvest_array = lambda *args: np.asarray(
        np.frompyfunc(harvesting.harvest_from_input_w, 6, 1)(*args), dtype=float
    )[()]
    centres, nodes = scenario.cell_centers_m, scenario.layout.positions_m
    covered = cone_mask(centres, nodes, scenario.cone_half_angle_deg, scenario.cone_range_m)
    covered &= link_budget(scenario, slant_distances_m(centres, nodes)).in_service
    covered &= ~scenario.blocked_cells[:, None]
    rows, cols = np.nonzero(covered)
    link_budget(scenario, slant_distances_m(centres, nodes)[rows, cols])
    return int(rows.size)


def measure(stage: str, cell_m: float, nodes: int) -> dict[str, float]:
    """Run one stage in this process; seconds, peak MiB over the imports, covered pairs."""
    from planners.bounds import upper_bound
    from swiptopt import kernel as K
    from swiptopt.env import AuvSwiptEnv
    from swiptopt.scenario import Scenario

    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    start = time.perf_counter()
    scenario = Scenario.preset("paper", cell_size_m=cell_m, n_nodes=nodes)
    if stage == "tables":
        pairs = int(K.build_tables(scenario).cov_node.size)
    elif stage == "env + bound":
        env = AuvSwiptEnv(scenario)
        upper_bound(scenario, env.tables)
        pairs = int(env.tables.cov_node.size)
    else:
        pairs = dense_reference(scenario)
    seconds = time.perf_counter() - start
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base  # KiB on Linux
    return {"seconds": seconds, "peak_mib": peak_kib / 1024, "pairs": pairs, "cells": scenario.n_cells}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cell", type=float, default=2.5, help="cell size, m")
    parser.add_argument("--nodes", type=int, default=1000)
    parser.add_argument("--no-reference", action="store_true", help="skip the dense construction")
    parser.add_argument("--stage", choices=STAGES, help=argparse.SUPPRESS)  # one measurement, in a child
    args = parser.parse_args()
    if args.stage:
        print(json.dumps(measure(args.stage, args.cell, args.nodes)))
        return

    spec = importlib.util.spec_from_file_location("machine", HERE / "machine.py")
    machine = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(machine)
    stages = STAGES[:2] if args.no_reference else STAGES
    results = {}
    for stage in stages:
        run = subprocess.run(
            [sys.executable, __file__, "--stage", stage, "--cell", str(args.cell), "--nodes", str(args.nodes)],
            capture_output=True, text=True, check=True,
        )
        results[stage] = json.loads(run.stdout)
    print(machine.describe())
    first = results["tables"]
    print(f"paper preset, {args.cell:g} m cells ({first['cells']:,} cells), {args.nodes:,} nodes, "
          f"{first['pairs']:,} covered pairs")
    for stage, r in results.items():
        print(f"  {stage:<16} {r['seconds']:8.2f} s   peak {r['peak_mib']:8.0f} MiB")
    if "dense reference" in results:
        ref = results["dense reference"]
        assert ref["pairs"] == first["pairs"], "the two constructions disagree on the covered pairs"
        print(f"  ratio dense reference / tables: time {ref['seconds'] / first['seconds']:.1f}, "
              f"peak memory {ref['peak_mib'] / max(first['peak_mib'], 1.0):.1f}")


if __name__ == "__main__":
    main()
