"""The results store: one SQLite file, each finished task committed at once.

Tasks are keyed by the hash of their resolved configuration (:attr:`Task.key`), so a rerun
skips what is stored and a killed sweep loses at most the tasks in flight. A task that
failed is kept apart with its reason (a rerun retries it). Each run of an experiment also
records its provenance: the experiment's configuration, package versions, and swiptopt's
own git revision when it runs from a checkout, and the experiment's record
(:meth:`~swiptopt.benchmark.experiment.Experiment.record`: the order of its algorithms, and
the settings of those that are not built in).

Reading a store runs no code it names: its experiments are rebuilt from the stored data
alone (:meth:`ResultStore.experiments`), so a plugin that is not installed here, or a
configuration that names ``os:abort`` as a plugin, neither stops nor runs anything.

The file is marked as ours (SQLite's ``application_id``, and ``user_version`` as the schema
version) and checked on every open: a file that is not SQLite, is damaged, belongs to
another program or to another schema version is refused with one line naming it
(:class:`StoreError`), and never written to. Every result row carries a SHA-256 of its
stored text, so damage that SQLite cannot see (a changed digit) is caught when it is read,
as are invalid JSON and records that lack a metric. Writers wait up to
:data:`BUSY_TIMEOUT_S` for one another (two runs can share a store), then stop with a
message saying the store is locked.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import platform
import re
import sqlite3
import time
from collections.abc import Iterable, Iterator
from importlib import metadata
from pathlib import Path
from typing import Any
from urllib.parse import quote

from swiptopt.errors import ConfigError
from swiptopt.files import existing_ancestor
from swiptopt.fpmath import TORCH_CPU_PATHS

DEFAULT_STORE = Path("results") / "swiptopt.sqlite"
#: ``PRAGMA application_id`` of a swiptopt store ("SWPT").
APPLICATION_ID = 0x53575054
#: ``PRAGMA user_version``: the layout of the tables below.
SCHEMA_VERSION = 1
#: How long a writer waits for another one before giving up, s.
BUSY_TIMEOUT_S = 60.0
#: The key of a run's provenance that holds the experiment's record (what reading it needs
#: beside its configuration: :meth:`~swiptopt.benchmark.experiment.Experiment.record`).
RUN_RECORD = "experiment_record"

_TABLES = {
    "results": """CREATE TABLE results (
    key TEXT PRIMARY KEY,
    algorithm TEXT NOT NULL,
    seed INTEGER NOT NULL,
    task TEXT NOT NULL,
    records TEXT NOT NULL,
    extra TEXT NOT NULL,
    duration_s REAL NOT NULL,
    finished REAL NOT NULL,
    checksum TEXT NOT NULL
)""",
    "runs": """CREATE TABLE runs (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    experiment TEXT NOT NULL,
    config TEXT NOT NULL,
    provenance TEXT NOT NULL,
    started REAL NOT NULL
)""",
    "failures": """CREATE TABLE failures (
    key TEXT PRIMARY KEY,
    algorithm TEXT NOT NULL,
    seed INTEGER NOT NULL,
    task TEXT NOT NULL,
    reason TEXT NOT NULL,
    detail TEXT NOT NULL,
    finished REAL NOT NULL
)""",
}
#: The tables of stores written before the mark (swiptopt 0.1.0 before schema 1), adopted
#: when opened for writing.
_UNMARKED_COLUMNS = {
    "results": ["key", "algorithm", "seed", "task", "records", "extra", "duration_s", "finished"],
    "runs": ["id", "experiment", "config", "provenance", "started"],
}
_SQLITE_MAGIC = b"SQLite format 3\x00"

_PACKAGES = ("swiptopt", "numpy", "scipy", "gymnasium", "numba", "ortools", "cvxpy", "clarabel", "highspy", "ompl",
             "scikit-learn", "threadpoolctl", "dask", "distributed", "torch", "stable-baselines3", "sb3-contrib")


class StoreError(ConfigError):
    """A results store that cannot be used as asked; the message names the file."""

    def __init__(self, path: Path | str, problem: str):
        super().__init__(f"results store {str(path)!r}: {problem}", "store")


# ------------------------------------------------------------------ provenance

_SHA = re.compile(r"[0-9a-f]{40}([0-9a-f]{24})?")


def _git_dir(root: Path) -> Path | None:
    dot = root / ".git"
    if dot.is_dir():
        return dot
    if dot.is_file():  # a worktree or submodule: "gitdir: <path>"
        text = dot.read_text(encoding="utf-8", errors="replace").strip()
        if text.startswith("gitdir:"):
            target = Path(text[len("gitdir:"):].strip())
            return target if target.is_absolute() else (root / target).resolve()
    return None


def _resolve_ref(git_dir: Path, common_dir: Path, ref: str, depth: int = 0) -> str | None:
    if depth > 5:
        return None
    for base in (git_dir, common_dir):
        path = base / ref
        if path.is_file():
            text = path.read_text(encoding="utf-8", errors="replace").strip()
            if text.startswith("ref:"):
                return _resolve_ref(git_dir, common_dir, text[4:].strip(), depth + 1)
            return text if _SHA.fullmatch(text) else None
    packed = common_dir / "packed-refs"
    if packed.is_file():
        for line in packed.read_text(encoding="utf-8", errors="replace").splitlines():
            sha, _, name = line.partition(" ")
            if name.strip() == ref and _SHA.fullmatch(sha):
                return sha
    return None


def checkout_revision(root: Path | str) -> str | None:
    """The commit checked out in the git working tree at ``root`` (its ``.git`` directory,
    or a worktree's ``.git`` file), or None if ``root`` is not one.

    Read from the files under ``.git`` (``HEAD``, refs, ``packed-refs``, a worktree's
    ``gitdir:`` and ``commondir``), never by running ``git``: a repository's configuration
    can make git run commands (``core.fsmonitor``). No dirty flag: telling one needs git.
    """
    try:
        git_dir = _git_dir(Path(root))
        if git_dir is None or not (git_dir / "HEAD").is_file():
            return None
        common_dir = git_dir
        if (git_dir / "commondir").is_file():
            common = Path((git_dir / "commondir").read_text(encoding="utf-8", errors="replace").strip())
            common_dir = common if common.is_absolute() else (git_dir / common).resolve()
        return _resolve_ref(git_dir, common_dir, "HEAD")
    except OSError:
        return None


def package_revision() -> str | None:
    """swiptopt's own git commit when it runs from a checkout (the directory holding the
    package is a git working tree), else None. The user's working directory plays no part."""
    import swiptopt

    return checkout_revision(Path(swiptopt.__file__).resolve().parent.parent)


