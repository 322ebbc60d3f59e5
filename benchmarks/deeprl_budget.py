"""How many training steps deep RL needs on the standard suite: learning curves at checkpoints.

PPO or DQN at Stable-Baselines3's defaults on the paper preset (25 nodes, the vector
observation), trained per layout (layouts 0..L-1) for several seeds, the SB3 seed being the
benchmark's task seed ``1000 * layout + seed``. At each checkpoint the greedy policy is
evaluated as the benchmark evaluates a task (10 episodes on the evaluation seeds
``1000 * layout + seed + 1_000_003``); ``--references`` adds k-means + TSP and Q-learning on
the same layouts and evaluation seeds.

With ``--across``, one model per seed is trained across layouts 0..L-1 (a layout drawn per
episode, SB3 seeded with the seed itself), as the ``compare`` suite trains them, and each
checkpoint evaluates it on every layout (the row's layout is then the evaluation layout).

Training runs in stages (``--stages 100000 300000``), every (seed, layout) through a stage
before any goes on to the next, so early stages' numbers come first. PPO goes on training
the same models (its schedules are constant, so the checkpoints are those of one long run);
DQN trains afresh for each stage's budget, because its exploration schedule spans 10 % of the
budget: a DQN checkpoint is that of a run of its stage's budget. Every finished checkpoint is
appended to ``--out`` (JSON lines) at once; the summary prints the mean return over layouts
per seed and checkpoint.

    python benchmarks/deeprl_budget.py --algorithm ppo [--seeds 0 1 2] [--layouts 3]
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
from swiptopt.benchmark.algorithms import build_policy
from swiptopt.benchmark.experiment import EVALUATION_OFFSET
from swiptopt.env import AuvSwiptEnv

EPISODES = 10


def references(layouts: int) -> dict[str, list[float]]:
    """Mean return per layout of k-means + TSP and Q-learning (task seed 1000 * layout)."""
    out: dict[str, list[float]] = {"kmeans_tsp": [], "q_learning": []}
    for layout in range(layouts):
        scenario = Scenario.preset("paper", n_nodes=25, layout_seed=layout)
        seed = 1000 * layout
        for name in out:
            env = AuvSwiptEnv(scenario)
            policy = build_policy(name, env, {}, seed)
            out[name].append(evaluate(policy, env, EPISODES, seed=seed + EVALUATION_OFFSET).summary["return"].mean)
    return out


def _model(algorithm: str, layout: int, seed: int, across: int = 0) -> Any:
    """A fresh model on ``layout`` (task seed 1000 x layout + seed), or with ``across``
    layouts on layouts 0..across-1 drawn per episode (SB3 seed: the seed itself)."""
    scenario = Scenario.preset("paper", n_nodes=25, layout_seed=layout)
    pin_torch()
    if across:
        env = AuvSwiptEnv(scenario, observation=OBSERVATION, layout_seeds=range(across))
        return _algorithm_class(algorithm)("MlpPolicy", env, seed=seed, device="cpu")
    env = AuvSwiptEnv(scenario, observation=OBSERVATION)
    return _algorithm_class(algorithm)("MlpPolicy", env, seed=1000 * layout + seed, device="cpu")


def train_stage(model: Any, algorithm: str, layouts: list[int], seed: int, stage: int, checkpoints: list[int],
                out: Path) -> None:
    """Train ``model`` up to ``stage`` timesteps, evaluating it on each of ``layouts`` at the
    checkpoints passed."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Checkpoints(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps in checkpoints and self.num_timesteps <= stage:
                for layout in layouts:
                    eval_env = AuvSwiptEnv(Scenario.preset("paper", n_nodes=25, layout_seed=layout),
                                           observation=OBSERVATION)
                    result = evaluate(self.model, eval_env, EPISODES, seed=1000 * layout + seed + EVALUATION_OFFSET)
                    row = {
                        "algorithm": algorithm, "layout": layout, "seed": seed, "timesteps": self.num_timesteps,
                        "budget": stage, "return": result.summary["return"].mean,
                        "data_bits": result.summary["data_bits"].mean, "across": len(layouts) > 1,
                    }
                    with out.open("a", encoding="utf-8") as f:
                        f.write(json.dumps(row) + "\n")
            return True

    model.learn(stage - model.num_timesteps, callback=Checkpoints(), reset_num_timesteps=False)


def run(algorithm: str, seeds: list[int], layouts: int, stages: list[int], checkpoints: list[int], out: Path,
        across: bool = False) -> None:
    kept: dict[tuple[int, int], Any] = {}  # PPO's models go on from stage to stage
    previous = 0
    for stage in stages:
        for seed in seeds:
            if across:
                if algorithm == "ppo":
                    model = kept.setdefault((seed, -1), _model(algorithm, 0, seed, layouts))
                    wanted = [c for c in checkpoints if previous < c <= stage]
                else:
                    model = _model(algorithm, 0, seed, layouts)
                    wanted = [c for c in checkpoints if c <= stage and (c > previous or c == stage)]
                train_stage(model, algorithm, list(range(layouts)), seed, stage, wanted, out)
                continue
            for layout in range(layouts):
                if algorithm == "ppo":
                    model = kept.setdefault((seed, layout), _model(algorithm, layout, seed))
                    wanted = [c for c in checkpoints if previous < c <= stage]
                else:
                    model = _model(algorithm, layout, seed)
                    wanted = [c for c in checkpoints if c <= stage and (c > previous or c == stage)]
                train_stage(model, algorithm, [layout], seed, stage, wanted, out)
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
    parser.add_argument("--algorithm", choices=["ppo", "dqn"], default="ppo")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--layouts", type=int, default=3)
    parser.add_argument("--stages", type=int, nargs="+", default=[100_000, 300_000])
    parser.add_argument("--checkpoints", type=int, nargs="+", default=[25_000, 50_000, 100_000, 150_000, 200_000, 300_000])
    parser.add_argument("--out", type=Path, default=Path("deeprl_budget.jsonl"))
    parser.add_argument("--summary-only", action="store_true")
    parser.add_argument("--references", action="store_true", help="also evaluate k-means + TSP and Q-learning")
    parser.add_argument("--across", action="store_true",
                        help="one model per seed across the layouts (as compare trains), not one per layout")
    args = parser.parse_args()
    if not args.summary_only:
        run(args.algorithm, args.seeds, args.layouts, sorted(args.stages), sorted(args.checkpoints), args.out,
            args.across)
    summary(args.out, references(args.layouts) if args.references else None)


if __name__ == "__main__":
    main()
