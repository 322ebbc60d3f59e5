"""Worker processes that behave: one native thread each, gone when their parent dies, and
fresh processes for work that must not share one.

- :func:`limit_native_threads`: one thread in every native pool (OpenMP, BLAS, torch) of
  this process. Every worker calls it (:func:`prepare_worker`): scikit-learn's k-means
  otherwise starts an OpenMP thread per core in every worker, and N workers on N cores
  fight over the cores.
- :func:`die_with_parent`: the process exits when its parent does (Linux
  ``PR_SET_PDEATHSIG``, plus a watchdog thread that polls the parent's pid everywhere), so a
  killed ``swiptopt run`` leaves no worker behind.
- :func:`run_in_fresh_process`: call a function in a new Python process (started with
  ``subprocess``, so it works from any worker, Dask's daemonic ones included) and get its
  value back, or its exception, or how the process died: a segfault becomes an outcome
  instead of taking the worker down.
"""

from __future__ import annotations

import contextlib
import ctypes
import faulthandler
import importlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

#: Environment variables that size native thread pools when a library loads later.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
                    "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS", "NUMBA_NUM_THREADS")
#: How often the watchdog looks at the parent, s.
PARENT_POLL_S = 0.5
#: Exit status of a worker that outlived its parent.
ORPHAN_EXIT = 70

_PR_SET_PDEATHSIG = 1
_watchdog_for: tuple[int, int] | None = None
_watchdog_lock = threading.Lock()


class NativeThreadLimit(contextlib.AbstractContextManager):
    """One thread per native pool loaded in this process; :meth:`restore` (or leaving a
    ``with`` block) gives the pools their previous sizes back."""

    def __init__(self) -> None:
        # torch's size is read before threadpoolctl limits the OpenMP pool torch sizes itself
        # by, and restored first, so that the OpenMP pools get their own sizes back last
        self._torch: tuple[Any, int] | None = None
        torch = sys.modules.get("torch")
        if torch is not None:  # torch's intra-op pool is its own, not only OpenMP's
            self._torch = (torch, torch.get_num_threads())
        try:
            from threadpoolctl import threadpool_limits
        except ImportError:  # the bench extra; scikit-learn brings it too
            self._pools = None
        else:
            self._pools = threadpool_limits(limits=1)
        if torch is not None:
            torch.set_num_threads(1)

    def restore(self) -> None:
        if self._torch is not None:
            torch, threads = self._torch
            torch.set_num_threads(threads)
        if self._pools is not None:
            self._pools.restore_original_limits()

    def __exit__(self, *exc: Any) -> None:
        self.restore()


def limit_native_threads() -> NativeThreadLimit:
    """Limit every native thread pool already loaded in this process (OpenMP, BLAS, torch
    when imported) to one thread.

    Pools of libraries loaded later are not covered: import them first (workers also set
    :data:`THREAD_VARIABLES`, which those libraries read when they load). Extend this
    function when a new kind of pool appears. Returns the limit, which is also a context
    manager that restores the previous sizes on exit.
    """
    return NativeThreadLimit()


def import_modules(names: Iterable[str]) -> None:
    """Import ``names`` now (a module that is not installed is skipped: the task that needs
    it reports that)."""
    for name in names:
        try:
            importlib.import_module(name)
        except ImportError:
            pass


def prepare_worker(modules: Iterable[str] = ()) -> None:
    """Make this process a good worker: native libraries loaded later start with one
    thread, torch's CPU paths are those every x86-64 CPU with AVX2 shares
    (:func:`swiptopt.fpmath.pin_torch_cpu_paths`), ``modules`` are imported, and every loaded
    pool is limited to one thread."""
    from swiptopt.fpmath import pin_torch_cpu_paths

    for variable in THREAD_VARIABLES:
        os.environ[variable] = "1"
    pin_torch_cpu_paths()
    import_modules(modules)
    limit_native_threads()


def die_with_parent(parent_pid: int | None = None) -> None:
    """Make this process exit as soon as ``parent_pid`` (default: the current parent) dies.

    On Linux the kernel sends SIGKILL when the parent exits (``PR_SET_PDEATHSIG``); a
    daemon thread also polls ``os.getppid()`` every :data:`PARENT_POLL_S` seconds, which
    covers other platforms and a parent that died before this call.
    """
    global _watchdog_for
    parent_pid = os.getppid() if parent_pid is None else parent_pid
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):
            pass  # the watchdog still covers it
    if os.getppid() != parent_pid:
        os._exit(ORPHAN_EXIT)
    with _watchdog_lock:
        # keyed by our own pid too: a forked child inherits this variable but not the thread
        if _watchdog_for == (os.getpid(), parent_pid):
            return
        _watchdog_for = (os.getpid(), parent_pid)
    threading.Thread(target=_watch_parent, args=(parent_pid,), name="swiptopt-parent-watchdog", daemon=True).start()


