"""Does any number depend on the CPU's code paths? One machine plays several CPUs.

Runs a ``swiptopt`` command (by default ``compare --quick``, every algorithm of both
suites, deep RL included) once per configuration below, each in a fresh process with a
fresh store, and prints whether the tables are identical. The configurations switch the
CPU-specific code paths of the libraries underneath, as a different CPU would:

- ``numpy without AVX-512``: ``NPY_DISABLE_CPU_FEATURES=X86_V4`` (numpy's SIMD loops for
  exp, log, power and friends; an AMD EPYC without AVX-512 or an older Intel);
- ``OpenBLAS SkylakeX`` / ``OpenBLAS Haswell``: ``OPENBLAS_CORETYPE`` (the BLAS kernels an
  Intel Xeon with AVX-512 and an AMD EPYC pick);
- ``torch AVX2``: ``ATEN_CPU_CAPABILITY=avx2`` (torch's vectorised kernels without AVX-512);
- ``MKL AVX2``: ``MKL_ENABLE_INSTRUCTIONS=AVX2`` (torch's matrix products without AVX-512);
- ``glibc without FMA``: ``GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2_Usable,-FMA_Usable,-AVX2,-FMA``
  (the C library's generic exp/log/pow, as on a CPU without FMA).

A configuration whose switch does nothing on this machine (a feature it lacks) still
runs and must agree. Usage::

    python benchmarks/cpu_paths.py                      # compare --quick, all configurations
    python benchmarks/cpu_paths.py --args "compare --suite standard"   # the full standard suite
"""

from __future__ import annotations

import argparse
import difflib
import hashlib
import os
import shlex
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CONFIGURATIONS = {
    "as this CPU is": {},
    "numpy without AVX-512": {"NPY_DISABLE_CPU_FEATURES": "X86_V4"},
    "OpenBLAS SkylakeX": {"OPENBLAS_CORETYPE": "SkylakeX"},
    "OpenBLAS Haswell": {"OPENBLAS_CORETYPE": "Haswell"},
    "torch AVX2": {"ATEN_CPU_CAPABILITY": "avx2"},
    "MKL AVX2": {"MKL_ENABLE_INSTRUCTIONS": "AVX2"},
    "glibc without FMA": {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2_Usable,-FMA_Usable,-AVX2,-FMA"},
}


def raw_digests(store: Path) -> dict[str, str]:
    """Per algorithm, a digest of every stored episode record (full float precision, task
    keys sorted): equal digests mean equal numbers to the last bit, not only in print."""
    with sqlite3.connect(f"file:{store}?mode=ro", uri=True) as db:
        rows = sorted(db.execute("SELECT algorithm, key, records FROM results"))
    digests: dict[str, hashlib._Hash] = {}
    for algorithm, key, records in rows:
        digests.setdefault(algorithm, hashlib.sha256()).update(f"{key}{records}".encode())
    return {algorithm: digest.hexdigest()[:12] for algorithm, digest in digests.items()}


def run(args: list[str], extra_env: dict[str, str], workdir: Path) -> tuple[str, dict[str, str], float]:
    env = dict(os.environ, **extra_env)
    started = time.perf_counter()
    out = subprocess.run(
        [sys.executable, "-m", "swiptopt.cli", *args, "--store", str(workdir / "store.sqlite"), "--format", "markdown"],
        env=env, capture_output=True, text=True, check=False,
    )
    if out.returncode != 0:
        raise SystemExit(f"{args} with {extra_env} failed ({out.returncode}): {out.stderr.strip()[-2000:]}")
    tables = "\n".join(line for line in out.stdout.splitlines() if line.startswith(("|", "**")))
    return tables, raw_digests(workdir / "store.sqlite"), time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--args", default="compare --quick", help="the swiptopt command to run (default: %(default)s)")
    parser.add_argument("--only", nargs="*", choices=list(CONFIGURATIONS), help="run only these configurations")
    options = parser.parse_args()
    names = options.only or list(CONFIGURATIONS)
    reference: str | None = None
    reference_raw: dict[str, str] = {}
    failures = 0
    for name in names:
        with tempfile.TemporaryDirectory(prefix="swiptopt-cpu-") as tmp:
            tables, raw, seconds = run(shlex.split(options.args), CONFIGURATIONS[name], Path(tmp))
        if reference is None:
            reference, reference_raw = tables, raw
            print(f"{name:24s} {seconds:7.1f} s  reference ({len(tables.splitlines())} table lines, "
                  f"{len(raw)} algorithms)")
            continue
        same = tables == reference
        failures += not same
        differ = sorted(a for a in set(raw) | set(reference_raw) if raw.get(a) != reference_raw.get(a))
        bits = "every record to the last bit" if not differ else f"records differ in the last bits: {', '.join(differ)}"
        print(f"{name:24s} {seconds:7.1f} s  tables {'identical' if same else 'DIFFERENT'}; {bits}")
        if not same:
            diff = difflib.unified_diff(
                reference.splitlines(), tables.splitlines(), "reference", name, lineterm="", n=0
            )
            print("\n".join(list(diff)[:40]))
    print("all identical" if failures == 0 else f"{failures} configuration(s) differ")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
