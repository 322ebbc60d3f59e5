"""Path length each OMPL planner reaches at fixed time limits, around a sphere and in the harbour.

For each planner and time limit, the median over ``--runs`` runs of the (simplified) path
length, its excess over the optimum, and the number of exact solutions. Sphere: the
analytic optimum (tangent - great-circle arc - tangent), and the same around the sphere
grown by the motion-check margin that ``plan_path_3d`` keeps. Harbour: the straight line
from south of the pier to above the wreck is blocked by the pier only, so the optimum is
the two-segment path over the pier's far vertical edge (x = 60, y = 90) at constant depth.
OMPL's seed is process-wide and set once (``--seed``), so the runs are successive draws of
one seeded stream. Usage:

    python benchmarks/bench_paths3d.py [--limits 0.1 0.5 1.0] [--runs 3] [--planners InformedRRTstar RRTstar ...]
"""

from __future__ import annotations

import sys
from pathlib import Path

# keep this folder off the path: the planners package must not be shadowed by a script here
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import argparse
import math
import statistics

import numpy as np

from planners.paths3d import available_planners, plan_path_3d
from swiptopt.scenario import Scenario, Sphere

CUBE = ((0.0, 0.0, 0.0), (100.0, 100.0, 100.0))
BALL = Sphere((50.0, 50.0, 50.0), 15.0)
SPHERE_START, SPHERE_GOAL = (10.0, 50.0, 50.0), (90.0, 50.0, 50.0)
HARBOUR_CELLS = ((0, 8, 1), (14, 15, 1))  # south of the pier -> above the wreck
PIER_EDGE_XY = (60.0, 90.0)  # the pier's corner the shortest harbour path bends round


def shortest_around_sphere_m(a, b, center, radius) -> float:  # type: ignore[no-untyped-def]
    """Tangent from a, great-circle arc in the plane of a, b and the centre, tangent to b
    (the straight segment if it misses the ball)."""
    a, b, c = (np.asarray(v, dtype=float) for v in (a, b, center))
    ab = b - a
    t = np.clip((c - a) @ ab / (ab @ ab), 0.0, 1.0)
    if np.linalg.norm(a + t * ab - c) >= radius:
        return float(np.linalg.norm(ab))
    da, db = np.linalg.norm(a - c), np.linalg.norm(b - c)
    angle = math.acos(np.clip((a - c) @ (b - c) / (da * db), -1.0, 1.0))
    arc = angle - math.acos(radius / da) - math.acos(radius / db)
    return float(math.sqrt(da**2 - radius**2) + math.sqrt(db**2 - radius**2) + radius * arc)


def run_case(title, start, goal, world, bounds, references, planners, limits, runs, seed):  # type: ignore[no-untyped-def]
    """``references``: (name, metres) pairs; the excess is relative to the first."""
    print(f"\n{title}: start {tuple(map(float, start))} -> goal {tuple(map(float, goal))}")
    for name, value in references:
        print(f"  {name}: {value:.3f} m")
    reference = references[0][1]
    header = "  " + f"{'planner':<16}" + "".join(f"{f'{t:g} s':>22}" for t in limits)
    print(header)
    for name in planners:
        cells = []
        for limit in limits:
            results = [
                plan_path_3d(start, goal, world, planner=name, time_limit_s=limit, bounds=bounds, seed=seed)
                for _ in range(runs)
            ]
            lengths = [r.length_m for r in results if r.exact]
            if lengths:
                med = statistics.median(lengths)
                cells.append(f"{med:8.2f} {100 * (med / reference - 1):+6.2f}% {len(lengths)}/{runs}")
            else:
                cells.append(f"{'no path':>16} 0/{runs}")
        print("  " + f"{name:<16}" + "".join(f"{c:>22}" for c in cells))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--limits", type=float, nargs="+", default=[0.1, 0.5, 1.0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--planners", nargs="+", default=None, help="default: every planner the OMPL build has")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    planners = args.planners or list(available_planners())

    print(f"median path length (m), excess over the reference, exact solutions / runs; seed {args.seed}")
    optimum = shortest_around_sphere_m(SPHERE_START, SPHERE_GOAL, BALL.center_m, BALL.radius_m)
    probe = plan_path_3d(
        SPHERE_START, SPHERE_GOAL, [BALL], planner="RRTConnect", bounds=CUBE, time_limit_s=0.1, seed=args.seed
    )
    margin = probe.check_spacing_m / 2
    grown = shortest_around_sphere_m(SPHERE_START, SPHERE_GOAL, BALL.center_m, BALL.radius_m + margin)
    run_case(
        f"sphere r = {BALL.radius_m:g} m in a 100 m cube", SPHERE_START, SPHERE_GOAL, [BALL], CUBE,
        [("analytic optimum", optimum), (f"optimum around the sphere grown by the check margin {margin:.3f} m", grown)],
        planners, args.limits, args.runs, args.seed,
    )
    harbour = Scenario.preset("harbour")
    start, goal = (harbour.cell_centers_m[harbour.cell_index(c)] for c in HARBOUR_CELLS)
    edge = np.array([*PIER_EDGE_XY, start[2]])
    around = float(np.linalg.norm(edge - start) + np.linalg.norm(goal - edge))
    run_case(
        "harbour preset", start, goal, harbour, None,
        [
            ("optimum round the pier's edge", around),
            ("straight line (blocked by the pier)", float(np.linalg.norm(goal - start))),
        ],
        planners, args.limits, args.runs, args.seed,
    )


if __name__ == "__main__":
    main()
