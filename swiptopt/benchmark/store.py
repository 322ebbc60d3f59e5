"""The results store: one SQLite file, each finished task committed at once.

Tasks are keyed by the hash of their resolved configuration (:attr:`Task.key`), so a rerun
skips what is stored and a killed sweep loses at most the tasks in flight. Each run of an
experiment also records its provenance: the experiment's configuration, package versions
and the git revision of the working tree.
"""

from __future__ import annotations

import json
import sqlite3
import subprocess
import time
from importlib import metadata
from pathlib import Path
from typing import Any, Iterable

from swiptopt.errors import ConfigError

DEFAULT_STORE = Path("results") / "swiptopt.sqlite"

_SCHEMA = """
CREATE TABLE IF NOT EXISTS results (
    key TEXT PRIMARY KEY,
    algorithm TEXT NOT NULL,
    seed INTEGER NOT NULL,
    task TEXT NOT NULL,
    records TEXT NOT NULL,
    extra TEXT NOT NULL,
    duration_s REAL NOT NULL,
    finished REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS runs (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    experiment TEXT NOT NULL,
    config TEXT NOT NULL,
    provenance TEXT NOT NULL,
    started REAL NOT NULL
);
"""

_PACKAGES = ("swiptopt", "numpy", "gymnasium", "numba", "ortools", "cvxpy", "ompl", "scikit-learn", "dask", "distributed")


def provenance() -> dict[str, Any]:
    """Package versions and the git revision (with a dirty flag) of the working directory."""
    versions = {}
    for name in _PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    git = None
    try:
        rev = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5)
        if rev.returncode == 0:
            dirty = subprocess.run(["git", "status", "--porcelain"], capture_output=True, text=True, timeout=5)
            git = rev.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        pass
    return {"versions": versions, "git": git}


class ResultStore:
    """An SQLite file of finished tasks and runs. Safe to reopen, append and read while
    another process writes (WAL journal)."""

    def __init__(self, path: str | Path = DEFAULT_STORE, *, create: bool = True):
        self.path = Path(path)
        if not create and not self.path.exists():
            raise ConfigError(f"no results store at {str(self.path)!r}", "store")
        if create:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self._db = sqlite3.connect(self.path, timeout=60)
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.executescript(_SCHEMA)
        except sqlite3.DatabaseError as exc:
            raise ConfigError(f"{self.path} is not a swiptopt results store: {exc}", "store") from None

    def close(self) -> None:
        self._db.close()

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def keys(self) -> set[str]:
        return {row[0] for row in self._db.execute("SELECT key FROM results")}

    def put(self, result: dict[str, Any]) -> None:
        """Commit one finished task (a repeated key is ignored: the first result stands)."""
        task = result["task"]
        with self._db:
            self._db.execute(
                "INSERT OR IGNORE INTO results VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    result["key"], task["algorithm"], task["seed"], json.dumps(task, sort_keys=True),
                    json.dumps(result["records"]), json.dumps(result["extra"]), result["duration_s"], time.time(),
                ),
            )

    def get(self, keys: Iterable[str]) -> dict[str, dict[str, Any]]:
        """Stored results by key, for the keys that are stored."""
        keys = list(keys)
        out: dict[str, dict[str, Any]] = {}
        for i in range(0, len(keys), 500):
            chunk = keys[i : i + 500]
            rows = self._db.execute(
                f"SELECT key, task, records, extra, duration_s FROM results WHERE key IN ({','.join('?' * len(chunk))})",
                chunk,
            )
            for key, task, records, extra, duration in rows:
                out[key] = {"key": key, "task": json.loads(task), "records": json.loads(records),
                            "extra": json.loads(extra), "duration_s": duration}
        return out

    def count(self) -> int:
        return int(self._db.execute("SELECT COUNT(*) FROM results").fetchone()[0])

    def add_run(self, experiment: str, config: dict[str, Any]) -> None:
        with self._db:
            self._db.execute(
                "INSERT INTO runs (experiment, config, provenance, started) VALUES (?, ?, ?, ?)",
                (experiment, json.dumps(config, sort_keys=True), json.dumps(provenance()), time.time()),
            )

    def runs(self) -> list[dict[str, Any]]:
        """The latest run of each experiment name, oldest first."""
        rows = self._db.execute(
            "SELECT experiment, config, provenance, started FROM runs WHERE id IN "
            "(SELECT MAX(id) FROM runs GROUP BY experiment) ORDER BY id"
        )
        return [{"experiment": e, "config": json.loads(c), "provenance": json.loads(p), "started": s} for e, c, p, s in rows]