def cpu_model() -> str | None:
    """The CPU's model name (Linux: ``/proc/cpuinfo``; elsewhere what ``platform`` knows)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as info:
            for line in info:
                name, _, value = line.partition(":")
                if name.strip() in ("model name", "Model", "cpu model"):
                    return value.strip() or None
    except OSError:
        pass
    return platform.processor() or None


def machine() -> dict[str, Any]:
    """What the guarantee of the same numbers depends on beside the package versions: the
    CPU, its architecture, the C library, the SIMD features numpy found and torch's CPU
    paths (:data:`swiptopt.fpmath.TORCH_CPU_PATHS`, as set in this process)."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:  # numpy < 2
        from numpy.core._multiarray_umath import __cpu_features__ as features
    libc, libc_version = platform.libc_ver()
    return {
        "cpu": cpu_model(),
        "architecture": platform.machine(),
        "libc": f"{libc} {libc_version}".strip() or None,
        "simd": [name for name in ("AVX2", "FMA3", "AVX512F", "AVX512_SKX") if features.get(name)],
        "torch_cpu_paths": {name: os.environ.get(name) for name in TORCH_CPU_PATHS},
    }


def provenance() -> dict[str, Any]:
    """Package versions, the machine (:func:`machine`) and swiptopt's git revision (None
    unless it runs from a checkout)."""
    versions = {}
    for name in _PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return {"versions": versions, "machine": machine(), "git": package_revision()}


# ------------------------------------------------------------------ the store


def result_checksum(key: str, task: str, records: str, extra: str) -> str:
    """SHA-256 of a result row's stored text (key, task, records, extra)."""
    digest = hashlib.sha256()
    for part in (key, task, records, extra):
        digest.update(part.encode("utf-8"))
        digest.update(b"\x00")
    return digest.hexdigest()


