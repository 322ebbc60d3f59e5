"""Running an experiment's tasks: local worker processes or a Dask cluster.

A task builds the environment from its resolved scenario, builds (and, for RL, trains) the
policy with the task's seed, evaluates it with :func:`swiptopt.evaluate` on the task's
evaluation seeds, and returns per-episode records with the scenario's bounds and what the
algorithm records of itself (the MILP: its status, best, bound and gap). Everything a
task computes comes from its configuration and seed, so the numbers do not depend on where
it ran. Tasks go out in small batches; every finished task is committed to the store as
soon as its batch returns.

What can go wrong, and what happens then:

- A task that raises is a *failure*: recorded in the store with its reason (a rerun
  retries it), and the other tasks go on.
- A task that uses OMPL (``tour_costs = "ompl"``, the continuous world's OMPL tour: its
  algorithm's ``uses_ompl``) runs in a fresh process, whose
  process-wide OMPL seed is set from the task before anything plans: its numbers do not
  depend on which tasks ran before it, and a crash inside OMPL is that task's failure.
- A worker that dies (any native crash) loses only the tasks it held: they are run again
  one per fresh process, so the one that crashes is recorded as failed and the rest finish.
- Every worker runs one thread per native pool and exits when the run's process dies
  (:mod:`swiptopt.benchmark.processes`).

Trained deep-RL models are kept beside the store, in ``<store's directory>/models/``, as
weights files (data, never pickles) named by the hash of their training configuration
(:func:`rl.deep.train_or_load_deep`): a task whose model is there loads it instead of
training, so a second run (or another experiment with the same training) trains nothing. A
model trained across layouts serves every task of its training seed; the runner starts one
task per model first, each alone in its batch, so the workers train different models at
once, and a lock beside each model makes any other process that needs it wait and load it.
A models directory that this process cannot write is read without locks, provided it holds
every model the run needs. What would make the tasks of built-in deep-RL algorithms fail on
their models (``models`` beside the store is a file, a directory where a model, its lock or
the manifest goes, a read-only directory that lacks a model) is refused before any task runs
(:func:`check_models_dir`).

A plugin's algorithm runs only in the worker processes (never warmed up in this one), so a
crash in its native code loses its own tasks and nothing else.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from swiptopt.benchmark.experiment import Experiment, Task
from swiptopt.benchmark.processes import (
    die_with_parent,
    import_modules,
    limit_native_threads,
    one_line,
    prepare_worker,
    qualified_name,
    run_in_fresh_process,
)
from swiptopt.benchmark.store import ResultStore
from swiptopt.errors import ConfigError
from swiptopt.evaluation import EVALUATION_SEED_OFFSET
from swiptopt.files import can_make_files_in
from swiptopt.fpmath import pin_torch_cpu_paths

#: Modules with the native libraries of each algorithm family: imported before the thread
#: limit and before workers start, so the limit covers their pools and forked workers
#: share them.
NATIVE_MODULES = {
    "rl": ("numba",),
    "planner": ("numba", "sklearn.cluster", "ortools.constraint_solver.pywrapcp", "ortools.sat.python.cp_model",
                "cvxpy", "highspy", "scipy.sparse.csgraph"),
}
#: Local worker processes (``workers`` or a ``local:N`` scheduler) allowed per core of the machine.
MAX_WORKERS_PER_CORE = 4
#: Dask schemes that reach another process.
DASK_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")
#: How long connecting to a Dask scheduler may take before the run is refused, s.
SCHEDULER_TIMEOUT_S = 20.0
#: The key of a task dict sent to a worker that holds where trained models are kept (not
#: part of the task: it does not change the result).
MODELS_DIR = "models_dir"
#: The directory, beside the store, that holds trained models.
MODELS_SUBDIR = "models"
#: The models shipped with swiptopt (the deep-RL models of ``compare``), each vouched for by
#: the directory's manifest; ``--retrain`` leaves them out (docs/deep-rl.md says how they were made).
PRETRAINED_DIR = Path(__file__).resolve().parent / "pretrained"


def models_dir_for(store_path: Any) -> str:
    """Where a run on the store at ``store_path`` keeps trained models (absolute)."""
    return str(Path(store_path).resolve().parent / MODELS_SUBDIR)


#: The key of a task dict sent to a worker that holds the step counts at which the task's
#: training also saves its model (the other budgets of its lineage; not part of the task).
CHECKPOINTS = "checkpoints"
#: The key of a task dict that holds read-only directories of models trained elsewhere,
#: each vouched for by its manifest (:func:`rl.deep.train_or_load_deep`'s ``pretrained``).
PRETRAINED = "pretrained"
#: The key of a task dict that asks its training to keep its state at its end in the models
#: directory (:func:`rl.deep.train_or_load_deep`'s ``keep_state``), so that a longer budget
#: of its lineage goes on from there (not part of the task).
KEEP_STATE = "keep_state"


def _split(task: dict[str, Any]) -> tuple[dict[str, Any], str | None]:
    """A task dict as sent to a worker: the task itself, and the models directory (the
    checkpoints and pretrained directories stay out of the task too: see :func:`_routing`)."""
    task = dict(task)
    task.pop(CHECKPOINTS, None)
    task.pop(PRETRAINED, None)
    task.pop(KEEP_STATE, None)
    return task, task.pop(MODELS_DIR, None)


def _routing(task: dict[str, Any]) -> tuple[tuple[int, ...], tuple[str, ...], bool]:
    """A task dict's checkpoints, pretrained model directories and whether its training
    keeps its state at its end."""
    return tuple(task.get(CHECKPOINTS, ())), tuple(task.get(PRETRAINED, ())), bool(task.get(KEEP_STATE, False))


# ------------------------------------------------------------------------ one task


def run_task(task: dict[str, Any]) -> dict[str, Any]:
    """Run one task (a :meth:`Task.to_dict`, with :data:`MODELS_DIR` where trained models
    are kept, if anywhere); returns its result for the store."""
    from planners.bounds import EXACT_STATE_LIMIT, exact_state_bound, upper_bound
    from swiptopt.benchmark.algorithms import BuildContext, build_policy, get_algorithm, task_extra
    from swiptopt.benchmark.experiment import SEEDS_PER_LAYOUT
    from swiptopt.evaluation import evaluate
    from swiptopt.scenario import Scenario
    from swiptopt.worlds import GRID, make_env

    start = time.perf_counter()
    checkpoints, pretrained, keep_state = _routing(task)
    task, models_dir = _split(task)
    t = Task(**task)
    algorithm = get_algorithm(t.algorithm, t.plugin)  # registers a plugin in this process
    scenario = Scenario.from_dict(t.scenario)
    grid = t.world == GRID
    training = tuple(t.training_layouts) if t.training_layouts is not None else None
    context = BuildContext(scenario, t.seed % SEEDS_PER_LAYOUT, training, models_dir, t.world, checkpoints, pretrained,
                           keep_state)
    if algorithm.fleet:
        return _run_fleet_task(t, task, algorithm, context, start)
    # the continuous world has one observation (the vector); planners read the env itself
    env = make_env(t.world, scenario, observation=(algorithm.observation or "tabular") if grid else None)
    policy = build_policy(t.algorithm, env, t.settings, t.seed, context)
    result = evaluate(policy, env, t.episodes, seed=t.seed + EVALUATION_SEED_OFFSET)
    extra: dict[str, Any] = task_extra(t.algorithm, policy, env)
    if grid:
        # the bound counts the nodes coverable from the grid's cells: in the continuous world a
        # node may be coverable from off-lattice positions only, so it bounds nothing there
        extra = {"upper_bound_return": upper_bound(scenario, env.tables).return_, **extra}
    if grid and scenario.channel == "none" and scenario.failure_prob_max == 0:
        # a deterministic instance: whether its exact optimum is affordable is decided before
        # searching, from a bound on the search's size that the scenario alone gives
        states = exact_state_bound(scenario, env.tables)
        if states <= EXACT_STATE_LIMIT:
            try:
                extra["optimum_return"] = _exact_optimum_return(scenario, env.tables)
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


def _run_fleet_task(t: Task, task: dict[str, Any], algorithm: Any, context: Any, start: float) -> dict[str, Any]:
    """Run a fleet algorithm's task (docs/fleet.md): its policy in the fleet env, scored by
    :func:`swiptopt.evaluation.evaluate_fleet` (the records hold the fleet's metrics)."""
    from swiptopt.benchmark.algorithms import build_policy, task_extra
    from swiptopt.env_fleet import AuvFleetEnv
    from swiptopt.evaluation import evaluate_fleet

    env = AuvFleetEnv(context.scenario, observation=algorithm.observation or "vector")
    policy = build_policy(t.algorithm, env, t.settings, t.seed, context)
    result = evaluate_fleet(policy, env, t.episodes, seed=t.seed + EVALUATION_SEED_OFFSET)
    return {
        "key": t.key,
        "task": task,
        "records": result.records,
        "extra": task_extra(t.algorithm, policy, env),
        "duration_s": time.perf_counter() - start,
    }


#: The exact optima this process has found, by scenario (its name aside): every algorithm's
#: task on a deterministic instance asks for the same one.
_EXACT_OPTIMA: dict[str, float] = {}


def _exact_optimum_return(scenario: Any, tables: Any) -> float:
    """The exact optimum's return of a deterministic ``scenario`` (:func:`planners.bounds.exact_optimum`),
    searched once per process and scenario; the scenario's name labels it and changes no number."""
    from planners.bounds import exact_optimum

    key = json.dumps({k: v for k, v in scenario.to_dict().items() if k != "name"}, sort_keys=True)
    if key not in _EXACT_OPTIMA:
        _EXACT_OPTIMA[key] = exact_optimum(scenario, tables=tables).return_
    return _EXACT_OPTIMA[key]


def uses_ompl(task: dict[str, Any]) -> bool:
    """Whether the task plans with OMPL (and so must run in a fresh process): what its
    algorithm's ``uses_ompl`` says of its settings."""
    algorithm = _algorithm_of(task)
    return algorithm is not None and algorithm.uses_ompl is not None and bool(algorithm.uses_ompl(task["settings"]))


def ompl_seed(task: dict[str, Any]) -> int:
    """OMPL's process-wide seed for a task: its own seed, shifted past 0 (which OMPL
    replaces by 1)."""
    return int(task["seed"]) + 1


def seed_ompl(task: dict[str, Any]) -> None:
    """Set OMPL's process-wide seed from the task. OMPL's rule: once per process, before
    anything plans, so call it first thing in a fresh process."""
    from ompl import util as ou

    ou.RNG.setSeed(ompl_seed(task))


def run_ompl_task(task: dict[str, Any]) -> dict[str, Any]:
    """:func:`run_task` in a fresh process, OMPL seeded from the task first."""
    seed_ompl(task)
    return run_task(task)


def _failure(task: dict[str, Any], reason: str, detail: str = "") -> dict[str, Any]:
    task, _ = _split(task)
    return {"key": Task(**task).key, "task": task, "error": reason, "detail": detail}


def _algorithm_of(task: dict[str, Any]) -> Any:
    """The task's algorithm, or None if it cannot be found here (the task reports why)."""
    from swiptopt.benchmark.algorithms import get_algorithm

    try:
        return get_algorithm(task["algorithm"], task.get("plugin", ""))
    except ConfigError:
        return None


def _modules_for(tasks: list[dict[str, Any]]) -> tuple[str, ...]:
    algorithms = {t["algorithm"]: _algorithm_of(t) for t in tasks}
    known = [a for _, a in sorted(algorithms.items()) if a is not None]
    families = sorted({a.family for a in known})
    modules = [m for family in families for m in NATIVE_MODULES.get(family, ())] + [m for a in known for m in a.modules]
    return tuple(dict.fromkeys(modules))


def run_isolated(task: dict[str, Any]) -> dict[str, Any]:
    """Run one task in a fresh process: its result, or a failure saying how it failed
    (an exception, or the signal that killed the process)."""
    target = run_ompl_task if uses_ompl(task) else run_task
    outcome = run_in_fresh_process(qualified_name(target), task, modules=_modules_for([task]))
    if outcome.error is not None:
        return _failure(task, outcome.error, outcome.detail)
    return outcome.value


def run_outcome(task: dict[str, Any]) -> dict[str, Any]:
    """Run one task here (in a fresh process if it uses OMPL); an exception becomes a
    failure record (``"error"``, ``"detail"``) instead of stopping the run, and so does a
    ``SystemExit`` that an algorithm's code raises."""
    if uses_ompl(task):
        return run_isolated(task)
    try:
        return run_task(task)
    except (Exception, SystemExit) as exc:  # recorded with its traceback; the run goes on
        return _failure(task, one_line(exc), traceback.format_exc())


#: Where a local worker sends the progress of its tasks' training (set by the pool's
#: initializer when the parent listens; see :func:`_local`).
_REPORTS: Any = None


def run_batch(tasks: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Run tasks one after the other (a unit of work sent to a worker); a worker whose
    parent listens reports how far each task's training has got."""
    if _REPORTS is None:
        return [run_outcome(t) for t in tasks]
    from rl.deep import reporting_progress

    outcomes = []
    for t in tasks:
        with reporting_progress(_reporter(t)):
            outcomes.append(run_outcome(t))
    return outcomes


def _reporter(task: dict[str, Any]) -> Callable[[int, int, bool], None] | None:
    """What sends a task's training progress to the parent, or None if it does not listen."""
    reports = _REPORTS
    if reports is None:
        return None
    key = Task(**_split(task)[0]).key

    def report(steps: int, total: int, finished: bool) -> None:
        reports.put((key, steps, total, finished))

    return report


def run_batch_isolated(tasks: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Run tasks one after the other, each in a fresh process (after a worker died)."""
    return [run_isolated(t) for t in tasks]


def warm_up(tasks: list[dict[str, Any]]) -> None:
    """Run each built-in algorithm of ``tasks`` once on a small scenario, so that workers
    forked afterwards inherit the compiled kernel, the solvers' first-call set-up and every
    import instead of each paying for them. The results are thrown away. A plugin's
    algorithm is never run here: a crash in its code would end the run, not only its task."""
    from swiptopt.benchmark.algorithms import ALGORITHMS
    from swiptopt.scenario import Scenario

    small = Scenario.from_dict({"preset": "paper", "n_nodes": 4, "episode_steps": 10}).to_dict()
    seen: set[str] = set()
    for task in tasks:
        if task["algorithm"] not in ALGORITHMS or task.get("plugin"):
            continue
        algorithm = ALGORITHMS[task["algorithm"]]
        # a trained model's warm-up would cost a training; its imports are in its modules
        if task["algorithm"] in seen or uses_ompl(task) or algorithm.trains_model:
            continue
        seen.add(task["algorithm"])
        settings = dict(task["settings"])
        if settings.get("train_episodes"):
            settings["train_episodes"] = 1
        try:
            run_task({**_split(task)[0], "scenario": small, "settings": settings, "episodes": 1})
        except Exception:
            pass  # the real task meets the same error and records it


# ------------------------------------------------------------------ schedulers


def check_run_options(workers: int | None, scheduler: str | None) -> int:
    """Validate :func:`execute`'s ``workers`` and ``scheduler`` (before any task runs);
    returns the number of local workers to use (ignored with a scheduler)."""
    cores = os.cpu_count() or 1
    limit = MAX_WORKERS_PER_CORE * cores
    if workers is not None and scheduler is not None:
        raise ConfigError("give workers (local processes) or scheduler (Dask), not both", "workers")
    if workers is not None:
        if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= limit:
            raise ConfigError(
                f"workers = {workers!r} must be an integer in [1, {limit}] "
                f"({MAX_WORKERS_PER_CORE} per core, {cores} cores)", "workers")
    if scheduler is not None:
        _check_scheduler(scheduler, limit)
    return workers if workers is not None else cores


def _check_scheduler(scheduler: str, limit: int) -> None:
    usage = "use local:N (a local Dask cluster of N workers) or a scheduler address such as tcp://HOST:PORT"
    if not isinstance(scheduler, str) or not scheduler.strip():
        raise ConfigError(f"scheduler = {scheduler!r} is empty: {usage}", "scheduler")
    if scheduler.startswith("local:"):
        count = scheduler.split(":", 1)[1]
        if not count.isdigit() or not 1 <= int(count) <= limit:
            raise ConfigError(f"scheduler = {scheduler!r}: N must be an integer in [1, {limit}]", "scheduler")
        return
    try:
        from distributed.comm.addressing import parse_address, parse_host_port
    except ImportError:
        raise ConfigError("scheduler needs dask.distributed: pip install 'swiptopt[bench]'", "scheduler") from None
    try:
        scheme, location = parse_address(scheduler, strict=False)
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"scheduler = {scheduler!r} is not a scheduler address ({exc}): {usage}",
                          "scheduler") from None
    if scheme not in DASK_SCHEMES:
        raise ConfigError(f"scheduler = {scheduler!r}: unknown scheme {scheme!r}; one of {', '.join(DASK_SCHEMES)}",
                          "scheduler")
    try:
        host, port = parse_host_port(location)
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"scheduler = {scheduler!r} is not a scheduler address ({exc}): {usage}",
                          "scheduler") from None
    if not host or not 1 <= port <= 65535:
        raise ConfigError(f"scheduler = {scheduler!r} needs a host and a port in [1, 65535]: {usage}", "scheduler")


def _start_pool_worker(parent_pid: int, modules: tuple[str, ...], reports: Any = None) -> None:
    global _REPORTS
    die_with_parent(parent_pid)
    prepare_worker(modules)
    if reports is not None:
        reports.cancel_join_thread()  # a report not yet sent never holds up the worker's exit
    _REPORTS = reports


#: Seconds the parent waits for a batch before it passes on the training reports it got.
REPORT_POLL_S = 1.0
#: What the parent is told of a training: the task's key, its steps so far, its total, and
#: whether it has finished.
TrainingReport = Callable[[str, int, int, bool], None]


def _drain(reports: Any, on_training: TrainingReport | None) -> None:
    """Pass on every training report waiting in ``reports`` (a multiprocessing queue: a
    worker's ``put`` never blocks, whether or not the parent is reading)."""
    import queue

    if reports is None or on_training is None:
        return
    while True:
        try:
            report = reports.get_nowait()
        except queue.Empty:
            return
        on_training(*report)


def _isolated(tasks: list[dict[str, Any]], workers: int) -> Iterator[list[dict[str, Any]]]:
    """Each task in its own fresh process, ``workers`` at a time."""
    from concurrent.futures import ThreadPoolExecutor, as_completed

    # each thread waits for its child to the end (a Linux child dies with its thread)
    with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="swiptopt-isolated") as pool:
        for future in as_completed([pool.submit(run_isolated, t) for t in tasks]):
            yield [future.result()]


def _local(batches: list[list[dict[str, Any]]], workers: int, modules: tuple[str, ...],
           on_training: TrainingReport | None = None) -> Iterator[list[dict[str, Any]]]:
    """Batches on ``workers`` local processes (one too: a native crash must not end the run);
    with ``on_training``, the workers' training reports are passed to it as they come (at
    least every :data:`REPORT_POLL_S` seconds)."""
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    # fork shares the imported model, the warmed-up solvers and numba's loaded code; spawn
    # where fork is unavailable
    context = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
    queue = deque(batches)
    while queue:
        # a queue per pool: a worker killed while writing to it takes only its own pool's queue down
        reports = context.Queue() if on_training is not None else None
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_start_pool_worker,
                                   initargs=(os.getpid(), modules, reports))
        running: dict[Any, list[dict[str, Any]]] = {}
        lost: list[list[dict[str, Any]]] = []
        try:
            while (queue or running) and not lost:
                while queue and len(running) < 2 * workers:  # a short queue: a crash strands little
                    try:
                        future = pool.submit(run_batch, batch := queue.popleft())
                    except BrokenProcessPool:  # a worker died already: the batch waits for the next pool
                        queue.appendleft(batch)
                        break
                    running[future] = batch
                if not running:  # the pool broke before it took any batch: the next runs alone
                    lost.append(queue.popleft())
                    break
                done, _ = wait(running, timeout=None if reports is None else REPORT_POLL_S,
                               return_when=FIRST_COMPLETED)
                _drain(reports, on_training)
                for future in done:
                    batch = running.pop(future)
                    if isinstance(future.exception(), BrokenProcessPool):
                        lost.append(batch)
                    else:
                        yield future.result()
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
            _drain(reports, on_training)  # what the workers sent before they stopped
        # a worker died: keep what finished meanwhile, then find the culprit task by running
        # each task it may have held in a fresh process
        for future, batch in running.items():
            if not future.cancelled() and future.exception() is None:
                yield future.result()
            else:
                lost.append(batch)
        if lost:
            yield from _isolated([t for batch in lost for t in batch], workers)


def _staged(stages: list[list[list[dict[str, Any]]]],
            run: Callable[[list[list[dict[str, Any]]]],
                          Iterator[list[dict[str, Any]]]]) -> Iterator[list[dict[str, Any]]]:
    """The outcomes of each stage's batches, one stage run to its end before the next."""
    for batches in stages:
        yield from run(batches)


@contextlib.contextmanager
def dask_client(scheduler: str | None) -> Iterator[Any]:
    """A client of the Dask scheduler ``scheduler`` (``local:N``: a new local cluster on
    loopback, closed with the client), or ``None`` without a scheduler. A scheduler that
    cannot be reached within :data:`SCHEDULER_TIMEOUT_S` is a :class:`ConfigError` naming
    it: connect before writing anything, so such a run leaves no trace."""
    if scheduler is None:
        yield None
        return
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise ConfigError("scheduler needs dask.distributed: pip install 'swiptopt[bench]'", "scheduler") from None
    cluster = None
    if scheduler.startswith("local:"):
        cluster = LocalCluster(n_workers=int(scheduler.split(":", 1)[1]), threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None, silence_logs=50)
        address: Any = cluster
    else:
        address = scheduler
    try:
        client = Client(address, timeout=f"{SCHEDULER_TIMEOUT_S:g}s")
    except (OSError, TimeoutError) as exc:
        if cluster is not None:
            cluster.close()
        raise ConfigError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}", "scheduler") from None
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _dask(stages: list[list[list[dict[str, Any]]]], client: Any, modules: tuple[str, ...],
          watch_parent: bool) -> Iterator[list[dict[str, Any]]]:
    """The outcomes of each stage's batches on the Dask cluster of ``client``
    (``watch_parent``: its workers are this process's, a local cluster's)."""
    from dask.distributed import as_completed

    from swiptopt.benchmark.dask_plugin import PrepareWorker

    client.register_plugin(PrepareWorker(modules, watch_parent=watch_parent))
    for batches in stages:
        pending = {client.submit(run_batch, b, pure=False): (b, False) for b in batches}
        stream = as_completed(pending)
        for future in stream:
            batch, isolated = pending.pop(future)
            try:
                yield future.result()
            except Exception as exc:  # the worker died under the batch (KilledWorker, a crash)
                if isolated:
                    yield [_failure(t, f"the Dask worker died running it: {one_line(exc)}") for t in batch]
                else:
                    retry = client.submit(run_batch_isolated, batch, pure=False)
                    pending[retry] = (batch, True)
                    stream.add(retry)


# ------------------------------------------------------------------------ models


def _task_models(tasks: list[Task], models_dir: str,
                 pretrained: tuple[str, ...] = ()) -> Iterator[tuple[Task, Any, Any, Path]]:
    """Each task of a built-in algorithm that keeps a model (its ``trained_model``), with
    that model's training configuration and scenario and its path in ``models_dir`` (a
    plugin's code runs only in its tasks, so its models are not named)."""
    from rl.deep import model_path
    from swiptopt.benchmark.algorithms import ALGORITHMS, BuildContext
    from swiptopt.benchmark.experiment import SEEDS_PER_LAYOUT
    from swiptopt.scenario import Scenario

    for t in tasks:
        algorithm = ALGORITHMS.get(t.algorithm)
        if algorithm is None or t.plugin or algorithm.trained_model is None:
            continue
        training = tuple(t.training_layouts) if t.training_layouts is not None else None
        context = BuildContext(Scenario.from_dict(t.scenario), t.seed % SEEDS_PER_LAYOUT, training, models_dir,
                               t.world, (), tuple(pretrained))
        config, scenario = algorithm.trained_model(t.settings, t.seed, context)
        yield t, config, scenario, model_path(Path(models_dir), config, scenario)


def _models_of(tasks: list[Task], models_dir: str,
               pretrained: tuple[str, ...] = ()) -> Iterator[tuple[Task, Any, Any, Path]]:
    """Each model the built-in algorithms' tasks keep, once (:func:`_task_models`, the first
    task that names it)."""
    seen: set[Path] = set()
    for t, config, scenario, path in _task_models(tasks, models_dir, pretrained):
        if path not in seen:
            seen.add(path)
            yield t, config, scenario, path


def _with_models(tasks: list[Task], models_dir: str, pretrained: tuple[str, ...] = ()) -> set[str]:
    """The keys of the tasks whose model is already kept: in ``models_dir`` or vouched for in
    ``pretrained``."""
    from rl.deep import find_model

    found: dict[Path, bool] = {}
    keys = set()
    for t, config, scenario, path in _task_models(tasks, models_dir, pretrained):
        if path not in found:
            found[path] = find_model([models_dir, *pretrained], config, scenario)[0] is not None
        if found[path]:
            keys.add(t.key)
    return keys


def check_models_dir(tasks: list[Task], models_dir: str, pretrained: tuple[str, ...] = ()) -> None:
    """Refuse, before any task runs, a models directory the tasks could not use: a file at
    its path (when any task keeps a model), a directory where the manifest or its lock goes,
    and for each task of a built-in algorithm that keeps models (its ``trained_model``) a
    directory where its model or its lock goes, a lock file that cannot be written, or a
    directory this process cannot write that does not hold the model (a read-only
    directory that holds every model is read as it is)."""
    from rl.deep import MANIFEST, find_model

    keeping = [t for t in tasks if (a := _algorithm_of(t.to_dict())) is not None and a.trains_model]
    if not keeping:
        return
    directory = Path(models_dir)
    where = "trained models are kept in a directory of that name beside the store"
    if directory.exists() and not directory.is_dir():
        raise ConfigError(f"models directory {str(directory)!r} is a file: {where}; move the file away", "models")
    for name in (MANIFEST, MANIFEST + ".lock"):
        if (directory / name).is_dir():
            raise ConfigError(f"{str(directory / name)!r} is a directory where the models' manifest goes: remove it",
                              "models")
    writable = can_make_files_in(directory)
    for t, config, scenario, path in _models_of(keeping, models_dir, pretrained):
        lock = path.with_name(path.name + ".lock")
        for place, what in ((path, "a trained model"), (lock, "a model's lock")):
            if place.is_dir():
                raise ConfigError(f"{str(place)!r} is a directory where {what} goes: remove it", "models")
        if not writable:
            found, _ = find_model([directory, *pretrained], config, scenario)
            if found is None:
                raise ConfigError(f"models directory {str(directory)!r} is not writable and lacks the model "
                                  f"{path.name} ({t.algorithm}): make it writable", "models")
        elif lock.exists() and not os.access(lock, os.W_OK):
            raise ConfigError(f"{str(lock)!r} (a model's lock) is not writable: remove it", "models")


def models_to_train(experiment: Experiment, store: ResultStore, pretrained: tuple[str, ...] | list[str] = ()
                    ) -> list[str]:
    """The algorithms (one entry per model) whose models the tasks of ``experiment`` that
    ``store`` lacks would train: neither in the store's models directory nor vouched for in
    ``pretrained``. A model is named by its configuration and by the versions of torch,
    Stable-Baselines3, sb3-contrib and Gymnasium (:func:`rl.deep.deep_config_hash`), so an
    installation with other versions finds none of the shipped models."""
    from rl.deep import find_model

    models_dir = models_dir_for(store.path)
    return [t.algorithm for t, config, scenario, _ in _models_of(_todo(experiment.tasks(), store), models_dir,
                                                                    tuple(pretrained))
            if find_model([models_dir, *pretrained], config, scenario)[0] is None]


# ------------------------------------------------------------------------- a run


def _lineage_of(task: Task) -> tuple[Any, ...] | None:
    """What names the training run behind a task's model, all but its length: tasks of one
    lineage differ only in ``timesteps`` (a learning curve's budgets) or in the layout they
    are evaluated on (a model trained across layouts), so one run, saving its model at
    every budget the lineage needs, serves them all. None for tasks that train nothing."""
    import json

    algorithm = _algorithm_of(task.to_dict())
    if algorithm is None or not algorithm.trains_model:
        return None
    from swiptopt.benchmark.experiment import SEEDS_PER_LAYOUT

    settings = {k: v for k, v in task.settings.items() if k != "timesteps"}
    if task.training_layouts is None:
        return (task.algorithm, task.plugin, task.world, json.dumps([task.scenario, settings], sort_keys=True),
                task.seed)
    scenario = {k: v for k, v in task.scenario.items() if k != "layout_seed"}
    return (task.algorithm, task.plugin, task.world, json.dumps([scenario, settings], sort_keys=True),
            task.seed % SEEDS_PER_LAYOUT, tuple(task.training_layouts))


def _batches(tasks: list[Task], workers: int, models_dir: str | None = None,
             pretrained: tuple[str, ...] = (), keep_state: bool = False) -> list[list[list[dict[str, Any]]]]:
    """The tasks as stages of batches of task dicts, each stage run to its end before the
    next starts. First, one task per training lineage (:func:`_lineage_of`), its longest
    budget whose model is not kept yet (in ``models_dir`` or ``pretrained``: a shipped
    model of the last budget is loaded, not a reason to train each shorter budget apart),
    each alone and the longest first (so the workers train different models at once and the
    longest work starts first), told to save its model at the lineage's other budgets that
    lack one; beside them every task that trains nothing (a kept model's too). Then the
    lineages' other tasks, which load the models their trainers saved. Batches hold at most
    4 tasks (at least ~8 per worker for load balance) so a killed run loses little. With
    ``keep_state`` each lineage's trainer keeps its training state at its end
    (:data:`KEEP_STATE`)."""
    lineages: dict[tuple[Any, ...], list[Task]] = {}
    plain: list[Task] = []
    for t in tasks:
        lineage = _lineage_of(t)
        if lineage is None:
            plain.append(t)
        else:
            lineages.setdefault(lineage, []).append(t)
    extra: dict[str, Any] = {MODELS_DIR: models_dir} if models_dir is not None else {}
    if pretrained:
        extra[PRETRAINED] = list(pretrained)
    kept = _with_models([t for m in lineages.values() for t in m], models_dir, pretrained) if models_dir else set()
    trainers: list[dict[str, Any]] = []
    followers: list[Task] = []
    for members in lineages.values():
        members = sorted(members, key=lambda t: -int(t.settings.get("timesteps", 0)))
        missing = [t for t in members if t.key not in kept]
        plain += [t for t in members if t.key in kept]  # they load a kept model: they train nothing
        if not missing:
            continue
        lead = missing[0]
        longest = int(lead.settings.get("timesteps", 0))
        budgets = sorted({int(t.settings.get("timesteps", 0)) for t in missing[1:]} - {longest})
        keep = {KEEP_STATE: True} if keep_state else {}
        trainers.append({**lead.to_dict(), **extra, CHECKPOINTS: budgets, **keep})
        followers += missing[1:]
    trainers.sort(key=lambda d: -int(d["settings"].get("timesteps", 0)))

    def small(group: list[Task]) -> list[list[dict[str, Any]]]:
        size = max(1, min(4, math.ceil(len(group) / max(1, workers * 8))))
        dicts = [{**t.to_dict(), **extra} for t in group]
        return [dicts[i : i + size] for i in range(0, len(dicts), size)]

    stages = [[[d] for d in trainers] + small(plain), small(followers)]
    return [stage for stage in stages if stage]


@dataclass(frozen=True)
class Failure:
    """A task that could not run, and why (one line)."""

    key: str
    algorithm: str
    point: dict[str, Any]
    seed: int
    reason: str


@dataclass(frozen=True)
class RunReport:
    """What a run did: tasks in the experiment, found already stored, run now (of which
    ``failures`` failed), and the wall time."""

    total: int
    cached: int
    ran: int
    seconds: float
    failures: tuple[Failure, ...] = ()

    @property
    def failed(self) -> int:
        return len(self.failures)


def execute(
    experiment: Experiment,
    store: ResultStore,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    on_progress: Callable[[int, int], None] | None = None,
    pretrained: tuple[str, ...] | list[str] = (),
    client: Any = None,
    on_training: Callable[[Task, int, int, bool], None] | None = None,
    keep_state: bool = False,
) -> RunReport:
    """Run the experiment's tasks that the store lacks; commit each as it finishes.

    ``workers``: local processes (default: the machine's cores); ``scheduler``: a Dask
    scheduler address, or ``local:N`` for a local Dask cluster on loopback; ``client``: a
    client of that scheduler already connected (:func:`dask_client`; else one is made here,
    before the store records the run, and closed at the end). Everything that could stop
    the run (the options, the models directory, the scheduler) is checked before the store
    records it.
    ``on_progress(done, todo)`` is called after every committed task, and
    ``on_training(task, steps, total, finished)`` as a task's deep-RL training goes on (its
    steps so far of its total; every few seconds, and once ``finished``; local workers only:
    a Dask worker reports no training). A task that fails is
    recorded in the store (not as a result) and in the report; the others go on. Trained
    models go to ``models/`` beside the store (:func:`models_dir_for`); a model is reused
    from there, or from the ``pretrained`` directories, when the directory's manifest
    vouches for its file. A training cut short goes on from its last saved state when the
    run is repeated (:func:`rl.deep.train_or_load_deep`); with ``keep_state`` the longest
    training of each lineage keeps its state at its end in ``models/``, so that a longer
    budget added later goes on from it.
    """
    start = time.perf_counter()
    workers = check_run_options(workers, scheduler)
    pin_torch_cpu_paths()  # before torch computes here or in a forked worker
    tasks = experiment.tasks()
    todo = _todo(tasks, store)
    total = len({t.key for t in tasks})
    models_dir = models_dir_for(store.path)
    check_models_dir(todo, models_dir, tuple(pretrained))
    with contextlib.ExitStack() as stack:
        if scheduler and todo and client is None:  # reach the scheduler before the store records the run
            client = stack.enter_context(dask_client(scheduler))
        store.add_run(experiment.name, experiment.to_dict(), experiment.record())
        if on_progress:
            on_progress(0, len(todo))
        if not todo:
            return RunReport(total, total, 0, time.perf_counter() - start)
        failures = _run_todo(todo, store, workers, scheduler, client, models_dir, tuple(pretrained), on_progress,
                             on_training, keep_state)
    return RunReport(total, total - len(todo), len(todo), time.perf_counter() - start, tuple(failures))


def _todo(tasks: list[Task], store: ResultStore) -> list[Task]:
    """The distinct tasks that the store lacks, in order."""
    stored = store.keys()
    unique: dict[str, Task] = {}
    for t in tasks:
        if t.key not in stored:
            unique.setdefault(t.key, t)
    return list(unique.values())


def check_models_for(experiment: Experiment, store: ResultStore, pretrained: tuple[str, ...] | list[str] = ()) -> None:
    """:func:`check_models_dir` for the tasks of ``experiment`` that ``store`` lacks (what
    :func:`execute` checks first; a caller with several experiments checks them all before
    running any)."""
    check_models_dir(_todo(experiment.tasks(), store), models_dir_for(store.path), tuple(pretrained))


def check_retrain(experiment: Experiment, store: ResultStore) -> None:
    """What ``--retrain`` checks before any task runs: that ``store`` holds no result of
    ``experiment`` evaluated with a model shipped with swiptopt. A store keeps a task's
    first result, so such a task would be reported from the shipped model, not retrained."""
    keys = {t.key for t in experiment.tasks()} & store.keys()
    shipped = [r["task"]["algorithm"] for r in store.get(sorted(keys)).values() if r["extra"].get("model_shipped")]
    if shipped:
        names = ", ".join(sorted(set(shipped)))
        raise ConfigError(f"--retrain: the store {str(store.path)!r} already holds {len(shipped)} results of "
                          f"{experiment.name!r} evaluated with the models shipped with swiptopt ({names}); a store "
                          "keeps a task's first result, so they would be reported, not retrained: name a new "
                          "--store", "store")


def _run_todo(todo: list[Task], store: ResultStore, workers: int, scheduler: str | None, client: Any,
              models_dir: str, pretrained: tuple[str, ...],
              on_progress: Callable[[int, int], None] | None,
              on_training: Callable[[Task, int, int, bool], None] | None = None,
              keep_state: bool = False) -> list[Failure]:
    """Run the tasks (locally, or on the Dask cluster of ``client``), committing each
    outcome to the store as it comes; returns the failures."""
    by_key = {t.key: t for t in todo}

    def training(key: str, steps: int, total: int, finished: bool) -> None:
        if on_training is not None and key in by_key:
            on_training(by_key[key], steps, total, finished)

    todo_dicts = [t.to_dict() for t in todo]
    stages = _batches(todo, workers if scheduler is None else 4, models_dir, pretrained, keep_state)
    modules = _modules_for(todo_dicts)
    limit = None
    if scheduler:
        stream = _dask(stages, client, modules, watch_parent=scheduler.startswith("local:"))
    else:
        # load the native libraries, limit their pools, then warm up: the forked workers
        # inherit all of it, and no OpenMP pool has started threads that a fork would break
        import_modules(modules)
        limit = limit_native_threads()
        warm_up(todo_dicts)
        stream = _staged(stages, lambda batches: _local(batches, workers, modules,
                                                        training if on_training is not None else None))
    failures: list[Failure] = []
    done = 0
    try:
        for outcomes in stream:
            for outcome in outcomes:
                if "error" in outcome:
                    store.put_failure(outcome)
                    task = outcome["task"]
                    failures.append(Failure(outcome["key"], task["algorithm"], task["point"], task["seed"],
                                            outcome["error"]))
                else:
                    store.put(outcome)
                done += 1
                if on_progress:
                    on_progress(done, len(todo))
    finally:
        stream.close()
        if limit is not None:
            limit.restore()
    return failures
