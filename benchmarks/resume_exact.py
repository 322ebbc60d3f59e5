"""Exact resume at the benchmark's own settings: SAC in the harbour, trained across the
harbour suite's 8 layouts with its default configuration (16 copies, a 300,000-transition
replay buffer, learning from 10,000 steps, [128, 128] networks), once straight through and
once kept at half-way (:mod:`rl.resume`) and gone on from in a fresh model. Prints whether
the two final models are the same to the bit, the size of the state file and what going on
from it cost (reading it, restoring and replaying the environments). Usage::

    python benchmarks/resume_exact.py [--timesteps 32768] [--algorithm sac]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from machine import describe

from rl.deep import train_deep
from swiptopt import Scenario
from swiptopt.benchmark.algorithms import deep_hyperparams, resolve_settings
from swiptopt.worlds import CONTINUOUS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--timesteps", type=int, default=32_768, help="steps of the whole run (even)")
    parser.add_argument("--algorithm", choices=["sac", "ppo"], default="sac")
    args = parser.parse_args()
    settings = resolve_settings(args.algorithm, {}, CONTINUOUS)
    kwargs = dict(hyperparams=deep_hyperparams(settings), policy_kwargs={"net_arch": list(settings["net_arch"])},
                  layout_seeds=tuple(range(8)), world=CONTINUOUS, n_envs=settings["n_envs"])
    scenario = Scenario.preset("harbour")
    print(describe())
    whole = train_deep(args.algorithm, scenario, args.timesteps, 0, **kwargs)
    with tempfile.TemporaryDirectory() as directory:
        state = Path(directory) / "run.state.npz"
        train_deep(args.algorithm, scenario, args.timesteps // 2, 0, state_file=state, **kwargs)
        size = state.stat().st_size
        start = time.perf_counter()
        resumed = train_deep(args.algorithm, scenario, args.timesteps, 0, state_file=state, **kwargs)
        went_on = time.perf_counter() - start
    a, b = whole.model.policy.state_dict(), resumed.model.policy.state_dict()
    same = all(np.array_equal(a[k].numpy(), b[k].numpy()) for k in a)
    print(f"{args.algorithm}, {args.timesteps:,} steps straight against {args.timesteps // 2:,} kept and gone on "
          f"from: same weights {same}, same {len(whole.episode_returns)} training returns "
          f"{np.array_equal(whole.episode_returns, resumed.episode_returns)}; state file {size / 1e6:.0f} MB; "
          f"the second half took {went_on:.1f} s of wall time, reading and replaying included")


if __name__ == "__main__":
    main()
