"""Running an experiment's tasks: local worker processes or a Dask cluster.

A task builds the environment from its resolved scenario, builds (and, for RL, trains) the
policy with the task's seed, evaluates it with :func:`swiptopt.evaluate` on the task's
evaluation seeds, and returns per-episode records with the scenario's bounds. Everything a
task computes comes from its configuration and seed, so the numbers do not depend on where
it ran. Tasks go out in small batches; every finished task is committed to the store as
soon as its batch returns.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterator

from swiptopt.errors import ConfigError
from swiptopt.benchmark.experiment import EVALUATION_OFFSET, Experiment, Task
from swiptopt.benchmark.store import ResultStore


def run_task(task: dict[str, Any]) -> dict[str, Any]:
    """Run one task (a :meth:`Task.to_dict`); returns its result for the store."""
    from planners.bounds import EXACT_STATE_LIMIT, exact_optimum, exact_state_bound, upper_bound
    from swiptopt.benchmark.algorithms import build_policy
    from swiptopt.env import AuvSwiptEnv
    from swiptopt.evaluation import evaluate
    from swiptopt.scenario import Scenario

    start = time.perf_counter()
    t = Task(**task)
    scenario = Scenario.from_dict(t.scenario)
    env = AuvSwiptEnv(scenario)
    policy = build_policy(t.algorithm, env, t.settings, t.seed)
    result = evaluate(policy, env, t.episodes, seed=t.seed + EVALUATION_OFFSET)
    bound = upper_bound(scenario, env.tables)
    extra: dict[str, Any] = {"upper_bound_return": bound.return_}
    if scenario.name == "tiny" and scenario.channel == "none" and scenario.failure_prob_max == 0:
        # decided before running: the search's size is bounded from the scenario alone
        states = exact_state_bound(scenario, env.tables)
        if states <= EXACT_STATE_LIMIT:
            try:
                extra["optimum_return"] = exact_optimum(scenario, tables=env.tables).return_
            except ConfigError as exc:  # the search outgrew its bound (float rounding): a skip
                extra["optimum_skipped"] = str(exc)
        else:
            extra["optimum_skipped"] = (
                f"the exact optimum could explore up to {states:.3g} states, above the limit of "
                f"{EXACT_STATE_LIMIT:,} (planners.bounds.EXACT_STATE_LIMIT)"
            )
    return {
        "key": t.key,
        "task": task,
        "records": result.records,
        "extra": extra,
        "duration_s": time.perf_counter() - start,
    }


def run_batch(tasks: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Run tasks one after the other (a unit of work sent to a worker)."""
    return [run_task(t) for t in tasks]


def _batches(tasks: list[Task], workers: int) -> list[list[dict[str, Any]]]:
    # small batches: at least ~8 per worker for load balance, at most 4 tasks each so a
    # killed run loses little
    size = max(1, min(4, math.ceil(len(tasks) / max(1, workers * 8))))
    dicts = [t.to_dict() for t in tasks]
    return [dicts[i : i + size] for i in range(0, len(dicts), size)]


@dataclass(frozen=True)
class RunReport:
    """What a run did: tasks in the experiment, found already stored, and newly run."""

    total: int
    cached: int
    ran: int
    seconds: float


def _local(batches: list[list[dict[str, Any]]], workers: int) -> Iterator[list[dict[str, Any]]]:
    if workers <= 1:
        for batch in batches:
            yield run_batch(batch)
        return
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed

    # fork shares the imported model and numba's loaded code; spawn where fork is unsafe
    method = "fork" if "fork" in mp.get_all_start_methods() else "spawn"
    with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context(method)) as pool:
        futures = [pool.submit(run_batch, b) for b in batches]
        for future in as_completed(futures):
            yield future.result()


def _dask(batches: list[list[dict[str, Any]]], scheduler: str) -> Iterator[list[dict[str, Any]]]:
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise ConfigError("--scheduler needs dask.distributed: pip install 'swiptopt[bench]'", "scheduler") from None
    cluster = None
    if scheduler.startswith("local:"):
        try:
            n = int(scheduler.split(":", 1)[1])
        except ValueError:
            raise ConfigError(f"--scheduler {scheduler!r}: use local:N with N workers", "scheduler") from None
        if n < 1:
            raise ConfigError(f"--scheduler {scheduler!r}: N must be at least 1", "scheduler")
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address=None, silence_logs=50)
        address: Any = cluster
    else:
        address = scheduler
    try:
        client = Client(address, timeout="20s")
    except OSError as exc:
        if cluster is not None:
            cluster.close()
        raise ConfigError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}", "scheduler") from None
    try:
        futures = [client.submit(run_batch, b, pure=False) for b in batches]
        for future in as_completed(futures):
            yield future.result()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def execute(
    experiment: Experiment,
    store: ResultStore,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    on_progress: Callable[[int, int], None] | None = None,
) -> RunReport:
    """Run the experiment's tasks that the store lacks; commit each as it finishes.

    ``workers``: local processes (default: the machine's cores); ``scheduler``: a Dask
    scheduler address, or ``local:N`` for a local Dask cluster on loopback.
    ``on_progress(done, todo)`` is called after every committed task.
    """
    start = time.perf_counter()
    tasks = experiment.tasks()
    stored = store.keys()
    unique: dict[str, Task] = {}
    for t in tasks:
        if t.key not in stored:
            unique.setdefault(t.key, t)
    todo = list(unique.values())
    store.add_run(experiment.name, experiment.to_dict())
    workers = workers if workers is not None else (os.cpu_count() or 1)
    if workers < 1:
        raise ConfigError(f"--workers {workers} must be at least 1", "workers")
    batches = _batches(todo, workers if scheduler is None else 4)
    stream = _dask(batches, scheduler) if scheduler else _local(batches, workers)
    done = 0
    if on_progress:
        on_progress(0, len(todo))
    for results in stream:
        for result in results:
            store.put(result)
            done += 1
            if on_progress:
                on_progress(done, len(todo))
    total = len({t.key for t in tasks})
    return RunReport(total, total - len(todo), len(todo), time.perf_counter() - start)
