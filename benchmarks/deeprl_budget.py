"""How many training steps deep RL needs on the standard suite: learning curves at checkpoints.

PPO or DQN at Stable-Baselines3's defaults on the paper preset (25 nodes, the vector
observation) in the grid world, or (``--world continuous``) PPO or SAC on the harbour preset in
the continuous world with the settings the ``harbour`` suite gives them
(:mod:`swiptopt.benchmark.algorithms`; SAC's ``--train-freq`` defaults to the suite's 4),
trained per layout (layouts 0..L-1) for several seeds, the SB3 seed being the
benchmark's task seed ``1000 * layout + seed``. At each checkpoint the greedy policy is
evaluated as the benchmark evaluates a task (10 episodes on the evaluation seeds
``1000 * layout + seed + 1_000_003``); ``--references`` adds k-means + TSP and Q-learning
(in the continuous world: the OMPL tour and the straight line, at the suite's settings) on the
same layouts and evaluation seeds.

With ``--across``, one model per seed is trained across layouts 0..L-1 (a layout drawn per
episode, SB3 seeded with the seed itself), as the ``compare`` suite trains them, and each
checkpoint evaluates it on every layout (the row's layout is then the evaluation layout).

Training runs in stages (``--stages 100000 300000``), every (seed, layout) through a stage
before any goes on to the next, so early stages' numbers come first. PPO goes on training
the same models (its schedules are constant, so the checkpoints are those of one long run), and
so does SAC (constant learning rate, no exploration schedule);
DQN trains afresh for each stage's budget, because its exploration schedule spans 10 % of the
budget: a DQN checkpoint is that of a run of its stage's budget. Every finished checkpoint is
appended to ``--out`` (JSON lines) at once; the summary prints the mean return over layouts
per seed and checkpoint.

    python benchmarks/deeprl_budget.py [--world grid|continuous] --algorithm ppo|dqn|sac
        [--train-freq 4] [--seeds 0 1 2] [--layouts 3]
        [--stages 100000 300000] [--checkpoints 25000 50000 100000 150000 200000 300000]
        [--out deeprl_budget.jsonl] [--references] [--across]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path
from typing import Any

# benchmarks/planners.py, beside this script, would shadow the planners package
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from rl.deep import OBSERVATION, _algorithm_class, pin_torch
from swiptopt import Scenario, evaluate
from swiptopt.benchmark.algorithms import build_policy, deep_hyperparams, resolve_settings
from swiptopt.benchmark.experiment import EVALUATION_OFFSET, HARBOUR_SAC_TRAIN_FREQ
from swiptopt.worlds import CONTINUOUS, GRID, WORLDS, make_env

EPISODES = 10
#: The algorithms trained in each world.
ALGORITHMS = {GRID: ("ppo", "dqn"), CONTINUOUS: ("ppo", "sac")}
#: The reference algorithms of each world (benchmark names, at their default settings).
REFERENCES = {GRID: ("kmeans_tsp", "q_learning"), CONTINUOUS: ("ompl_tour", "straight_line")}
#: The algorithms whose models go on training from stage to stage (no schedule spans the budget).
CONTINUED = ("ppo", "sac")


def scenario(world: str, layout: int) -> Scenario:
    """The world's scenario on ``layout``: the paper preset with 25 nodes, or the harbour preset."""
    if world == GRID:
        return Scenario.preset("paper", n_nodes=25, layout_seed=layout)
    return Scenario.preset("harbour", layout_seed=layout)


def reference(world: str, name: str, layout: int) -> float:
    """Mean return of the reference algorithm ``name`` on ``layout`` (task seed 1000 * layout)."""
    seed = 1000 * layout
    env = make_env(world, scenario(world, layout))
    policy = build_policy(name, env, {}, seed)
    return float(evaluate(policy, env, EPISODES, seed=seed + EVALUATION_OFFSET).summary["return"].mean)


