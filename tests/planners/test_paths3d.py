import json
import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest

pytest.importorskip("ompl")

from planners import paths3d  # noqa: E402
from planners.paths3d import PathResult, path_energy_j, plan_path_3d, segment_energy_j  # noqa: E402
from swiptopt import auv  # noqa: E402
from swiptopt.errors import ConfigError  # noqa: E402
from swiptopt.scenario import Box, Scenario, Sphere  # noqa: E402

CUBE = ((0.0, 0.0, 0.0), (100.0, 100.0, 100.0))
BALL = Sphere((50.0, 50.0, 50.0), 15.0)
A, B = (10.0, 50.0, 50.0), (90.0, 50.0, 50.0)


def shortest_around_sphere_m(a, b, center, radius):
    """Shortest path from a to b avoiding a ball: straight if the segment misses it, else
    tangent segment + great-circle arc (in the plane through a, b and the centre) + tangent."""
    a, b, c = (np.asarray(v, dtype=float) for v in (a, b, center))
    ab = b - a
    t = np.clip((c - a) @ ab / (ab @ ab), 0.0, 1.0)
    if np.linalg.norm(a + t * ab - c) >= radius:
        return float(np.linalg.norm(ab))
    da, db = np.linalg.norm(a - c), np.linalg.norm(b - c)
    angle = math.acos(np.clip((a - c) @ (b - c) / (da * db), -1.0, 1.0))
    arc = angle - math.acos(radius / da) - math.acos(radius / db)
    return math.sqrt(da**2 - radius**2) + math.sqrt(db**2 - radius**2) + radius * arc


def dense_points(waypoints, spacing_m=0.02):
    """Points along every segment of a polyline, at most ``spacing_m`` apart."""
    parts = []
    for p, q in zip(waypoints[:-1], waypoints[1:]):
        n = max(2, int(np.ceil(np.linalg.norm(q - p) / spacing_m)) + 1)
        parts.append(p + np.linspace(0.0, 1.0, n)[:, None] * (q - p))
    return np.concatenate(parts)


def needs(*names):
    missing = [n for n in names if n not in paths3d.available_planners()]
    if missing:
        pytest.skip(f"OMPL build lacks {missing}")


def test_analytic_reference_is_right():
    # d = 40, r = 15: tangents sqrt(40^2 - 15^2) each, arc 15 (pi - 2 acos(15/40))
    expected = 2 * math.sqrt(1375.0) + 15.0 * (math.pi - 2 * math.acos(15 / 40))
    assert shortest_around_sphere_m(A, B, BALL.center_m, 15.0) == pytest.approx(expected)
    assert shortest_around_sphere_m((0, 0, 0), (10, 0, 0), (5, 20, 0), 1.0) == pytest.approx(10.0)


@pytest.mark.parametrize("planner", ["InformedRRTstar", "BITstar"])
def test_path_around_a_sphere_is_clear_and_near_the_analytic_optimum(planner):
    needs(planner)
    result = plan_path_3d(A, B, [BALL], planner=planner, bounds=CUBE, time_limit_s=1.0)
    assert isinstance(result, PathResult)
    assert result.status == "exact" and result.exact
    np.testing.assert_array_equal(result.waypoints[0], A)
    np.testing.assert_array_equal(result.waypoints[-1], B)
    points = dense_points(result.waypoints)
    assert np.all(np.linalg.norm(points - np.asarray(BALL.center_m), axis=1) > BALL.radius_m)
    assert np.all((points >= 0.0) & (points <= 100.0))
    optimum = shortest_around_sphere_m(A, B, BALL.center_m, BALL.radius_m)
    assert optimum <= result.length_m <= 1.03 * optimum  # shorter would mean it cut through
    assert result.length_m == pytest.approx(np.linalg.norm(np.diff(result.waypoints, axis=0), axis=1).sum())
    assert result.energy_j is None


def test_clearance_is_kept_along_every_segment():
    result = plan_path_3d(A, B, [BALL], planner="RRTConnect", bounds=CUBE, time_limit_s=0.5, clearance_m=3.0)
    assert result.exact
    gap = np.linalg.norm(dense_points(result.waypoints) - np.asarray(BALL.center_m), axis=1) - BALL.radius_m
    assert gap.min() > 3.0


