"""The same numbers on any x86-64 CPU with AVX2 and FMA: the scenario tables, short kernel
traces of both worlds, the planners' expected amounts, hover points and the MILP's plan and
bound, held to one reference digest and to themselves with numpy's AVX-512 loops and
OpenBLAS's kernels switched as another CPU would switch them.

``benchmarks/cpu_paths.py`` runs the whole benchmark (deep RL included) the same way.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]

#: The digests of :func:`digests`, the same on every x86-64 CPU with AVX2 (docs/guarantees.md).
#: A change to the model's physics changes them on purpose: regenerate the results' tables
#: (README, docs/results.md), then these
#: (``python -m tests.swiptopt.test_cpu_paths`` prints them).
REFERENCE = {
    "grid tables": "0f6219067d7ca01c",
    "harbour tables": "3041418d2b88a9d9",
    "grid trace": "5c29a2f43ffb2ee5",
    "continuous trace": "564c5f7cfa89f5a0",
    "expected service": "54c4ace90a007c1b",
    "hover points": "1628ec2f446d03ad",
    "milp": "ab655a102929f8ed",
}


def _hash(*arrays: object) -> str:
    digest = hashlib.sha256()
    for array in arrays:
        digest.update(np.ascontiguousarray(np.asarray(array)).tobytes())
    return digest.hexdigest()[:16]


def digests() -> dict[str, str]:
    """Digests of the numbers every table is made of (this process's CPU paths)."""
    import gymnasium as gym

    import swiptopt  # noqa: F401 (registers the environments)
    from planners import solve_optimum
    from planners.clustering import kmeans_hover_points
    from planners.service import step_model
    from swiptopt import Scenario
    from swiptopt import kernel as K

    out: dict[str, str] = {}
    paper = Scenario.preset("paper", n_nodes=25, layout_seed=0, channel="rician")
    tables = K.build_tables(paper)
    fields = ("next_cell", "propulsion_j", "cov_ptr", "cov_node", "cov_snr", "cov_pav", "params")
    out["grid tables"] = _hash(*(getattr(tables, f) for f in fields))
    harbour = K.build_tables(Scenario.preset("harbour", layout_seed=1))
    out["harbour tables"] = _hash(*(getattr(harbour, f) for f in fields))

    rng = np.random.default_rng(5)
    env = gym.make("swiptopt/AuvSwipt-v1", preset="paper", n_nodes=25, channel="rician", observation="vector")
    obs, _ = env.reset(seed=11)
    trace = [obs]
    for _ in range(60):
        obs, reward, terminated, truncated, info = env.step(int(rng.integers(7)))
        trace += [obs, [reward]]
        if terminated or truncated:
            obs, _ = env.reset()
    out["grid trace"] = _hash(*trace)

    env = gym.make("swiptopt/AuvSwiptContinuous-v0", preset="harbour", channel="rician")
    obs, _ = env.reset(seed=3)
    trace = [obs]
    for _ in range(60):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1.0, 1.0, 3).astype(np.float32))
        trace += [obs, [reward], info["position"]]
    out["continuous trace"] = _hash(*trace)

    model = step_model(tables)
    out["expected service"] = _hash(model.bits, model.joules)
    points = kmeans_hover_points(paper, rng=0, tables=tables)
    out["hover points"] = _hash(points.cells, points.labels)
    result = solve_optimum(Scenario.preset("paper", n_nodes=12, layout_seed=2, episode_steps=30), budget="quick")
    out["milp"] = _hash(result.actions, [result.objective, result.bound, result.lp_bound])
    return out


def _in_fresh_process(extra_env: dict[str, str]) -> dict[str, str]:
    env = dict(os.environ, **extra_env)
    code = "import json; from tests.swiptopt.test_cpu_paths import digests; print(json.dumps(digests()))"
    out = subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT, env=env, capture_output=True, text=True, check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def _has_avx512() -> bool:
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:  # numpy < 2
        from numpy.core._multiarray_umath import __cpu_features__ as features
    return bool(features.get("AVX512F"))


@pytest.fixture(scope="module")
def here() -> dict[str, str]:
    return digests()


def test_the_numbers_are_the_reference_numbers(here):
    """Reference values: every CPU with AVX2 and FMA (and glibc 2.36, as CI's) gives these."""
    assert here == REFERENCE


def test_numpy_without_avx512_and_another_blas_kernel_give_the_same_numbers(here):
    """One machine playing an AMD EPYC without AVX-512 (numpy's generic loops, OpenBLAS's
    Haswell kernels) and, where it can, an Intel Xeon with it (OpenBLAS's SkylakeX
    kernels): the same digests as this process."""
    assert _in_fresh_process({"NPY_DISABLE_CPU_FEATURES": "X86_V4", "OPENBLAS_CORETYPE": "Haswell"}) == here
    if _has_avx512():
        assert _in_fresh_process({"OPENBLAS_CORETYPE": "SkylakeX"}) == here


if __name__ == "__main__":
    print(json.dumps(digests(), indent=4))


def test_torch_trains_on_the_cpu_paths_every_avx2_cpu_shares():
    """rl.deep pins torch's CPU paths before it computes (unless the user chose others), and
    the run's provenance records them."""
    pytest.importorskip("torch")
    import platform

    if platform.machine().lower() not in ("x86_64", "amd64"):
        pytest.skip("the pinned paths are x86-64's")
    code = ("import torch, rl.deep as d; d.pin_torch(); torch.ones(3).softmax(0); "
            "print(torch.backends.cpu.get_cpu_capability())")
    env = {k: v for k, v in os.environ.items() if k not in ("ATEN_CPU_CAPABILITY", "MKL_CBWR")}
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, check=True)
    with open("/proc/cpuinfo") if os.path.exists("/proc/cpuinfo") else open(os.devnull) as info:
        has_avx2 = " avx2" in info.read()
    if has_avx2:
        assert run.stdout.strip() == "AVX2"
    chosen = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=dict(env, ATEN_CPU_CAPABILITY="default"),
                            capture_output=True, text=True, check=True)
    assert chosen.stdout.strip() == "DEFAULT"  # the user's choice stands