def references(layouts: int, world: str = GRID) -> dict[str, list[float]]:
    """Mean return per layout of the world's reference algorithms, each (algorithm, layout)
    in a fresh process, one at a time: OMPL's seed is process-wide, so the OMPL tour of each
    layout needs its own process (as the benchmark runs it)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    out: dict[str, list[float]] = {name: [] for name in REFERENCES[world]}
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"), max_tasks_per_child=1) as pool:
        for layout in range(layouts):
            for name in out:
                out[name].append(pool.submit(reference, world, name, layout).result())
    return out


def sb3_arguments(algorithm: str, world: str, train_freq: int | None = None) -> dict[str, Any]:
    """SB3 constructor arguments: none in the grid (SB3's defaults), the ``harbour`` suite's
    settings of ``algorithm`` in the continuous world (SAC's ``train_freq`` as given)."""
    if world == GRID:
        return {}
    overrides = {} if train_freq is None else {"train_freq": train_freq}
    settings = resolve_settings(algorithm, overrides)
    return {**deep_hyperparams(settings), "policy_kwargs": {"net_arch": list(settings["net_arch"])}}


def _model(algorithm: str, layout: int, seed: int, across: int = 0, world: str = GRID,
           train_freq: int | None = None) -> Any:
    """A fresh model on ``layout`` (task seed 1000 x layout + seed), or with ``across``
    layouts on layouts 0..across-1 drawn per episode (SB3 seed: the seed itself)."""
    pin_torch()
    arguments = sb3_arguments(algorithm, world, train_freq)
    if across:
        env = make_env(world, scenario(world, layout), observation=OBSERVATION, layout_seeds=range(across))
        return _algorithm_class(algorithm)("MlpPolicy", env, seed=seed, device="cpu", **arguments)
    env = make_env(world, scenario(world, layout), observation=OBSERVATION)
    return _algorithm_class(algorithm)("MlpPolicy", env, seed=1000 * layout + seed, device="cpu", **arguments)


def train_stage(model: Any, algorithm: str, layouts: list[int], seed: int, stage: int, checkpoints: list[int],
                out: Path, world: str = GRID) -> None:
    """Train ``model`` up to ``stage`` timesteps, evaluating it on each of ``layouts`` at the
    checkpoints passed."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Checkpoints(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps in checkpoints and self.num_timesteps <= stage:
                for layout in layouts:
                    eval_env = make_env(world, scenario(world, layout), observation=OBSERVATION)
                    result = evaluate(self.model, eval_env, EPISODES, seed=1000 * layout + seed + EVALUATION_OFFSET)
                    row = {
                        "algorithm": algorithm, "layout": layout, "seed": seed, "timesteps": self.num_timesteps,
                        "budget": stage, "return": result.summary["return"].mean,
                        "data_bits": result.summary["data_bits"].mean, "across": len(layouts) > 1,
                        "world": world,
                    }
                    with out.open("a", encoding="utf-8") as f:
                        f.write(json.dumps(row) + "\n")
            return True

    model.learn(stage - model.num_timesteps, callback=Checkpoints(), reset_num_timesteps=False)


def run(algorithm: str, seeds: list[int], layouts: int, stages: list[int], checkpoints: list[int], out: Path,
        across: bool = False, world: str = GRID, train_freq: int | None = None) -> None:
    kept: dict[tuple[int, int], Any] = {}  # PPO's and SAC's models go on from stage to stage
    previous = 0
    for stage in stages:
        for seed in seeds:
            if across:
                if algorithm in CONTINUED:
                    if (seed, -1) not in kept:
                        kept[seed, -1] = _model(algorithm, 0, seed, layouts, world, train_freq)
                    model = kept[seed, -1]
                    wanted = [c for c in checkpoints if previous < c <= stage]
                else:
                    model = _model(algorithm, 0, seed, layouts, world, train_freq)
                    wanted = [c for c in checkpoints if c <= stage and (c > previous or c == stage)]
                train_stage(model, algorithm, list(range(layouts)), seed, stage, wanted, out, world)
                continue
            for layout in range(layouts):
                if algorithm in CONTINUED:
                    if (seed, layout) not in kept:
                        kept[seed, layout] = _model(algorithm, layout, seed, 0, world, train_freq)
                    model = kept[seed, layout]
                    wanted = [c for c in checkpoints if previous < c <= stage]
                else:
                    model = _model(algorithm, layout, seed, 0, world, train_freq)
                    wanted = [c for c in checkpoints if c <= stage and (c > previous or c == stage)]
                train_stage(model, algorithm, [layout], seed, stage, wanted, out, world)
        previous = stage


def summary(out: Path, refs: dict[str, list[float]] | None) -> None:
    rows = [json.loads(line) for line in out.read_text(encoding="utf-8").splitlines() if line.strip()]
    if refs:
        for name, values in refs.items():
            print(f"{name}: mean return over layouts {statistics.mean(values):.2f} (per layout {[round(v, 2) for v in values]})")
    for algorithm in sorted({r["algorithm"] for r in rows}):
        mine = [r for r in rows if r["algorithm"] == algorithm]
        seeds = sorted({r["seed"] for r in mine})
        print(f"{algorithm}: mean return over the layouts done (their count in brackets), by seed")
        print("  timesteps (budget) " + "".join(f"{'seed ' + str(s):>14}" for s in seeds))
        for budget, steps in sorted({(r.get("budget", 0), r["timesteps"]) for r in mine}, key=lambda k: (k[1], k[0])):
            cells = ""
            for s in seeds:
                values = [r["return"] for r in mine if r["seed"] == s and r["timesteps"] == steps and r.get("budget", 0) == budget]
                cells += f"{statistics.mean(values):>10.2f} [{len(values)}]" if values else f"{'-':>14}"
            print(f"  {steps:>9} ({budget:>7}) {cells}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", choices=WORLDS, default=GRID,
                        help="grid: the paper preset; continuous: the harbour preset with the harbour suite's settings")
    parser.add_argument("--algorithm", choices=sorted({a for names in ALGORITHMS.values() for a in names}),
                        default="ppo", help="grid: ppo or dqn; continuous: ppo or sac")
    parser.add_argument("--train-freq", type=int, default=None,
                        help=f"SAC's environment steps between updates (default: the harbour suite's {HARBOUR_SAC_TRAIN_FREQ})")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--layouts", type=int, default=3)
    parser.add_argument("--stages", type=int, nargs="+", default=[100_000, 300_000])
    parser.add_argument("--checkpoints", type=int, nargs="+", default=[25_000, 50_000, 100_000, 150_000, 200_000, 300_000])
    parser.add_argument("--out", type=Path, default=Path("deeprl_budget.jsonl"))
    parser.add_argument("--summary-only", action="store_true")
    parser.add_argument("--references", action="store_true",
                        help="also evaluate k-means + TSP and Q-learning (continuous: the OMPL tour and the straight line)")
    parser.add_argument("--across", action="store_true",
                        help="one model per seed across the layouts (as compare trains), not one per layout")
    args = parser.parse_args()
    if args.algorithm not in ALGORITHMS[args.world]:
        parser.error(f"--algorithm {args.algorithm} does not train in the {args.world} world: choose one of "
                     f"{', '.join(ALGORITHMS[args.world])}")
    if args.train_freq is not None and args.algorithm != "sac":
        parser.error("--train-freq applies to sac only")
    if args.train_freq is not None and args.train_freq < 1:
        parser.error(f"--train-freq {args.train_freq} must be an integer >= 1")
    train_freq = HARBOUR_SAC_TRAIN_FREQ if args.algorithm == "sac" and args.train_freq is None else args.train_freq
    if not args.summary_only:
        run(args.algorithm, args.seeds, args.layouts, sorted(args.stages), sorted(args.checkpoints), args.out,
            args.across, args.world, train_freq)
    summary(args.out, references(args.layouts, args.world) if args.references else None)


if __name__ == "__main__":
    main()