def check_new_store_location(path: Path | str) -> None:
    """Refuse, before anything runs, a store path that cannot be created: a directory, a
    parent that is a file, or a directory that is not writable."""
    path = Path(path)
    if path.is_dir():
        raise StoreError(path, "is a directory; give a file name such as results/swiptopt.sqlite")
    if path.exists():
        return
    ancestor = existing_ancestor(path.parent)
    if not ancestor.is_dir():
        raise StoreError(path, f"cannot be created: {str(ancestor)!r} is a file, not a directory")
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise StoreError(path, f"cannot be created: the directory {str(ancestor)!r} is not writable")


class ResultStore:
    """An SQLite file of finished tasks, failed tasks and runs. Safe to reopen, append and
    read while another process writes (WAL journal).

    ``create``: make the file (and its directories) if it does not exist; ``readonly``:
    only read (works on a read-only file); ``timeout_s``: how long a write waits for
    another writer.
    """

    def __init__(self, path: str | Path = DEFAULT_STORE, *, create: bool = True, readonly: bool = False,
                 timeout_s: float | None = None):
        self.path = Path(path)
        self.readonly = readonly
        self.timeout_s = BUSY_TIMEOUT_S if timeout_s is None else float(timeout_s)
        self._checksums = True
        if self.path.is_dir():
            raise StoreError(self.path, "is a directory, not a results store")
        if not self.path.exists():
            if readonly or not create:
                raise ConfigError(f"no results store at {str(self.path)!r}", "store")
            check_new_store_location(self.path)
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise StoreError(self.path, f"cannot create its directory: {exc.strerror}") from None
        elif not readonly:
            if not os.access(self.path, os.R_OK | os.W_OK):
                raise StoreError(self.path, "is read-only here; 'swiptopt table' and 'swiptopt plot' can read it")
            if not os.access(self.path.parent, os.W_OK | os.X_OK):
                raise StoreError(self.path, f"cannot be written: its directory {str(self.path.parent)!r} is not "
                                            "writable (SQLite keeps its write-ahead log beside the file)")
        self._check_header()
        self._db = self._connect()
        try:
            self._check_identity()
        except BaseException:
            self._db.close()
            raise

    # ------------------------------------------------------------ opening

    def _check_header(self) -> None:
        if not self.path.exists():
            return  # a new store
        try:
            with self.path.open("rb") as f:
                head = f.read(len(_SQLITE_MAGIC))
        except OSError as exc:
            raise StoreError(self.path, f"cannot be read: {exc.strerror}") from None
        if head and head != _SQLITE_MAGIC:
            raise StoreError(self.path, "is not an SQLite database, so not a results store")
        if not head and self.readonly:
            raise StoreError(self.path, "is empty: no results in it yet")

    def _connect(self) -> sqlite3.Connection:
        try:
            if not self.readonly:
                db = sqlite3.connect(self.path, timeout=self.timeout_s, isolation_level=None)
            else:
                db = self._connect_readonly()
        except sqlite3.OperationalError as exc:
            raise StoreError(self.path, f"cannot be opened: {exc}") from None
        except sqlite3.DatabaseError as exc:
            raise StoreError(self.path, f"is damaged or not an SQLite database ({exc})") from None
        return db

    def _connect_readonly(self) -> sqlite3.Connection:
        uri = f"file:{quote(str(self.path.resolve()))}"
        db = sqlite3.connect(f"{uri}?mode=ro", uri=True, timeout=self.timeout_s, isolation_level=None)
        try:
            db.execute("SELECT COUNT(*) FROM sqlite_master").fetchone()
            return db
        except sqlite3.OperationalError:
            db.close()
        # A WAL file in a directory we cannot write: SQLite cannot make its shared-memory
        # index. Safe to read as immutable only when no log holds unmerged commits.
        wal = Path(f"{self.path}-wal")
        if wal.exists() and wal.stat().st_size > 0:
            raise StoreError(self.path, f"has unmerged commits in {wal.name} and its directory is not writable; "
                                        "open it once where it can be written")
        return sqlite3.connect(f"{uri}?mode=ro&immutable=1", uri=True, isolation_level=None)

    @contextlib.contextmanager
    def _guard(self, doing: str) -> Iterator[None]:
        """SQLite's errors as one line naming the store and what we were doing."""
        try:
            yield
        except sqlite3.OperationalError as exc:
            message = str(exc)
            if "locked" in message or "busy" in message:
                raise StoreError(self.path, f"locked by another process for more than {self.timeout_s:g} s "
                                            f"while {doing}; try again when that process is done") from None
            if "readonly" in message or "read-only" in message or "unable to open" in message:
                raise StoreError(self.path, f"cannot be written while {doing}: the file or its directory "
                                            f"is read-only ({message})") from None
            raise StoreError(self.path, f"failed while {doing}: {message}") from None
        except sqlite3.DatabaseError as exc:
            raise StoreError(self.path, f"is damaged or not an SQLite database ({exc})") from None

    @contextlib.contextmanager
    def _write(self, doing: str) -> Iterator[sqlite3.Connection]:
        """One write transaction (taken at once, so it waits for other writers up front)."""
        if self.readonly:
            raise StoreError(self.path, f"is open read-only; cannot {doing}")
        with self._guard(doing):
            self._execute_waiting("BEGIN IMMEDIATE")
            try:
                yield self._db
            except BaseException:
                if self._db.in_transaction:  # SQLite may have rolled back already
                    self._db.execute("ROLLBACK")
                raise
            self._db.execute("COMMIT")

    def _tables(self) -> dict[str, list[str]]:
        names = [r[0] for r in self._db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
        return {n: [c[0] for c in self._db.execute("SELECT name FROM pragma_table_info(?) ORDER BY cid", (n,))]
                for n in names if n != "sqlite_sequence"}

    def _identity(self) -> tuple[int, int, dict[str, list[str]]]:
        app = int(self._db.execute("PRAGMA application_id").fetchone()[0])
        version = int(self._db.execute("PRAGMA user_version").fetchone()[0])
        return app, version, self._tables()

    def _check_identity(self) -> None:
        with self._guard("checking it"):
            # one read transaction, so that the mark and the tables come from the same
            # moment: read apart, another process creating the store between the two reads
            # shows an unmarked database holding our tables, which is not a store of ours
            self._execute_waiting("BEGIN")
            try:
                problems = [r[0] for r in self._db.execute("PRAGMA quick_check")]
                app, version, tables = self._identity()
            finally:
                if self._db.in_transaction:  # an error may have ended it already
                    self._db.execute("COMMIT")
            if problems != ["ok"]:
                raise StoreError(self.path, f"is damaged (SQLite's check: {problems[0]})")
        if app == APPLICATION_ID:
            self._check_ours(version, tables)
        elif app == 0 and not tables:
            self._initialise()
        elif app == 0 and {k: tables.get(k) for k in _UNMARKED_COLUMNS} == _UNMARKED_COLUMNS \
                and set(tables) <= {"results", "runs"}:
            self._adopt()
        else:
            what = f"application id {app:#x}" if app else "tables " + ", ".join(sorted(tables))
            raise StoreError(self.path, f"is not a swiptopt results store (an SQLite database with {what}); "
                                        "it is left untouched")
        if not self.readonly:
            with self._guard("opening it for writing"):
                self._execute_waiting("PRAGMA journal_mode=WAL")  # a no-op once it is
            with self._write("opening it for writing"):
                pass  # waits here, before any work, if another process holds the store

    def _execute_waiting(self, sql: str) -> None:
        """Execute ``sql`` (a lock-taking statement), waiting for other processes up to the
        busy timeout even where SQLite does not: it fails at once, without its busy handler,
        when waiting could deadlock (two processes switching a new file to WAL, or upgrading
        read locks, at the same moment), so retry such failures until the timeout."""
        deadline = time.monotonic() + self.timeout_s
        while True:
            try:
                self._db.execute(sql)
                return
            except sqlite3.OperationalError as exc:
                message = str(exc)
                if ("locked" not in message and "busy" not in message) or time.monotonic() >= deadline:
                    raise
                time.sleep(0.02)

    def _check_ours(self, version: int, tables: dict[str, list[str]]) -> None:
        if version != SCHEMA_VERSION:
            newer = "a newer" if version > SCHEMA_VERSION else "an older"
            raise StoreError(self.path, f"was written by {newer} swiptopt (store schema {version}; this version "
                                        f"reads schema {SCHEMA_VERSION})")
        missing = sorted(set(_TABLES) - set(tables))
        if missing:
            raise StoreError(self.path, f"is damaged: the table {missing[0]!r} is missing")

    def _initialise(self) -> None:
        if self.readonly:
            raise StoreError(self.path, "is an empty SQLite database: no results in it yet")
        with self._write("creating it") as db:
            app, _, tables = self._identity()
            if app == 0 and not tables:  # nobody initialised it while we waited for the lock
                for sql in _TABLES.values():
                    db.execute(sql)
                db.execute(f"PRAGMA application_id = {APPLICATION_ID}")
                db.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
        app, version, tables = self._identity()
        if app != APPLICATION_ID:
            raise StoreError(self.path, "was changed by another program while being created")
        self._check_ours(version, tables)

    def _adopt(self) -> None:
        """A store written before stores were marked: read it as it is, or (when writable)
        add the checksums, the failures table and the mark."""
        if self.readonly:
            self._checksums = False
            return
        with self._write("upgrading it to the current store schema") as db:
            app, _, tables = self._identity()
            if app == 0 and "checksum" not in tables.get("results", []):
                db.execute("ALTER TABLE results ADD COLUMN checksum TEXT NOT NULL DEFAULT ''")
                rows = db.execute("SELECT key, task, records, extra FROM results").fetchall()
                for key, task, records, extra in rows:
                    self._decode_result(key, task, records, extra)
                    db.execute("UPDATE results SET checksum = ? WHERE key = ?",
                               (result_checksum(key, task, records, extra), key))
                db.execute(_TABLES["failures"])
                db.execute(f"PRAGMA application_id = {APPLICATION_ID}")
                db.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")

    def close(self) -> None:
        self._db.close()

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # ------------------------------------------------------------ results

    def keys(self) -> set[str]:
        """The keys of the stored results."""
        with self._guard("reading its results"):
            return {row[0] for row in self._db.execute("SELECT key FROM results")}

    def put(self, result: dict[str, Any]) -> None:
        """Commit one finished task (a repeated key is ignored: the first result stands);
        a failure recorded for the same task is dropped."""
        task_text = json.dumps(result["task"], sort_keys=True)
        records, extra = json.dumps(result["records"]), json.dumps(result["extra"])
        key, task = result["key"], result["task"]
        with self._write("storing a result") as db:
            db.execute(
                "INSERT OR IGNORE INTO results VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (key, task["algorithm"], task["seed"], task_text, records, extra, result["duration_s"], time.time(),
                 result_checksum(key, task_text, records, extra)),
            )
            db.execute("DELETE FROM failures WHERE key = ?", (key,))

    def _load(self, what: str, column: str, text: Any) -> Any:
        try:
            return json.loads(text)
        except (TypeError, ValueError):
            raise StoreError(self.path, f"{what} holds invalid JSON in '{column}'") from None

    def _decode_result(self, key: str, task: Any, records: Any, extra: Any) -> dict[str, Any]:
        from swiptopt.benchmark.experiment import Task
        from swiptopt.metrics import EPISODE_METRICS

        other_version = "(a store from another version of swiptopt?)"
        what = f"the result {key[:12]}"
        t, r, e = self._load(what, "task", task), self._load(what, "records", records), self._load(what, "extra", extra)
        if not isinstance(t, dict) or not isinstance(r, list) or not isinstance(e, dict):
            raise StoreError(self.path, f"the result {key[:12]} has a task, records or extra of the wrong kind")
        try:
            matches = Task(**t).key == key
        except TypeError as exc:
            raise StoreError(self.path, f"the result {key[:12]} has a task this version cannot read ({exc}) "
                                        f"{other_version}") from None
        if not matches:
            raise StoreError(self.path, f"the result {key[:12]} does not match its task (damaged)")
        for record in r:
            if not isinstance(record, dict):
                raise StoreError(self.path, f"the result {key[:12]} has a record that is not a table of metrics")
            for metric in EPISODE_METRICS:
                if metric not in record:
                    raise StoreError(self.path, f"the result {key[:12]} has a record without the metric "
                                                f"{metric!r} {other_version}")
        return {"key": key, "task": t, "records": r, "extra": e}

    def get(self, keys: Iterable[str]) -> dict[str, dict[str, Any]]:
        """Stored results by key, for the keys that are stored; each row is checked (JSON,
        metrics, checksum) and a damaged one stops with a :class:`StoreError`."""
        keys = list(keys)
        out: dict[str, dict[str, Any]] = {}
        checksum = "checksum" if self._checksums else "NULL"
        with self._guard("reading its results"):
            for i in range(0, len(keys), 500):
                chunk = keys[i : i + 500]
                rows = self._db.execute(
                    f"SELECT key, task, records, extra, duration_s, {checksum} FROM results "
                    f"WHERE key IN ({','.join('?' * len(chunk))})",
                    chunk,
                ).fetchall()
                for key, task, records, extra, duration, stored_sum in rows:
                    result = self._decode_result(key, task, records, extra)
                    if self._checksums and stored_sum != result_checksum(key, task, records, extra):
                        raise StoreError(self.path, f"the result {key[:12]} is damaged: its content does not "
                                                    "match its checksum")
                    out[key] = {**result, "duration_s": duration}
        return out

    def count(self) -> int:
        with self._guard("counting its results"):
            return int(self._db.execute("SELECT COUNT(*) FROM results").fetchone()[0])

    # ------------------------------------------------------------ failures

    def put_failure(self, failure: dict[str, Any]) -> None:
        """Record a task that failed (``key``, ``task``, ``error``, ``detail``); a later
        failure of the same task replaces it, a result removes it."""
        task = failure["task"]
        with self._write("recording a failed task") as db:
            db.execute(
                "INSERT OR REPLACE INTO failures SELECT ?, ?, ?, ?, ?, ?, ? WHERE NOT EXISTS "
                "(SELECT 1 FROM results WHERE key = ?)",
                (failure["key"], task["algorithm"], task["seed"], json.dumps(task, sort_keys=True), failure["error"],
                 failure.get("detail", ""), time.time(), failure["key"]),
            )

    def failures(self, keys: Iterable[str] | None = None) -> dict[str, str]:
        """The reasons of failed tasks without a result, by key (only ``keys`` if given)."""
        if not self._checksums:  # a store from before failures were recorded
            return {}
        wanted = None if keys is None else set(keys)
        with self._guard("reading its failed tasks"):
            rows = self._db.execute(
                "SELECT key, reason FROM failures WHERE key NOT IN (SELECT key FROM results)").fetchall()
        return {key: str(reason) for key, reason in rows if wanted is None or key in wanted}

    # ------------------------------------------------------------ runs

    def add_run(self, experiment: str, config: dict[str, Any], record: dict[str, Any] | None = None) -> None:
        """Record a run of ``experiment`` with its configuration, and in its provenance the
        experiment's ``record`` (:data:`RUN_RECORD`), when given."""
        origin = provenance()
        if record is not None:
            origin[RUN_RECORD] = record
        row = (experiment, json.dumps(config, sort_keys=True), json.dumps(origin), time.time())
        with self._write("recording the run") as db:
            db.execute("INSERT INTO runs (experiment, config, provenance, started) VALUES (?, ?, ?, ?)", row)

    def runs(self) -> list[dict[str, Any]]:
        """The latest run of each experiment name, oldest first."""
        with self._guard("reading its runs"):
            rows = self._db.execute(
                "SELECT experiment, config, provenance, started FROM runs WHERE id IN "
                "(SELECT MAX(id) FROM runs GROUP BY experiment) ORDER BY id"
            ).fetchall()
        out = []
        for name, config, prov, started in rows:
            where = f"the run of {name!r}"
            out.append({"experiment": name, "config": self._load(where, "config", config),
                        "provenance": self._load(where, "provenance", prov), "started": started})
        return out

    def experiments(self, name: str | None = None) -> list[Any]:
        """The :class:`~swiptopt.benchmark.experiment.Experiment` of the latest run of each
        experiment (or of ``name``), rebuilt from the stored data alone
        (:meth:`~swiptopt.benchmark.experiment.Experiment.from_stored`: no plugin or entry
        point is loaded, nothing the store names is imported or called) and otherwise
        validated like a new one: a stored configuration this version does not accept is a
        :class:`StoreError`."""
        from swiptopt.benchmark.experiment import Experiment

        out = []
        for run in self.runs():
            if name is not None and run["experiment"] != name:
                continue
            config = run["config"]
            if not isinstance(config, dict):
                raise StoreError(self.path, f"the run of {run['experiment']!r} has a configuration that is not a table")
            origin = run["provenance"]
            record = origin.get(RUN_RECORD) if isinstance(origin, dict) else None
            try:
                out.append(Experiment.from_stored(config, record))
            except ConfigError as exc:
                raise StoreError(self.path, f"the run of {run['experiment']!r} has a configuration this version "
                                            f"does not accept: {exc}") from None
        return out
