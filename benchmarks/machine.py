"""What machine a benchmark ran on, printed with its numbers (speed figures mean little
without it): the CPU model, the cores this process may use, and the versions that matter."""

from __future__ import annotations

import os
import platform
import sys
from importlib import metadata


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo`` on Linux, else what ``platform`` knows)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown CPU"


def describe() -> str:
    """One line: CPU, usable and logical cores, OS, Python and the numerical packages."""
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    versions = []
    for name in ("numpy", "numba", "gymnasium", "ortools", "scipy"):
        try:
            versions.append(f"{name} {metadata.version(name)}")
        except metadata.PackageNotFoundError:
            pass
    return (
        f"machine: {cpu_model()}, {usable} usable of {os.cpu_count()} logical cores, {platform.system()} "
        f"{platform.release()}; Python {sys.version.split()[0]}, {', '.join(versions)}"
    )


if __name__ == "__main__":
    print(describe())
