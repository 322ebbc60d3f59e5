"""Bounds that hold for every policy, against the algorithms (docs/optimum.md).

Part 1, the paper preset (fading and link failures, as the benchmark runs it; ``--channel
none`` for the deterministic variant), for each number of nodes and layout: each bound's
value and the CPU time it took,

- ``upper``: every coverable node fully served, no travel (:func:`planners.upper_bound`);
- ``lp``: the expected-rate relaxation's linear relaxation (``lp (expected)``, after the
  budget's cut rounds), a bound on every non-anticipative policy;
- ``milp``: the branch-and-bound's dual bound at each named budget, for open-loop plans
  only, and only where no walk can end early (``milp (expected)``; with ``--channel none``
  it is ``milp`` and holds for every policy);
- ``hindsight``: the perfect-information bound, the mean over ``--hindsight-samples`` draw
  tables of each table's time-indexed program (its linear relaxation by default:
  ``--hindsight-nodes 0``), with its 95 % interval; its upper end holds for every policy;

then each algorithm's mean return over ``--episodes`` evaluation episodes and its gap to the
tightest bound that holds for its class (``(bound - return) / |bound|``, the bound named):
the MILP's plan is open loop, every other algorithm adaptive.

Part 2, the ``tiny`` fading variant (:data:`planners.adaptive.TINY_FADING`): the exact
optimal adaptive policy by dynamic programming, each bound's value and its slack above it,
and each algorithm's return (``--tiny-episodes`` episodes, 95 % CI) below it.

Usage (about 15 minutes with the defaults on one free core; ``--skip-paper`` or
``--skip-tiny`` for one part):

    python benchmarks/optimum.py [--nodes 25] [--layouts 0,1,2] [--budgets compare,default]
"""

from __future__ import annotations

import sys
from pathlib import Path

# keep this folder off the path: the planners package must not be shadowed by a script here
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import argparse
import math
import time
from typing import Any

from planners import BUDGETS, solve_optimum, upper_bound
from planners.adaptive import TINY_FADING, AdaptivePolicy, adaptive_optimum
from planners.bounds import ADAPTIVE, UPPER_NAME, PolicyBound
from planners.hindsight import HindsightBudget, hindsight_bound
from planners.optimal import MilpBudget, policy_bounds
from swiptopt import Scenario, evaluate
from swiptopt.benchmark.algorithms import build_policy, get_algorithm, task_extra
from swiptopt.worlds import GRID, make_env

DETERMINISTIC = {"channel": "none", "failure_prob_min": 0.0, "failure_prob_max": 0.0}
ALGORITHMS = "kmeans_tsp,rate_greedy,greedy,lawnmower,milp,q_learning,sarsa,random"
EVALUATION_SEED = 10_000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", default="25", help="node counts, comma-separated")
    parser.add_argument("--layouts", default="0,1,2", help="layout seeds, comma-separated")
    parser.add_argument("--channel", default="paper", choices=("paper", "none"),
                        help="the paper preset's fading and failures, or a deterministic channel")
    parser.add_argument("--budgets", default="compare,default", help=f"MILP budgets from {', '.join(BUDGETS)}")
    parser.add_argument("--algorithms", default=ALGORITHMS, help="algorithms of the registry, comma-separated")
    parser.add_argument("--episodes", type=int, default=10, help="evaluation episodes per algorithm and layout")
    parser.add_argument("--hindsight-samples", type=int, default=8, help="draw tables of the hindsight bound (0: skip)")
    parser.add_argument("--hindsight-nodes", type=int, default=0,
                        help="branch-and-bound nodes per table (0: its linear relaxation)")
    parser.add_argument("--tiny-episodes", type=int, default=2000, help="evaluation episodes on the tiny variant")
    parser.add_argument("--tiny-samples", type=int, default=256,
                        help="draw tables of the tiny variant's hindsight bound")
    parser.add_argument("--skip-paper", action="store_true")
    parser.add_argument("--skip-tiny", action="store_true")
    args = parser.parse_args()
    budgets = args.budgets.split(",")
    unknown = [b for b in budgets if b not in BUDGETS]
    if unknown:
        sys.exit(f"unknown budget {unknown[0]!r}: choose from {', '.join(BUDGETS)}")
    algorithms = args.algorithms.split(",")
    for name in algorithms:
        get_algorithm(name)  # an unknown name fails here, before any work
    if not args.skip_paper:
        paper(args, budgets, algorithms)
    if not args.skip_tiny:
        tiny(args, algorithms)


