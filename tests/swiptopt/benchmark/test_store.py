"""The results store: each damaged, foreign, locked or read-only case either works correctly
or stops with one line naming the store (exit 2), never losing, duplicating or overwriting."""

import ctypes
import json
import os
import shutil
import sqlite3
import subprocess
import sys
import threading
import time
import types

import pytest

from swiptopt.benchmark import store as store_module
from swiptopt.benchmark.experiment import Experiment
from swiptopt.benchmark.runner import execute
from swiptopt.benchmark.store import (
    APPLICATION_ID,
    ResultStore,
    StoreError,
    checkout_revision,
    result_checksum,
)
from swiptopt.cli import main

SMALL = {
    "name": "small",
    "layouts": 3,
    "episodes": 1,
    "scenario": {"preset": "paper", "n_nodes": 6},
    "algorithms": {"random": {}, "greedy": {}},
}
SMALL_TOML = """
name = "small"
layouts = 3
episodes = 1
[scenario]
preset = "paper"
n_nodes = 6
[algorithms.random]
[algorithms.greedy]
"""


@pytest.fixture(scope="module")
def good_store(tmp_path_factory):
    """A complete store of SMALL and its Markdown table."""
    path = tmp_path_factory.mktemp("good") / "good.sqlite"
    with ResultStore(path) as s:
        report = execute(Experiment.from_dict(SMALL), s, workers=1)
        assert report.ran == 6 and not report.failures
    return path


def table_of(path, capsys):
    """(exit code, stdout, stderr lines) of `swiptopt table --format markdown`."""
    code = main(["table", str(path), "--format", "markdown"])
    out, err = capsys.readouterr()
    return code, out, [line for line in err.splitlines() if line.strip()]


def assert_one_line_naming(code, err_lines, path, *words):
    assert code == 2
    assert len(err_lines) == 1, err_lines
    assert str(path) in err_lines[0]
    for word in words:
        assert word in err_lines[0]


def copy(good, tmp_path, name):
    path = tmp_path / name
    shutil.copy(good, path)
    return path


def test_a_new_store_is_marked_as_ours(good_store):
    db = sqlite3.connect(good_store)
    assert db.execute("PRAGMA application_id").fetchone()[0] == APPLICATION_ID
    assert db.execute("PRAGMA user_version").fetchone()[0] == store_module.SCHEMA_VERSION
    assert db.execute("SELECT COUNT(*) FROM results").fetchone()[0] == 6