def test_a_thin_wall_is_not_jumped():
    # a 5 cm wall across most of the volume: only the open band y > 80 lets the AUV by
    wall = Box((49.975, 0.0, 0.0), (50.025, 80.0, 100.0))
    result = plan_path_3d(
        (10.0, 20.0, 50.0), (90.0, 20.0, 50.0), [wall], planner="RRTConnect", bounds=CUBE, time_limit_s=0.5
    )
    assert result.exact
    assert not np.any(wall.contains(dense_points(result.waypoints, spacing_m=0.005)))
    assert result.check_spacing_m <= 0.25 * 0.05 + 1e-12


def test_start_inside_an_obstacle_is_a_config_error_naming_start():
    with pytest.raises(ConfigError, match="Sphere") as info:
        plan_path_3d((50.0, 50.0, 40.0), B, [BALL], bounds=CUBE)
    assert info.value.field == "start"
    with pytest.raises(ConfigError, match="outside the bounds") as info:
        plan_path_3d(A, (90.0, 50.0, 101.0), [BALL], bounds=CUBE)
    assert info.value.field == "goal"
    with pytest.raises(ConfigError, match="seabed") as info:
        plan_path_3d((5.0, 5.0, 15.0), (5.0, 5.0, 39.0), Scenario.preset("harbour"))
    assert info.value.field == "goal"


def test_unknown_planner_or_objective_is_a_config_error_listing_the_choices():
    with pytest.raises(ConfigError, match="RRTstar") as info:
        plan_path_3d(A, B, [BALL], bounds=CUBE, planner="RRTstr")
    assert info.value.field == "planner" and "RRTstr" in str(info.value)
    with pytest.raises(ConfigError, match="'length', 'energy'") as info:
        plan_path_3d(A, B, [BALL], bounds=CUBE, objective="time")
    assert info.value.field == "objective"


def test_invalid_combinations_are_refused():
    harbour = Scenario.preset("harbour")
    with pytest.raises(ConfigError) as info:
        plan_path_3d(A, B, [BALL], bounds=CUBE, objective="energy")
    assert info.value.field == "objective"
    with pytest.raises(ConfigError, match="AORRTC.*segmentation fault") as info:
        plan_path_3d((5.0, 85.0, 15.0), (95.0, 85.0, 15.0), harbour, planner="AORRTC")
    assert info.value.field == "planner"
    with pytest.raises(ConfigError, match="deadlock") as info:
        plan_path_3d((5.0, 85.0, 15.0), (95.0, 85.0, 15.0), harbour, planner="PRMstar", objective="energy")
    assert info.value.field == "planner"
    with pytest.raises(ConfigError) as info:
        plan_path_3d(A, B, [BALL], bounds=CUBE, time_limit_s=0.0)
    assert info.value.field == "time_limit_s"
    with pytest.raises(ConfigError) as info:
        plan_path_3d(A, B, [BALL])
    assert info.value.field == "bounds"
    with pytest.raises(ConfigError) as info:
        plan_path_3d(A, B, [BALL], bounds=CUBE, seed=0)
    assert info.value.field == "seed"


@pytest.mark.parametrize("planner", ["InformedRRTstar", "RRTstar"])
def test_an_enclosed_goal_is_a_status_not_an_exception(planner):
    needs(planner)
    goal = (80.0, 50.0, 50.0)
    shell = [  # six 2 m slabs around a 10 m cube of water holding the goal
        Box((73.0, 43.0, 43.0), (75.0, 57.0, 57.0)),
        Box((85.0, 43.0, 43.0), (87.0, 57.0, 57.0)),
        Box((73.0, 43.0, 43.0), (87.0, 45.0, 57.0)),
        Box((73.0, 55.0, 43.0), (87.0, 57.0, 57.0)),
        Box((73.0, 43.0, 43.0), (87.0, 57.0, 45.0)),
        Box((73.0, 43.0, 55.0), (87.0, 57.0, 57.0)),
    ]
    result = plan_path_3d(A, goal, shell, planner=planner, bounds=CUBE, time_limit_s=0.3)
    assert not result.exact and result.status != "exact"
    assert result.status in ("approximate", "timeout")
    if result.status == "approximate":
        np.testing.assert_array_equal(result.waypoints[0], A)
        assert not np.array_equal(result.waypoints[-1], goal)
        assert not any(np.any(box.contains(dense_points(result.waypoints))) for box in shell)
    else:
        assert result.waypoints.shape == (0, 3) and result.length_m == math.inf