def _cpu(fn: Any) -> tuple[Any, float]:
    started = time.process_time()
    out = fn()
    return out, time.process_time() - started


def _policy(name: str, scenario: Scenario, settings: dict[str, Any]) -> tuple[Any, Any]:
    algorithm = get_algorithm(name)
    env = make_env(GRID, scenario, observation=algorithm.observation or "tabular")
    return build_policy(name, env, settings, seed=0), env


def _evaluate(name: str, scenario: Scenario, settings: dict[str, Any], episodes: int) -> tuple[Any, dict, float]:
    """The algorithm's return summary on the scenario, what its task would record, and the
    CPU time of building (training, planning) and evaluating it."""
    started = time.process_time()
    policy, env = _policy(name, scenario, settings)
    result = evaluate(policy, env, episodes, seed=EVALUATION_SEED)
    return result.summary["return"], task_extra(name, policy, env), time.process_time() - started


def _tightest(bounds: list[PolicyBound], policy_class: str) -> PolicyBound | None:
    return min((b for b in bounds if b.holds(policy_class)), key=lambda b: b.value, default=None)


def paper(args: argparse.Namespace, budgets: list[str], algorithms: list[str]) -> None:
    channel = DETERMINISTIC if args.channel == "none" else {}
    print(f"Part 1: paper preset ({'deterministic channel' if channel else 'shadowing and link failures'})")
    for b in budgets:
        print(f"  budget {b}: {BUDGETS[b]}")
    hb = HindsightBudget(samples=max(args.hindsight_samples, 2), max_nodes=args.hindsight_nodes)
    for n in [int(v) for v in args.nodes.split(",")]:
        for layout in [int(v) for v in args.layouts.split(",")]:
            scenario = Scenario.preset("paper", n_nodes=n, layout_seed=layout, **channel)
            print(f"\nN = {n}, layout {layout}: bound, value, CPU time (the LP: its own solve, wall)")
            upper, cpu = _cpu(lambda scenario=scenario: upper_bound(scenario).return_)
            bounds = [PolicyBound(upper, UPPER_NAME, ADAPTIVE)]
            print(f"  {'upper':<22} {upper:8.3f} {cpu:7.1f} s   holds for every policy")
            for b in budgets:
                result, cpu = _cpu(lambda b=b, scenario=scenario: solve_optimum(scenario, budget=b))
                listed = policy_bounds(result)
                bounds += listed
                print(f"  {'lp, ' + b:<22} {_num(result.lp_bound)} {result.lp_time_s or 0.0:7.1f} s   "
                      + ("every policy" if any(x.name.startswith("lp") for x in listed) else "dominated by milp"))
                valid = [x for x in listed if x.name.startswith("milp")]
                scope = "every policy" if valid and valid[0].holds_for == ADAPTIVE else (
                    "open-loop plans" if valid else "none (a walk can end early)")
                print(f"  {'milp, ' + b:<22} {_num(result.bound)} {cpu:7.1f} s   holds for: {scope}; "
                      f"best walk {_num(result.objective)}, {result.nodes} nodes, {result.status}")
            if args.hindsight_samples:
                hind, cpu = _cpu(lambda scenario=scenario: hindsight_bound(scenario, budget=hb))
                if hind.status == "ok":
                    bounds.append(hind.policy_bound())
                    kind = "linear relaxation per table" if hb.max_nodes == 0 else f"{hb.max_nodes} nodes per table"
                    print(f"  {'hindsight':<22} {hind.mean:8.3f} {cpu:7.1f} s   ± {hind.ci95:.3f} over {hb.samples} "
                          f"tables ({kind}); upper limit {hind.upper_limit:.3f} holds for every policy")
                else:
                    print(f"  hindsight: {hind.status}: {hind.message}")
            print(f"  {'algorithm':<14} {'class':<10} {'return':>8} {'gap':>7}  bound          cpu")
            for name in algorithms:
                settings = {"budget": budgets[-1]} if name == "milp" else {}
                summary, extra, cpu = _evaluate(name, scenario, settings, args.episodes)
                policy_class = extra.get("policy_class", ADAPTIVE)
                best = _tightest(bounds, policy_class)
                gap = (best.value - summary.mean) / abs(best.value) if best else math.nan
                print(f"  {name:<14} {policy_class:<10} {summary.mean:8.3f} {100 * gap:6.1f}%  "
                      f"{best.name if best else '-':<14} {cpu:5.0f} s", flush=True)
    print("\ngap: (tightest bound that holds for the class - mean return) / |bound|; cpu: this process's CPU "
          "time (one core).")


