"""The Dask worker plugin that prepares every worker of a run like a local one (imported only
when a run uses ``--scheduler``, since it loads ``distributed``)."""

from __future__ import annotations

from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin

from swiptopt.benchmark.processes import die_with_parent, prepare_worker


class PrepareWorker(WorkerPlugin):
    """On each worker, before its first task: import ``modules``, one thread per native pool
    (:func:`~swiptopt.benchmark.processes.prepare_worker`) and, for the workers of a local
    cluster (``watch_parent``), exit when the process that started them dies."""

    name = "swiptopt-prepare-worker"
    idempotent = True

    def __init__(self, modules: tuple[str, ...], watch_parent: bool):
        self.modules = tuple(modules)
        self.watch_parent = watch_parent

    def setup(self, worker: Any) -> None:
        prepare_worker(self.modules)
        if self.watch_parent:
            die_with_parent()