@pytest.mark.parametrize("damage", ["truncated", "header_only", "zeroed_tail", "not_sqlite"])
def test_damaged_files_stop_with_one_line_and_stay_untouched(good_store, tmp_path, capsys, damage):
    path = copy(good_store, tmp_path, f"{damage}.sqlite")
    size = path.stat().st_size
    if damage == "truncated":
        os.truncate(path, size // 2)
    elif damage == "header_only":
        os.truncate(path, 50)
    elif damage == "zeroed_tail":
        with path.open("r+b") as f:
            f.seek(size - 4096)
            f.write(b"\0" * 4096)
    else:
        path.write_bytes(b"name,value\n1,2\n" * 100)
    before = path.read_bytes()
    code, _, err = table_of(path, capsys)
    assert_one_line_naming(code, err, path)
    exp = tmp_path / "small.toml"
    exp.write_text(SMALL_TOML)
    code = main(["run", str(exp), "--store", str(path), "--workers", "1"])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert_one_line_naming(code, err, path)
    assert path.read_bytes() == before  # never written to


def test_garbage_anywhere_gives_the_right_table_or_one_line(good_store, tmp_path, capsys):
    code, reference, _ = table_of(good_store, capsys)
    assert code == 0
    size = good_store.stat().st_size
    outcomes = set()
    for i, offset in enumerate(range(512, size - 64, size // 23)):
        path = copy(good_store, tmp_path, f"garbage{i}.sqlite")
        with path.open("r+b") as f:
            f.seek(offset)
            f.write(bytes((37 * k + offset) % 256 for k in range(64)))
        code, out, err = table_of(path, capsys)
        if code == 0:
            assert out == reference  # damage where nothing is read: the table is right
        else:
            assert_one_line_naming(code, err, path)
        outcomes.add(code)
    assert 2 in outcomes  # some of the damage was caught


def test_a_changed_digit_in_a_result_is_caught_by_its_checksum(good_store, tmp_path, capsys):
    path = copy(good_store, tmp_path, "digit.sqlite")
    data = bytearray(path.read_bytes())
    at = data.index(b'"mission_time_s": ') + len(b'"mission_time_s": ')  # a metric of a record
    assert chr(data[at]).isdigit()
    data[at] = ord("9") if data[at] != ord("9") else ord("8")
    path.write_bytes(bytes(data))
    code, out, err = table_of(path, capsys)  # SQLite sees nothing wrong; the checksum does
    assert_one_line_naming(code, err, path, "checksum")


def _edit_row(path, column, transform, fix_checksum):
    db = sqlite3.connect(path)
    key, task, records, extra = db.execute("SELECT key, task, records, extra FROM results LIMIT 1").fetchone()
    row = {"task": task, "records": records, "extra": extra}
    row[column] = transform(row[column])
    checksum = result_checksum(key, row["task"], row["records"], row["extra"]) if fix_checksum else "0"
    with db:
        db.execute(f"UPDATE results SET {column} = ?, checksum = ? WHERE key = ?", (row[column], checksum, key))
    db.close()
    return key


def _drop_metric(text):
    records = json.loads(text)
    del records[0]["data_bits"]
    return json.dumps(records)


@pytest.mark.parametrize(
    "column, transform, words",
    [
        ("records", lambda t: t[:-5], ["invalid JSON", "records"]),
        ("extra", lambda t: "{not json", ["invalid JSON", "extra"]),
        ("records", _drop_metric, ["data_bits", "another version"]),
        ("task", lambda t: json.dumps({**json.loads(t), "seed": 99}), ["does not match"]),
    ],
)
def test_damaged_rows_stop_with_one_line(good_store, tmp_path, capsys, column, transform, words):
    path = copy(good_store, tmp_path, "row.sqlite")
    key = _edit_row(path, column, transform, fix_checksum=True)
    code, _, err = table_of(path, capsys)
    assert_one_line_naming(code, err, path, key[:12], *words)


def test_a_run_config_from_another_version_stops_with_one_line(good_store, tmp_path, capsys):
    path = copy(good_store, tmp_path, "config.sqlite")
    db = sqlite3.connect(path)
    config = json.loads(db.execute("SELECT config FROM runs").fetchone()[0])
    with db:
        db.execute("UPDATE runs SET config = ?", (json.dumps({**config, "budget_hours": 3}),))
    db.close()
    code, _, err = table_of(path, capsys)
    assert_one_line_naming(code, err, path, "'small'", "budget_hours")
    # a stored configuration that is invalid now is refused like a new one
    with sqlite3.connect(path) as db:
        db.execute("UPDATE runs SET config = ?", (json.dumps({**config, "layouts": 0}),))
    code, _, err = table_of(path, capsys)
    assert_one_line_naming(code, err, path, "layouts")


def test_a_foreign_sqlite_file_is_refused_and_left_untouched(tmp_path, capsys):
    path = tmp_path / "foreign.sqlite"
    db = sqlite3.connect(path)
    with db:
        db.execute("CREATE TABLE results (id INTEGER PRIMARY KEY, value TEXT)")
        db.execute("INSERT INTO results (value) VALUES ('theirs')")
    db.close()
    before = path.read_bytes()
    code, _, err = table_of(path, capsys)
    assert_one_line_naming(code, err, path, "not a swiptopt results store")
    exp = tmp_path / "small.toml"
    exp.write_text(SMALL_TOML)
    code = main(["run", str(exp), "--store", str(path), "--workers", "1"])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert_one_line_naming(code, err, path, "not a swiptopt results store")
    assert path.read_bytes() == before
    # another program's application id is refused the same way
    marked = tmp_path / "marked.sqlite"
    with sqlite3.connect(marked) as db:
        db.execute("PRAGMA application_id = 1234")
        db.execute("CREATE TABLE t (x)")
    with pytest.raises(StoreError, match="application id 0x4d2"):
        ResultStore(marked)


def test_a_store_from_a_newer_schema_is_refused(good_store, tmp_path):
    path = copy(good_store, tmp_path, "newer.sqlite")
    with sqlite3.connect(path) as db:
        db.execute(f"PRAGMA user_version = {store_module.SCHEMA_VERSION + 1}")
    with pytest.raises(StoreError, match="newer swiptopt"):
        ResultStore(path, readonly=True)


def test_an_unmarked_store_of_the_previous_layout_is_adopted(good_store, tmp_path, capsys):
    # the layout swiptopt wrote before stores were marked: no mark, no checksums, no failures
    path = copy(good_store, tmp_path, "old.sqlite")
    code, reference, _ = table_of(good_store, capsys)
    db = sqlite3.connect(path)
    with db:
        db.execute("PRAGMA application_id = 0")
        db.execute("PRAGMA user_version = 0")
        db.execute("DROP TABLE failures")
        db.execute("ALTER TABLE results DROP COLUMN checksum")
    db.close()
    assert table_of(path, capsys)[1] == reference  # read as it is
    with ResultStore(path) as s:  # opened for writing: upgraded in place
        assert s.count() == 6 and s.failures() == {}
    db = sqlite3.connect(path)
    assert db.execute("PRAGMA application_id").fetchone()[0] == APPLICATION_ID
    sums = db.execute("SELECT key, task, records, extra, checksum FROM results").fetchall()
    assert all(c == result_checksum(k, t, r, e) for k, t, r, e, c in sums)
    db.close()
    assert table_of(path, capsys)[1] == reference


_LOCKER = """
import sqlite3, sys, time
db = sqlite3.connect(sys.argv[1], isolation_level=None)
db.execute("BEGIN IMMEDIATE")
print("locked", flush=True)
time.sleep(120)
"""


def test_a_store_locked_past_the_busy_timeout_stops_with_one_line(good_store, tmp_path, capsys, monkeypatch):
    path = copy(good_store, tmp_path, "locked.sqlite")
    exp = tmp_path / "small.toml"
    exp.write_text(SMALL_TOML)
    locker = subprocess.Popen([sys.executable, "-c", _LOCKER, str(path)], stdout=subprocess.PIPE, text=True)
    try:
        assert locker.stdout.readline().strip() == "locked"
        monkeypatch.setattr(store_module, "BUSY_TIMEOUT_S", 0.5)
        code = main(["run", str(exp), "--store", str(path), "--workers", "1"])
        err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
        assert_one_line_naming(code, err, path, "locked by another process", "0.5 s")
        # readers are not blocked by a writer
        code, out, _ = table_of(path, capsys)
        assert code == 0 and "| random |" in out
    finally:
        locker.kill()
        locker.wait()


def test_two_runs_on_one_store_at_once_both_finish_without_loss_or_duplicates(tmp_path):
    exp = tmp_path / "shared.toml"
    exp.write_text(SMALL_TOML.replace("layouts = 3", "layouts = 6"))
    path = tmp_path / "shared.sqlite"
    command = [sys.executable, "-m", "swiptopt.cli", "run", str(exp), "--store", str(path), "--workers", "1",
               "--format", "csv"]
    runs = [subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outputs = [run.communicate() for run in runs]
    for run, (out, err) in zip(runs, outputs):
        assert run.returncode == 0, err
        assert "tasks missing" not in err and "random" in out
    assert outputs[0][0] == outputs[1][0]  # both print the same, complete table
    expected = {t.key for t in Experiment.from_toml(exp).tasks()}
    with sqlite3.connect(path) as db:
        keys = [k for (k,) in db.execute("SELECT key FROM results")]
        assert db.execute("SELECT COUNT(*) FROM runs").fetchone()[0] == 2
    assert len(keys) == len(set(keys)) and set(keys) == expected


def _without_root_override():
    """Run a child without root's power to ignore file permissions (no-op for other users),
    so read-only files and directories are read-only for it too."""
    if os.geteuid() != 0:
        return
    libc = ctypes.CDLL(None, use_errno=True)
    for capability in (1, 2):  # CAP_DAC_OVERRIDE, CAP_DAC_READ_SEARCH
        if libc.prctl(24, capability, 0, 0, 0) != 0:  # PR_CAPBSET_DROP
            raise OSError(ctypes.get_errno(), "cannot drop capability")


def cli_unprivileged(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "swiptopt.cli", *args], capture_output=True, text=True, cwd=cwd,
                          preexec_fn=_without_root_override)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="drops Linux capabilities when root")
def test_read_only_places(good_store, tmp_path, capsys):
    code, reference, _ = table_of(good_store, capsys)
    readonly_file = copy(good_store, tmp_path, "ro.sqlite")
    readonly_file.chmod(0o444)
    closed = tmp_path / "closed"
    closed.mkdir()
    inside = copy(good_store, closed, "s.sqlite")
    closed.chmod(0o555)
    exp = tmp_path / "small.toml"
    exp.write_text(SMALL_TOML)
    try:
        # table works on a read-only file, and on a store in a read-only directory
        for path in (readonly_file, inside):
            result = cli_unprivileged("table", str(path), "--format", "markdown")
            assert result.returncode == 0, result.stderr
            assert result.stdout == reference
        # writing is refused in one line, before any task
        for store, words in ((closed / "new.sqlite", "not writable"), (readonly_file, "read-only"),
                             (inside, "not writable")):
            result = cli_unprivileged("run", str(exp), "--store", str(store), "--workers", "1")
            lines = result.stderr.strip().splitlines()
            assert result.returncode == 2 and len(lines) == 1, result.stderr
            assert str(store) in lines[0] and words in lines[0]
        assert not (closed / "new.sqlite").exists()
        assert sorted(p.name for p in closed.iterdir()) == ["s.sqlite"]
    finally:
        closed.chmod(0o755)


def test_a_store_under_a_file_or_at_a_directory_is_refused(tmp_path, capsys):
    exp = tmp_path / "small.toml"
    exp.write_text(SMALL_TOML)
    for store, words in ((exp / "s.sqlite", "is a file, not a directory"), (tmp_path, "directory")):
        code = main(["run", str(exp), "--store", str(store), "--workers", "1"])
        err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
        assert code == 2 and len(err) == 1 and words in err[0], err


ORDER_TOML = """
name = "order"
layouts = 1
episodes = 1
baseline = "random"
[scenario]
preset = "paper"
n_nodes = 4
[sweep]
split_ratio = [0.3, 0.5]
n_nodes = [4, 5]
[algorithms.random]
[algorithms.greedy]
"""


def test_table_prints_a_stored_run_in_the_order_the_run_printed_it(tmp_path, capsys):
    """A stored configuration's keys are sorted; the run's record keeps the experiment's
    order of algorithms and sweep keys, so `table` prints what `run` printed."""
    exp = tmp_path / "order.toml"
    exp.write_text(ORDER_TOML)
    store = tmp_path / "s.sqlite"
    assert main(["run", str(exp), "--store", str(store), "--workers", "1", "--format", "markdown"]) == 0
    printed = capsys.readouterr().out
    assert printed.index("| split_ratio=0.3, n_nodes=4 | random |") < printed.index(
        "| split_ratio=0.3, n_nodes=4 | greedy |")
    assert main(["table", str(store), "--format", "markdown"]) == 0
    assert capsys.readouterr().out == printed
    with ResultStore(store, readonly=True) as s:
        (stored,) = s.experiments()
    assert list(stored.algorithms) == ["random", "greedy"] and list(stored.sweep) == ["split_ratio", "n_nodes"]
    assert stored == Experiment.from_toml(exp)


def test_a_run_recorded_without_its_order_reads_in_the_stored_order(tmp_path):
    experiment = Experiment.from_toml(_write_order(tmp_path))
    with ResultStore(tmp_path / "s.sqlite") as s:
        s.add_run("order", json.loads(json.dumps(experiment.to_dict())))  # as runs were recorded before
        (stored,) = s.experiments()
    assert list(stored.algorithms) == ["greedy", "random"] and list(stored.sweep) == ["n_nodes", "split_ratio"]
    assert {t.key for t in stored.tasks()} == {t.key for t in experiment.tasks()}


def _write_order(directory):
    path = directory / "order.toml"
    path.write_text(ORDER_TOML)
    return path


def test_failures_are_kept_apart_and_cleared_by_a_result(tmp_path):
    exp = Experiment.from_dict(SMALL)
    task = exp.tasks()[0].to_dict()
    key = exp.tasks()[0].key
    with ResultStore(tmp_path / "f.sqlite") as s:
        s.put_failure({"key": key, "task": task, "error": "ValueError: boom", "detail": "trace"})
        s.put_failure({"key": key, "task": task, "error": "ValueError: boom again", "detail": "trace"})
        assert s.failures() == {key: "ValueError: boom again"} and s.count() == 0
        assert s.keys() == set()  # a failure is not a result: a rerun retries the task
        execute(exp, s, workers=1)
        assert s.failures() == {} and s.count() == 6
        s.put_failure({"key": key, "task": task, "error": "late", "detail": ""})
        assert s.failures() == {}  # a task with a result is not recorded as failed


# ------------------------------------------------------------------ provenance

def _git(*args, cwd):
    env = dict(os.environ, GIT_CONFIG_NOSYSTEM="1", HOME=str(cwd))
    return subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True, check=True, env=env).stdout.strip()


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git to build the repositories")
def test_checkout_revision_reads_what_git_reports(tmp_path):
    repo = tmp_path / "repo"
    repo.mkdir()
    _git("init", "-q", "-b", "main", cwd=repo)
    for message in ("one", "two"):
        _git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "--allow-empty", "-m", message, cwd=repo)
    assert checkout_revision(repo) == _git("rev-parse", "HEAD", cwd=repo)
    _git("pack-refs", "--all", cwd=repo)  # the branch now lives only in packed-refs
    assert not (repo / ".git" / "refs" / "heads" / "main").exists()
    assert checkout_revision(repo) == _git("rev-parse", "HEAD", cwd=repo)
    _git("worktree", "add", "-q", "--detach", str(tmp_path / "wt"), "HEAD~1", cwd=repo)  # a .git file
    assert checkout_revision(tmp_path / "wt") == _git("rev-parse", "HEAD~1", cwd=repo)
    assert checkout_revision(tmp_path) is None


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git to build the repository")
def test_run_does_not_run_git_in_the_working_directory(tmp_path):
    evil = tmp_path / "evil"
    evil.mkdir()
    marker = tmp_path / "MARKER"
    _git("init", "-q", cwd=evil)
    _git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "--allow-empty", "-m", "x", cwd=evil)
    _git("config", "core.fsmonitor", f"touch {marker}", cwd=evil)
    (evil / "small.toml").write_text(SMALL_TOML.replace("layouts = 3", "layouts = 1"))
    result = subprocess.run([sys.executable, "-m", "swiptopt.cli", "run", "small.toml", "--store", "s.sqlite",
                             "--workers", "1"], cwd=evil, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert not marker.exists()  # git's fsmonitor hook never ran
    with ResultStore(evil / "s.sqlite", readonly=True) as s:
        recorded = s.runs()[0]["provenance"]
    import swiptopt

    assert recorded["git"] == store_module.package_revision()
    assert recorded["git"] != _git("rev-parse", "HEAD", cwd=evil)
    assert recorded["versions"]["swiptopt"] and recorded["versions"]["numpy"]
    # the machine beside the versions: what the same-numbers guarantee depends on
    import platform

    assert recorded["machine"]["architecture"] == platform.machine()
    if os.path.exists("/proc/cpuinfo"):
        with open("/proc/cpuinfo") as info:
            names = [line.split(":", 1)[1].strip() for line in info if line.startswith("model name")]
        assert recorded["machine"]["cpu"] == (names[0] if names else recorded["machine"]["cpu"])
    root = os.path.dirname(os.path.dirname(os.path.abspath(swiptopt.__file__)))
    if os.path.exists(os.path.join(root, ".git")):
        assert recorded["git"] == _git("rev-parse", "HEAD", cwd=root)


_OPENER = """
import sys, time
from swiptopt.benchmark.store import ResultStore
start = float(sys.argv[2])
time.sleep(max(0.0, start - time.time()))  # every process opens the new file at once
with ResultStore(sys.argv[1]) as s:
    print(s.count())
"""


def test_many_processes_opening_one_new_store_at_once_all_succeed(tmp_path):
    # switching a new file to WAL deadlocks in SQLite when two processes do it at once; the
    # loser must wait and retry like any other writer, not fail with "locked"
    for attempt in range(3):
        path = tmp_path / f"new{attempt}.sqlite"
        start = time.time() + 1.5
        procs = [subprocess.Popen([sys.executable, "-c", _OPENER, str(path), str(start)], stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True) for _ in range(6)]
        results = [p.communicate(timeout=120) for p in procs]
        assert [p.returncode for p in procs] == [0] * 6, [err for _, err in results if err]
        assert [out.strip() for out, _ in results] == ["0"] * 6


class _CreatedMeanwhile:
    """A connection on which, as soon as the new store's mark has been read, another process
    (a thread with its own connection here) creates the store, and the reader goes on only
    once that creation has committed or is stuck waiting for the reader's lock."""

    def __init__(self, db, path):
        self.db, self.path, self.thread, self.error = db, path, None, None

    def _create(self):
        try:
            ResultStore(self.path, timeout_s=30.0).close()
        except BaseException as exc:  # reported by the test
            self.error = exc

    def execute(self, sql, *args):
        cursor = self.db.execute(sql, *args)
        if sql == "PRAGMA application_id" and self.thread is None:
            row = cursor.fetchone()  # read before the other process writes
            self.thread = threading.Thread(target=self._create)
            self.thread.start()
            self.thread.join(timeout=1.0)  # committed, or waiting for our read lock
            return types.SimpleNamespace(fetchone=lambda: row)
        return cursor

    def __getattr__(self, name):
        return getattr(self.db, name)


def test_a_store_created_by_another_process_while_being_checked_is_opened(tmp_path, monkeypatch):
    # the mark and the tables are read in one transaction: read apart, the other process's
    # creation landing between the two reads showed an unmarked database with our tables,
    # refused as "not a swiptopt results store" (seen in CI with six processes at once)
    path = tmp_path / "new.sqlite"
    real_connect = ResultStore._connect
    proxies = []

    def connect(self):
        if proxies:  # the other process's own connection
            return real_connect(self)
        proxies.append(_CreatedMeanwhile(real_connect(self), path))
        return proxies[-1]

    monkeypatch.setattr(ResultStore, "_connect", connect)
    with ResultStore(path, timeout_s=30.0) as s:
        assert s.count() == 0
    monkeypatch.undo()
    proxies[0].thread.join(timeout=30.0)
    assert proxies[0].error is None and not proxies[0].thread.is_alive()
    with ResultStore(path) as s:
        assert s.count() == 0


class _FailingFirst:
    """A connection whose first ``fails`` executions of ``sql`` raise SQLite's immediate
    "database is locked" (what a deadlock-avoiding SQLite returns without waiting)."""

    def __init__(self, db, sql, fails):
        self.db, self.sql, self.fails, self.calls = db, sql, fails, 0

    def execute(self, sql, *args):
        if sql == self.sql:
            self.calls += 1
            if self.calls <= self.fails:
                raise sqlite3.OperationalError("database is locked")
        return self.db.execute(sql, *args)

    def __getattr__(self, name):
        return getattr(self.db, name)


def test_an_immediate_lock_failure_is_retried_until_the_busy_timeout(tmp_path):
    with ResultStore(tmp_path / "s.sqlite", timeout_s=5.0) as s:
        real = s._db
        s._db = _FailingFirst(real, "BEGIN IMMEDIATE", 3)
        s._execute_waiting("BEGIN IMMEDIATE")  # retried past three immediate failures
        assert s._db.calls == 4 and real.in_transaction
        real.execute("ROLLBACK")
        s.timeout_s = 0.1
        s._db = _FailingFirst(real, "BEGIN IMMEDIATE", 10**9)
        started = time.monotonic()
        with pytest.raises(sqlite3.OperationalError, match="locked"):
            s._execute_waiting("BEGIN IMMEDIATE")  # gives up at the timeout, not before
        assert time.monotonic() - started >= 0.1 and s._db.calls > 1
        s._db = real


def test_the_shipped_stores_are_whole_files_that_reading_leaves_alone():
    """Each store in benchmarks/stores/ keeps all its rows in the one file git tracks
    (SQLite's rollback journal, not a write-ahead log that a clone would lack), so reading it
    in a fresh clone neither misses a row nor leaves a -wal or -shm file beside it."""
    from pathlib import Path

    stores = sorted((Path(__file__).parents[3] / "benchmarks" / "stores").glob("*.sqlite"))
    assert len(stores) >= 12
    for path in stores:
        db = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
        try:
            assert db.execute("PRAGMA journal_mode").fetchone()[0] == "delete", path.name
            assert db.execute("PRAGMA integrity_check").fetchone()[0] == "ok", path.name
        finally:
            db.close()
        with ResultStore(path, create=False, readonly=True) as stored:
            assert stored.count() == len(stored.get(stored.keys())) > 0, path.name
        assert not path.with_name(path.name + "-wal").exists() and not path.with_name(path.name + "-shm").exists()
