"""The speed-up of ``--workers 2`` (and a local Dask cluster) over one worker, on the built-in
experiment ``fig-efficiency-vs-nodes``.

Every run happens in this one process, into a fresh temporary store, so nothing is cached
between runs; the executors take turns within each repeat (so they see the same machine
load), and the median wall time of each is reported with the ratios to ``--workers 1``.
Target on a 2-core machine: ``--workers 2`` at least 1.7x one worker. Usage:

    python benchmarks/workers_speedup.py [--repeats 3] [--layouts 20] [--executors workers1,workers2,local2]

``--layouts`` shrinks the experiment (20 layouts: its 600 tasks; fewer for a quicker
look). Printed beside the result: the load average, and the speed-up two processes give a
plain CPU-bound loop before and after (2.0x on idle cores): when that control is well below
2, the machine is shared and the numbers are provisional.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
# keep this folder off the path: the planners package must not be shadowed by a script here
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != HERE]

from swiptopt.benchmark.experiment import builtin_experiments  # noqa: E402
from swiptopt.benchmark.runner import execute  # noqa: E402
from swiptopt.benchmark.store import ResultStore  # noqa: E402

EXECUTORS = {
    "workers1": {"workers": 1},
    "workers2": {"workers": 2},
    "local2": {"scheduler": "local:2"},
}


def timed_run(experiment, options: dict) -> float:  # type: ignore[no-untyped-def]
    """Seconds to run every task of ``experiment`` into a new store."""
    with tempfile.TemporaryDirectory() as tmp, ResultStore(Path(tmp) / "speedup.sqlite") as store:
        start = time.perf_counter()
        report = execute(experiment, store, **options)
        seconds = time.perf_counter() - start
    if report.ran != report.total or report.failures:
        raise SystemExit(f"the run did not complete: {report}")
    return seconds


def _burn(n: int) -> int:
    total = 0
    for i in range(n):
        total += i * i
    return total


def control_ratio(repeats: int, loops: int = 2_000_000, chunks: int = 8) -> float:
    """The speed-up two processes give a pure CPU-bound loop over one, right now: the
    ceiling the machine offers (below 2 when other work shares the cores)."""
    from concurrent.futures import ProcessPoolExecutor

    times: dict[int, list[float]] = {1: [], 2: []}
    for _ in range(repeats):
        for workers in (1, 2):
            with ProcessPoolExecutor(workers) as pool:
                start = time.perf_counter()
                list(pool.map(_burn, [loops] * chunks))
                times[workers].append(time.perf_counter() - start)
    return statistics.median(times[1]) / statistics.median(times[2])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--layouts", type=int, default=20)
    parser.add_argument("--executors", default=",".join(EXECUTORS))
    args = parser.parse_args()
    chosen = args.executors.split(",")
    unknown = [e for e in chosen if e not in EXECUTORS]
    if unknown or "workers1" not in chosen:
        raise SystemExit(f"--executors: a comma-separated choice of {', '.join(EXECUTORS)}, with workers1")

    experiment = dataclasses.replace(builtin_experiments()["fig-efficiency-vs-nodes"], layouts=args.layouts)
    tasks = len(experiment.tasks())
    timed_run(experiment.quick(), {"workers": 1})  # imports and compiled code, once, before timing
    control_before = control_ratio(args.repeats)
    load_before = os.getloadavg()
    times: dict[str, list[float]] = {e: [] for e in chosen}
    for r in range(args.repeats):
        for executor in chosen[r % len(chosen):] + chosen[: r % len(chosen)]:
            times[executor].append(timed_run(experiment, EXECUTORS[executor]))
            print(f"  repeat {r + 1}: {executor:<9} {times[executor][-1]:7.1f} s", flush=True)
    load_after = os.getloadavg()
    control_after = control_ratio(args.repeats)

    median = {e: statistics.median(t) for e, t in times.items()}
    print(f"fig-efficiency-vs-nodes, {tasks} tasks ({args.layouts} layouts), median of {args.repeats} runs, "
          f"{os.cpu_count()} cores ({platform.machine()}, Python {platform.python_version()})")
    print(f"  load average before {load_before[0]:.2f}, after {load_after[0]:.2f} (1 min); a CPU-bound loop in 2 "
          f"processes over 1, before and after: {control_before:.2f}x, {control_after:.2f}x (the machine's ceiling)")
    for executor in chosen:
        ratio = median["workers1"] / median[executor]
        print(f"  {executor:<9} {median[executor]:7.1f} s   speed-up over workers1: {ratio:.2f}x")


if __name__ == "__main__":
    main()