def test_harbour_path_between_free_cell_centres_avoids_every_blocked_point():
    harbour = Scenario.preset("harbour")
    centres = harbour.cell_centers_m
    start = centres[harbour.cell_index((0, 8, 1))]  # (5, 85, 15), south of the pier
    goal = centres[harbour.cell_index((14, 15, 1))]  # (145, 155, 15), above the wreck
    assert not harbour.is_blocked(np.stack([start, goal])).any()
    result = plan_path_3d(start, goal, harbour, time_limit_s=1.0)
    assert result.exact
    points = dense_points(result.waypoints)
    assert not harbour.is_blocked(points).any()
    assert np.all((points >= 0.0) & (points <= harbour.extent_m))
    assert result.length_m >= np.linalg.norm(goal - start)
    assert result.energy_j == pytest.approx(path_energy_j(result.waypoints, harbour))


def test_fast_validity_check_agrees_with_the_scenario():
    harbour = Scenario.preset("harbour")
    world, _ = paths3d._world_from(harbour, None)
    free = world.free_fn(0.0)
    points = np.random.default_rng(0).uniform(0.0, 1.0, (20_000, 3)) * harbour.extent_m
    fast = np.array([not free(*p) for p in points])
    np.testing.assert_array_equal(fast, harbour.is_blocked(points))


def test_the_compiled_motion_validator_answers_as_ompls_own():
    """The validator plan_path_3d installs (one compiled call per motion) accepts exactly the
    motions that OMPL's default discrete validator accepts with the same state checker."""
    from ompl import base as ob

    harbour = Scenario.preset("harbour")
    world, _ = paths3d._world_from(harbour, None)
    grow = 1.7
    free = world.free_fn(grow)
    geom, heights = world.geometry(grow)
    space = ob.RealVectorStateSpace(3)
    bounds = ob.RealVectorBounds(3)
    for axis, high in enumerate(harbour.extent_m):
        bounds.setLow(axis, 0.0)
        bounds.setHigh(axis, float(high))
    space.setBounds(bounds)
    space.setLongestValidSegmentFraction(0.004)
    si = ob.SpaceInformation(space)
    si.setStateValidityChecker(lambda s: free(s[0], s[1], s[2]))
    si.setup()
    compiled = paths3d._motion_validator_type()(si, space, geom, heights)
    points = np.random.default_rng(5).uniform(0.0, 1.0, (3000, 3)) * harbour.extent_m
    points = points[[free(*p) for p in points]]  # motions start from valid states
    a, b = space.allocState(), space.allocState()
    agree, accepted = [], 0
    for p, q in zip(points[0::2], points[1::2]):
        for axis in range(3):
            a[axis], b[axis] = float(p[axis]), float(q[axis])
        theirs = si.checkMotion(a, b)
        agree.append(compiled.checkMotion(a, b) == theirs)
        accepted += theirs
    assert all(agree)
    assert 0.05 * len(agree) < accepted < 0.95 * len(agree)  # both answers are common


CURRENT = Scenario(
    length_m=200.0,
    width_m=100.0,
    depth_m=50.0,
    current_mps=(1.2, 0.0, 0.0),  # strong at the surface, none at the bottom
    current_bottom_mps=(0.0, 0.0, 0.0),
    obstacles=(Sphere((100.0, 50.0, 25.0), 12.0),),
)


def test_scalar_energy_matches_the_vectorised_model():
    points = np.random.default_rng(1).uniform(0.0, 1.0, (50, 3)) * CURRENT.extent_m
    for scenario in (CURRENT, CURRENT.replace(current_bottom_mps=None), Scenario.preset("harbour")):
        fast = paths3d._segment_energy_fn(scenario)
        expected = segment_energy_j(points, scenario)
        got = [fast(*p, *q) for p, q in zip(points[:-1], points[1:])]
        np.testing.assert_allclose(got, expected, rtol=1e-12)
        floor = paths3d._min_energy_per_m(scenario)
        assert np.all(expected >= floor * np.linalg.norm(np.diff(points, axis=0), axis=1) * (1 - 1e-12))


def test_quadrature_is_close_to_a_fine_riemann_sum():
    a, b = np.array([10.0, 50.0, 2.0]), np.array([60.0, 40.0, 48.0])
    fine = a + np.linspace(0.0, 1.0, 20_001)[:, None] * (b - a)
    assert path_energy_j(np.stack([a, b]), CURRENT) == pytest.approx(path_energy_j(fine, CURRENT), rel=1e-6)


