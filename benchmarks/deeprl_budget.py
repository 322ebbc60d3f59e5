"""How many training steps deep RL needs on the standard suite: learning curves at checkpoints.

PPO or DQN at Stable-Baselines3's defaults on the paper preset (25 nodes, the vector
observation), trained per layout (layouts 0..L-1) for several seeds. At each checkpoint the
greedy policy is evaluated as the benchmark evaluates a task (10 episodes on the task's
evaluation seeds, ``1000 * layout + seed + 1_000_003``), next to k-means + TSP and Q-learning
on the same layouts and evaluation seeds. The checkpoints lie inside one run of the largest
budget (DQN's exploration schedule spans 10 % of that run, not of the checkpoint). Every
finished checkpoint is appended to ``--out`` (JSON lines) as it comes; the summary prints
the mean return over layouts per seed and checkpoint.

    python benchmarks/deeprl_budget.py --algorithm ppo [--seeds 0 1 2] [--layouts 3]
        [--checkpoints 25000 50000 100000 200000 300000] [--out deeprl_budget.jsonl]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

# benchmarks/planners.py, beside this script, would shadow the planners package
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from rl.deep import OBSERVATION, _algorithm_class, _episode_log_callback, pin_torch
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


def curve(algorithm: str, layout: int, seed: int, checkpoints: list[int], out: Path) -> None:
    """Train one model for max(checkpoints) steps, evaluating it at each checkpoint."""
    from stable_baselines3.common.callbacks import BaseCallback, CallbackList

    scenario = Scenario.preset("paper", n_nodes=25, layout_seed=layout)
    task_seed = 1000 * layout + seed
    eval_env = AuvSwiptEnv(scenario, observation=OBSERVATION)

    class Checkpoints(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps in checkpoints:
                result = evaluate(self.model, eval_env, EPISODES, seed=task_seed + EVALUATION_OFFSET)
                row = {
                    "algorithm": algorithm, "layout": layout, "seed": seed, "timesteps": self.num_timesteps,
                    "return": result.summary["return"].mean, "data_bits": result.summary["data_bits"].mean,
                }
                with out.open("a", encoding="utf-8") as f:
                    f.write(json.dumps(row) + "\n")
            return True

    pin_torch()
    model = _algorithm_class(algorithm)("MlpPolicy", AuvSwiptEnv(scenario, observation=OBSERVATION), seed=task_seed, device="cpu")
    model.learn(max(checkpoints), callback=CallbackList([_episode_log_callback(), Checkpoints()]))


def summary(out: Path, refs: dict[str, list[float]] | None) -> None:
    rows = [json.loads(line) for line in out.read_text(encoding="utf-8").splitlines() if line.strip()]
    if refs:
        for name, values in refs.items():
            print(f"{name}: mean return over layouts {statistics.mean(values):.2f} (per layout {[round(v, 2) for v in values]})")
    for algorithm in sorted({r["algorithm"] for r in rows}):
        print(f"{algorithm}: mean return over layouts, by seed (columns) and timesteps (rows)")
        mine = [r for r in rows if r["algorithm"] == algorithm]
        seeds = sorted({r["seed"] for r in mine})
        print("  timesteps " + "".join(f"{'seed ' + str(s):>10}" for s in seeds) + f"{'mean':>10}")
        for steps in sorted({r["timesteps"] for r in mine}):
            per_seed = []
            for s in seeds:
                values = [r["return"] for r in mine if r["seed"] == s and r["timesteps"] == steps]
                per_seed.append(statistics.mean(values) if values else float("nan"))
            cells = "".join(f"{v:>10.2f}" for v in per_seed)
            print(f"  {steps:>9} {cells}{statistics.mean(per_seed):>10.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--algorithm", choices=["ppo", "dqn"], default="ppo")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--layouts", type=int, default=3)
    parser.add_argument("--checkpoints", type=int, nargs="+", default=[25_000, 50_000, 100_000, 200_000, 300_000])
    parser.add_argument("--out", type=Path, default=Path("deeprl_budget.jsonl"))
    parser.add_argument("--summary-only", action="store_true")
    parser.add_argument("--references", action="store_true", help="also evaluate k-means + TSP and Q-learning")
    args = parser.parse_args()
    if not args.summary_only:
        for seed in args.seeds:
            for layout in range(args.layouts):
                curve(args.algorithm, layout, seed, sorted(args.checkpoints), args.out)
    summary(args.out, references(args.layouts) if args.references else None)


if __name__ == "__main__":
    main()
