"""Worker processes: one native thread each, gone with their parent, fresh processes that
report what happened to them."""

import importlib.util
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from swiptopt.benchmark import processes
from swiptopt.benchmark.processes import limit_native_threads, qualified_name, run_in_fresh_process

# skip without OMPL, without loading it into the test process
needs_ompl = pytest.mark.skipif(importlib.util.find_spec("ompl") is None, reason="needs OMPL")
linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")


# targets for run_in_fresh_process (module-level, so the child can import them)

def double(x):
    return 2 * x


def fail(message):
    raise ValueError(message)


def segfault(_):
    import ctypes

    ctypes.string_at(0)  # reads address 0: SIGSEGV


def chatty(x):
    print("noise on stdout")
    return x


def thread_report(_):
    from threadpoolctl import threadpool_info

    return {"pools": [p["num_threads"] for p in threadpool_info()], "omp": os.environ.get("OMP_NUM_THREADS")}


def ompl_draws(task):
    from ompl import util as ou

    from swiptopt.benchmark.runner import seed_ompl

    seed_ompl(task)
    rng = ou.RNG()
    return [ou.RNG.getSeed()] + [rng.uniform01() for _ in range(3)]


# ------------------------------------------------------------------ helpers

def process_tree() -> dict[int, list[int]]:
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    ppid = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(entry))
    return children


def descendants(pid: int) -> set[int]:
    tree, found, stack = process_tree(), set(), [pid]
    while stack:
        for child in tree.get(stack.pop(), []):
            if child not in found:
                found.add(child)
                stack.append(child)
    return found


def running(pid: int) -> bool:
    """Alive and not a zombie (an orphan's zombie waits for init to reap it)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def wait_until_gone(pids: set[int], seconds: float = 10.0) -> set[int]:
    deadline = time.monotonic() + seconds  # a wait limit, not a speed check
    while time.monotonic() < deadline and any(running(p) for p in pids):
        time.sleep(0.1)
    return {p for p in pids if running(p)}


def kill_all(pids):
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass


# ------------------------------------------------------------------ tests

def test_fresh_process_returns_value_error_or_signal():
    assert run_in_fresh_process(qualified_name(double), 21).value == 42
    failed = run_in_fresh_process(qualified_name(fail), "no path to cell 7")
    assert failed.value is None and failed.error == "ValueError: no path to cell 7"
    assert "Traceback" in failed.detail and "fail" in failed.detail
    crashed = run_in_fresh_process(qualified_name(segfault), None)
    assert crashed.value is None and crashed.error == "the task's process was killed by SIGSEGV"
    assert "segfault" in crashed.detail  # faulthandler's traceback names the function
    # what a task prints does not spoil the result
    assert run_in_fresh_process(qualified_name(chatty), [1, 2]).value == [1, 2]


def test_fresh_process_runs_one_native_thread_per_pool():
    report = run_in_fresh_process(qualified_name(thread_report), None, modules=["sklearn.cluster", "numpy"]).value
    assert report["omp"] == "1"
    assert report["pools"] and set(report["pools"]) == {1}


def test_limit_native_threads_limits_and_restores():
    import sklearn.cluster  # noqa: F401  loads OpenMP
    from threadpoolctl import threadpool_info

    torch = pytest.importorskip("torch")  # sizes its pool by OpenMP's: both must come back
    torch.set_num_threads(2)
    before, torch_before = [p["num_threads"] for p in threadpool_info()], torch.get_num_threads()
    with limit_native_threads():
        assert {p["num_threads"] for p in threadpool_info()} == {1} and torch.get_num_threads() == 1
    assert [p["num_threads"] for p in threadpool_info()] == before and torch.get_num_threads() == torch_before == 2


@needs_ompl
def test_ompl_seed_is_set_from_the_task_in_a_fresh_process():
    task = {"seed": 2001, "settings": {"tour_costs": "ompl"}}
    first = run_in_fresh_process(qualified_name(ompl_draws), task).value
    again = run_in_fresh_process(qualified_name(ompl_draws), task).value
    other = run_in_fresh_process(qualified_name(ompl_draws), {**task, "seed": 2002}).value
    assert first[0] == 2002  # the task's seed shifted past OMPL's reserved 0
    assert first == again  # the same draws in every fresh process
    assert other[1:] != first[1:]


_ORPHAN_MAKER = """
import sys, time
from swiptopt.benchmark.processes import run_in_fresh_process
run_in_fresh_process("time:sleep", 120)
"""


@linux_only
def test_fresh_process_dies_with_its_parent():
    parent = subprocess.Popen([sys.executable, "-c", _ORPHAN_MAKER])
    try:
        deadline = time.monotonic() + 60  # a wait limit for the child to start
        while time.monotonic() < deadline and not descendants(parent.pid):
            time.sleep(0.1)
        children = descendants(parent.pid)
        assert children, "the fresh process did not start"
        time.sleep(1.0)  # let it reach its parent watch
        parent.kill()
        parent.wait()
        assert not wait_until_gone(children)
    finally:
        parent.kill()
        kill_all(descendants(parent.pid))


@linux_only
def test_die_with_parent_watchdog_catches_a_parent_already_gone():
    # the child checks its parent at once: started under a parent that is already dead,
    # it exits with ORPHAN_EXIT instead of running on
    code = ("import os, sys; from swiptopt.benchmark.processes import die_with_parent; "
            "die_with_parent(os.getppid() + 1 if os.getppid() != 1 else 2); print('still here')")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == processes.ORPHAN_EXIT and "still here" not in result.stdout


def test_qualified_name_round_trips():
    assert qualified_name(double) == f"{__name__}:double"
    assert processes._resolve(qualified_name(double)) is double
    assert json.loads(json.dumps(run_in_fresh_process("math:sqrt", 16.0).value)) == 4.0