def _watch_parent(parent_pid: int) -> None:
    while True:
        time.sleep(PARENT_POLL_S)
        if os.getppid() != parent_pid:
            os._exit(ORPHAN_EXIT)


# ------------------------------------------------------------------ fresh processes


@dataclass(frozen=True)
class FreshOutcome:
    """What a call in a fresh process gave: its ``value``, or an ``error`` (one line) with
    ``detail`` (the traceback, or the process's last words on stderr)."""

    value: Any = None
    error: str | None = None
    detail: str = ""


def qualified_name(function: Callable[..., Any]) -> str:
    """``module:qualname`` of a module-level function, as :func:`run_in_fresh_process` takes."""
    return f"{function.__module__}:{function.__qualname__}"


def _resolve(target: str) -> Callable[..., Any]:
    module, _, name = target.partition(":")
    obj: Any = importlib.import_module(module)
    for part in name.split("."):
        obj = getattr(obj, part)
    return obj


_BOOT = (
    "import json, sys; payload = json.loads(sys.stdin.buffer.read()); sys.path[:] = payload['sys_path']; "
    "from swiptopt.benchmark.processes import fresh_process_main; fresh_process_main(payload)"
)


def run_in_fresh_process(target: str, argument: Any, *, modules: Iterable[str] = ()) -> FreshOutcome:
    """Call ``target(argument)`` in a new Python process and return its outcome.

    ``target`` is ``"module:function"``; ``argument`` and the return value travel as JSON.
    The child has this process's ``sys.path``, one thread per native pool (``modules`` are
    imported before the limit), and dies with this process. It runs in the calling thread's
    charge: on Linux it is killed when that thread ends, so call this from a thread that
    waits for it (it does wait). An exception in ``target`` becomes ``error``; a child that
    dies (a segfault in a native library) becomes ``error`` naming the signal.
    """
    payload = json.dumps({"sys_path": [str(p) for p in sys.path], "parent_pid": os.getpid(), "target": target,
                          "argument": argument, "modules": list(modules)})
    env = dict(os.environ, **{variable: "1" for variable in THREAD_VARIABLES})
    try:
        proc = subprocess.Popen([sys.executable, "-c", _BOOT], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, env=env)
    except OSError as exc:
        return FreshOutcome(error=f"cannot start a fresh Python process: {exc}")
    out, err = proc.communicate(payload.encode())
    last_words = err.decode("utf-8", errors="replace").strip()
    if proc.returncode == 0:
        try:
            message = json.loads(out)
        except ValueError:
            message = None
        if isinstance(message, dict) and ("value" in message or "error" in message):
            return FreshOutcome(message.get("value"), message.get("error"), message.get("detail", ""))
    if proc.returncode < 0:  # stderr holds faulthandler's traceback: the detail, not the reason
        try:
            name = signal.Signals(-proc.returncode).name
        except ValueError:
            name = f"signal {-proc.returncode}"
        error = f"the task's process was killed by {name}"
    else:
        tail = last_words.splitlines()[-1][:200] if last_words else ""
        error = f"the task's process exited with status {proc.returncode} without a result" + (
            f" ({tail})" if tail else "")
    return FreshOutcome(error=error, detail=last_words[-8000:])


def fresh_process_main(payload: dict[str, Any]) -> None:
    """The child's side of :func:`run_in_fresh_process` (reads nothing else, prints one JSON
    message on the original stdout; anything the task prints goes to stderr)."""
    die_with_parent(payload["parent_pid"])
    faulthandler.enable()  # a native crash leaves its Python traceback on stderr, for the detail
    result_stream = os.fdopen(os.dup(1), "w", encoding="utf-8")
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    try:
        prepare_worker(payload["modules"])
        message: dict[str, Any] = {"value": _resolve(payload["target"])(payload["argument"])}
    except Exception as exc:  # the parent records it; the traceback travels as detail
        message = {"error": one_line(exc), "detail": traceback.format_exc()}
    json.dump(message, result_stream)
    result_stream.flush()


def one_line(exc: BaseException, limit: int = 300) -> str:
    """``Type: message``, first line only, at most ``limit`` characters."""
    text = f"{type(exc).__name__}: {exc}".strip().splitlines()[0]
    return text if len(text) <= limit else text[: limit - 1] + "…"