def test_energy_without_current_is_length_times_a_constant():
    still = CURRENT.replace(current_mps=(0.0, 0.0, 0.0), current_bottom_mps=None)
    result = plan_path_3d((10.0, 50.0, 25.0), (190.0, 50.0, 25.0), still, objective="energy", time_limit_s=0.3)
    assert result.exact
    per_m = (auv.propulsion_power_w(still.speed_mps) + still.hotel_power_w) / still.speed_mps
    assert result.energy_j == pytest.approx(per_m * result.length_m, rel=1e-9)


def test_energy_objective_is_no_worse_than_the_shortest_path_under_a_strong_current():
    a, b = (10.0, 50.0, 25.0), (190.0, 50.0, 25.0)
    # an iteration budget, not the wall clock: the same search however loaded the machine is
    shortest = plan_path_3d(a, b, CURRENT, objective="length", time_limit_s=60.0, iterations=400)
    thrifty = plan_path_3d(a, b, CURRENT, objective="energy", time_limit_s=60.0, iterations=400)
    assert shortest.exact and thrifty.exact
    assert thrifty.energy_j <= 1.02 * shortest.energy_j
    assert thrifty.length_m >= shortest.length_m * (1 - 0.03)
    assert not CURRENT.is_blocked(dense_points(thrifty.waypoints)).any()


def test_start_equal_to_goal_is_a_zero_length_exact_path():
    result = plan_path_3d(A, A, [BALL], bounds=CUBE)
    assert result.exact and result.length_m == 0.0 and result.waypoints.shape == (1, 3)


SEED_SCRIPT = textwrap.dedent(
    """
    import json, sys
    from planners.paths3d import plan_path_3d
    from swiptopt.errors import ConfigError
    from swiptopt.scenario import Sphere
    kw = dict(bounds=((0, 0, 0), (100, 100, 100)), planner="RRTConnect", time_limit_s=0.5)
    ball = [Sphere((50.0, 50.0, 50.0), 15.0)]
    out = {"first": plan_path_3d((10, 50, 50), (90, 50, 50), ball, seed=7, **kw).waypoints.tolist()}
    out["again"] = plan_path_3d((10, 50, 50), (90, 50, 50), ball, seed=7, **kw).waypoints.tolist()
    try:
        plan_path_3d((10, 50, 50), (90, 50, 50), ball, seed=8, **kw)
    except ConfigError as exc:
        out["other_seed"] = exc.field
    print(json.dumps(out))
    """
)


def test_seed_is_set_once_per_process_and_repeats_in_a_fresh_process():
    runs = [
        subprocess.run([sys.executable, "-c", SEED_SCRIPT], capture_output=True, text=True, check=True)
        for _ in range(2)
    ]
    first, second = (json.loads(r.stdout) for r in runs)
    assert all(r.stderr == "" for r in runs)  # OMPL's log is silenced, nothing leaks at exit
    assert first["first"] == second["first"]  # same seed, fresh process: same samples
    assert first["other_seed"] == "seed"  # a second seed is refused, not silently ignored
    assert len(first["again"]) >= 2  # the same seed again is accepted (the stream continues)


LIGHT_SCRIPT = textwrap.dedent(
    """
    import json, sys
    import planners.paths3d as paths3d
    from swiptopt.errors import ConfigError
    from swiptopt.scenario import Sphere
    out = {"ompl_loaded_on_import": "ompl" in sys.modules}
    kw = dict(bounds=((0, 0, 0), (100, 100, 100)), planner="RRTConnect", time_limit_s=0.5)
    ball = [Sphere((50.0, 50.0, 50.0), 15.0)]
    out["unseeded"] = paths3d.plan_path_3d((10, 50, 50), (90, 50, 50), ball, **kw).status
    try:
        paths3d.plan_path_3d((10, 50, 50), (90, 50, 50), ball, seed=7, **kw)
    except ConfigError as exc:
        out["late_seed"] = exc.field
    print(json.dumps(out))
    """
)


def test_import_is_light_and_a_seed_after_unseeded_planning_is_refused():
    run = subprocess.run([sys.executable, "-c", LIGHT_SCRIPT], capture_output=True, text=True, check=True)
    assert run.stderr == ""
    out = json.loads(run.stdout)
    assert out == {"ompl_loaded_on_import": False, "unseeded": "exact", "late_seed": "seed"}