def tiny(args: argparse.Namespace, algorithms: list[str]) -> None:
    scenario = Scenario.preset("tiny", **TINY_FADING)
    print(f"\nPart 2: tiny with Rayleigh fading and link failures ({TINY_FADING})")
    optimum, cpu = _cpu(lambda: adaptive_optimum(scenario))
    value = optimum.value
    print(f"  {'optimal adaptive (DP)':<26} {value:8.4f} {cpu:7.1f} s   {optimum.states} states, "
          f"{optimum.kernel_steps} kernel steps")
    exact = MilpBudget(max_nodes=100_000, rel_gap=0.0)
    result, cpu = _cpu(lambda: solve_optimum(scenario, budget=exact))
    hind, hcpu = _cpu(lambda: hindsight_bound(scenario, budget=HindsightBudget(samples=args.tiny_samples,
                                                                                max_nodes=100_000)))
    open_loop = "open-loop plans" + (
        ", but a walk can end early here: none" if result.details.get("can_end_early") else ""
    )
    rows = [("upper", upper_bound(scenario).return_, 0.0, "every policy"),
            ("lp (expected)", result.lp_bound, result.lp_time_s, "every policy"),
            ("milp (expected)", result.bound, cpu, open_loop),
            (f"hindsight mean, {args.tiny_samples} tables", hind.mean, hcpu,
             f"± {hind.ci95:.4f}; {hind.proven} tables solved to optimality"),
            ("hindsight upper limit", hind.upper_limit, 0.0, "every policy (97.5 % confidence)")]
    for name, bound, seconds, note in rows:
        print(f"  {name:<26} {bound:8.4f} {seconds:7.1f} s   slack {bound - value:+.4f} "
              f"({100 * (bound - value) / abs(value):+.1f} %); holds for {note}" if "tables" not in name else
              f"  {name:<26} {bound:8.4f} {seconds:7.1f} s   slack {bound - value:+.4f} "
              f"({100 * (bound - value) / abs(value):+.1f} %); {note}")
    print(f"  {'algorithm':<14} {'class':<10} {'return':>17} {'below the DP by':>16}")
    evaluation = evaluate(AdaptivePolicy(), make_env(GRID, scenario), args.tiny_episodes, seed=EVALUATION_SEED)
    summary = evaluation.summary["return"]
    print(f"  {'DP policy':<14} {ADAPTIVE:<10} {summary.mean:8.4f} ± {summary.ci95:.4f} {value - summary.mean:+16.4f}")
    for name in algorithms:
        settings = {"budget": "default"} if name == "milp" else {}
        summary, extra, _ = _evaluate(name, scenario, settings, args.tiny_episodes)
        print(f"  {name:<14} {extra.get('policy_class', ADAPTIVE):<10} {summary.mean:8.4f} ± {summary.ci95:.4f} "
              f"{value - summary.mean:+16.4f}", flush=True)


def _num(value: float | None, width: int = 8, digits: int = 3) -> str:
    return f"{'-':>{width}}" if value is None else f"{value:{width}.{digits}f}"


if __name__ == "__main__":
    main()