CRASH_SCRIPT = textwrap.dedent(
    """
    import json, sys
    from planners.paths3d import available_planners, plan_path_3d
    from swiptopt.scenario import Scenario
    harbour = Scenario.preset("harbour")
    names = [None, *available_planners()]
    out = {}
    for name in names:
        result = plan_path_3d((5, 165, 15), (185, 25, 5), harbour, planner=name, time_limit_s=0.2)
        out[str(name)] = [result.planner, result.status]
    print(json.dumps(out))
    """
)


def test_the_harbour_case_that_crashed_ompl_runs_with_every_planner():
    """From (5, 165, 15) to (185, 25, 5) in the harbour, the former default planner (AORRTC)
    killed the process every time; now the default and every planner offered plan it. In a
    subprocess, so that a crash fails this test instead of killing the suite."""
    run = subprocess.run([sys.executable, "-c", CRASH_SCRIPT], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, f"the process died with code {run.returncode}: {run.stderr[-2000:]}"
    out = json.loads(run.stdout)
    assert out["None"] == ["InformedRRTstar", "exact"]
    assert "AORRTC" not in out and len(out) >= 10
    assert all(status in ("exact", "approximate", "timeout") for _, status in out.values())


ITERATION_SCRIPT = textwrap.dedent(
    """
    import json
    from planners.paths3d import plan_path_3d
    from swiptopt.scenario import Scenario
    harbour = Scenario.preset("harbour")
    kw = dict(objective="energy", seed=3, iterations=150, clearance_m=1.0)
    out = [plan_path_3d((30, 60, 20), (30, 140, 15), harbour, **kw).waypoints.tolist() for _ in range(2)]
    out.append(plan_path_3d((30, 60, 20), (30, 140, 15), harbour, objective="energy", iterations=1).status)
    print(json.dumps(out))
    """
)


def test_an_iteration_budget_repeats_its_paths_in_fresh_processes():
    """The counting termination condition: the same seed and calls give the same paths in
    two processes (two calls: the stream continues, and still repeats); one iteration cannot
    get round the pier."""
    runs = [subprocess.run([sys.executable, "-c", ITERATION_SCRIPT], capture_output=True, text=True, check=True)
            for _ in range(2)]
    first, second = (json.loads(r.stdout) for r in runs)
    assert first == second
    harbour = Scenario.preset("harbour")
    for path in first[:2]:
        waypoints = np.asarray(path)
        assert len(waypoints) >= 3  # the straight line crosses the pier
        assert not harbour.is_blocked(dense_points(waypoints)).any()
    assert first[2] == "timeout"


@pytest.mark.parametrize("bad", [0, -3, 2.5, True, "100"])
def test_a_bad_iteration_budget_is_refused(bad):
    with pytest.raises(ConfigError) as info:
        plan_path_3d(A, B, [BALL], bounds=CUBE, iterations=bad)
    assert info.value.field == "iterations"


def test_segments_free_agrees_with_dense_sampling_and_keeps_the_clearance():
    harbour = Scenario.preset("harbour")
    rng = np.random.default_rng(4)
    starts = rng.uniform(0.0, 1.0, (300, 3)) * harbour.extent_m
    ends = rng.uniform(0.0, 1.0, (300, 3)) * harbour.extent_m
    free = paths3d.segments_free(starts, ends, harbour, clearance_m=1.0)
    assert 20 < free.sum() < 280  # both outcomes occur
    for p, q, ok in zip(starts, ends, free):
        points = dense_points(np.stack([p, q]), spacing_m=0.1)
        if ok:
            sampled = points[:: max(1, len(points) // 50)]
            assert paths3d.clearance_of_m(sampled, harbour, faces=False).min() >= 1.0 - 1e-9
        blocked = bool(harbour.is_blocked(points).any())
        assert not (ok and blocked)
    # a segment along the pier's face, 3 m off it, has less than 3 m of clearance
    assert paths3d.segments_free([(10, 87, 10)], [(50, 87, 10)], harbour, clearance_m=2.0).tolist() == [True]
    assert paths3d.segments_free([(10, 87, 10)], [(50, 87, 10)], harbour, clearance_m=3.0).tolist() == [False]


def test_clearance_of_points_against_a_box_a_sphere_and_the_faces():
    harbour = Scenario.preset("harbour")
    # 5 m from the surface; 10 m east of the pier's end at mid-depth; inside the pier
    got = paths3d.clearance_of_m([(105.0, 105.0, 5.0), (70.0, 100.0, 20.0), (30.0, 100.0, 20.0)], harbour)
    assert got.tolist() == pytest.approx([5.0, 10.0, -10.0])
