"""The continuous world's planners (planners.continuous) on the harbour preset.

The OMPL tour runs in fresh processes (OMPL's seed is process-wide and other tests in this
process plan unseeded): :func:`harbour_runs` does every OMPL measurement at once and two
fresh processes run it, which is also the same-seed check.
"""

from __future__ import annotations

import concurrent.futures
import math

import numpy as np
import pytest

pytest.importorskip("ompl")
pytest.importorskip("sklearn")

from planners.continuous import (  # noqa: E402
    ARRIVAL_TOLERANCE_M,
    ContinuousPlan,
    Executor,
    Leg,
    OmplTourPlanner,
    PointService,
    StraightLinePlanner,
    leg_steps,
    point_model,
    trajectory_return,
)
from planners.paths3d import path_energy_j  # noqa: E402
from swiptopt import evaluate  # noqa: E402
from swiptopt.benchmark.processes import qualified_name, run_in_fresh_process  # noqa: E402
from swiptopt.env_continuous import AuvSwiptContinuousEnv  # noqa: E402
from swiptopt.errors import ConfigError  # noqa: E402
from swiptopt.scenario import Scenario  # noqa: E402

#: Harbour layouts where the pier (and the hull) lie across straight legs of the tour: the
#: straight-line planner gives stops up on each of them (asserted below).
LAYOUTS = (3, 6, 8)
#: Tiny budgets: a fixed K, 150 OMPL iterations per leg, short episodes.
SETTINGS = {"k": 5, "search_evaluations": 60}
OMPL_SETTINGS = {"ompl_iterations": 150}
STEPS = 80
EPISODES = 2
DETERMINISTIC = {"channel": "none", "failure_prob_min": 0.0, "failure_prob_max": 0.0}


def _plan_record(planner) -> dict:  # type: ignore[no-untyped-def]
    p = planner.plan_
    return {
        "hover_points_m": p.hover_points_m.tolist(),
        "legs": [{"waypoints_m": leg.waypoints_m.tolist(), "energy_j": leg.energy_j, "steps": leg.steps,
                  "source": leg.source} for leg in p.legs],
        "dwell_steps": p.dwell_steps.tolist(),
        "dwell_value": p.dwell_value,
        "model_return": p.model_return,
        "positions_m": p.positions_m.tolist(),
        "ompl_statuses": p.ompl_statuses,
        "status": p.status,
        "routes": [route.waypoints_m.tolist() for route in p.routes.values()],
    }


def _executor_record(planner) -> dict:  # type: ignore[no-untyped-def]
    """What the executor did in the last episode: stops given up, skipped, dwells cut,
    lingering, and whether it reached the end phase."""
    f = planner._executor
    return {"given_up": list(f.given_up), "skipped": list(f.skipped), "cut": list(f.cut),
            "lingered": f.lingered_steps, "end_phase": f.end_phase}


def harbour_runs(seed: int) -> dict:
    """Both planners on :data:`LAYOUTS` (plans, returns, the executed path of the last
    episode, stops given up) and the OMPL tour replayed on a deterministic channel, every
    step's reward parts recorded. A fresh process runs it (module docstring)."""
    out: dict = {"layouts": {}, "deterministic": {}}
    for layout in LAYOUTS:
        env = AuvSwiptContinuousEnv(preset="harbour", layout_seed=layout, episode_steps=STEPS)
        record = {}
        for name, planner in (("ompl", OmplTourPlanner(seed, **SETTINGS, **OMPL_SETTINGS)),
                              ("straight", StraightLinePlanner(seed, **SETTINGS))):
            result = evaluate(planner, env, EPISODES, seed=100)
            record[name] = {
                "returns": [r["return"] for r in result.records],
                "metrics": result.records,
                "path_m": env.path.tolist(),
                "given_up": list(planner.given_up_),
                "executor": _executor_record(planner),
                "plan": _plan_record(planner),
            }
        out["layouts"][str(layout)] = record
    for layout in (6, 8):
        env = AuvSwiptContinuousEnv(preset="harbour", layout_seed=layout, episode_steps=STEPS, **DETERMINISTIC)
        planner = OmplTourPlanner(seed, **SETTINGS, **OMPL_SETTINGS)
        obs, info = env.reset(seed=0)
        planner.begin_episode(env, obs, info)
        parts, done = [], False
        while not done:
            obs, _, terminated, truncated, step_info = env.step(planner.predict(obs))
            parts.append(step_info["reward_parts"])
            done = terminated or truncated
        out["deterministic"][str(layout)] = {"plan": _plan_record(planner), "parts": parts, "path_m": env.path.tolist(),
                                             "executor": _executor_record(planner)}
    return out


@pytest.fixture(scope="module")
def runs() -> list[dict]:
    """:func:`harbour_runs` with the same seed in two fresh processes, side by side."""
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        outcomes = list(pool.map(lambda _: run_in_fresh_process(qualified_name(harbour_runs), 0), range(2)))
    for outcome in outcomes:
        assert outcome.error is None, f"{outcome.error}\n{outcome.detail}"
    return [outcome.value for outcome in outcomes]


def _dense(path_m: np.ndarray, spacing_m: float = 0.05) -> np.ndarray:
    parts = [p + np.linspace(0.0, 1.0, max(2, math.ceil(np.linalg.norm(q - p) / spacing_m) + 1))[:, None] * (q - p)
             for p, q in zip(path_m[:-1], path_m[1:])]
    return np.concatenate(parts) if parts else path_m


def test_same_seed_same_plans_and_metrics_in_two_fresh_processes(runs):
    assert runs[0] == runs[1]


def test_no_executed_step_enters_an_obstacle(runs):
    harbour = Scenario.preset("harbour")
    for layout, record in runs[0]["layouts"].items():
        for name in ("ompl", "straight"):
            path = np.asarray(record[name]["path_m"])
            assert len(path) == STEPS + 1 or record[name]["metrics"][-1]["steps"] < STEPS
            assert not harbour.is_blocked(_dense(path)).any(), (layout, name)
        for leg in record["ompl"]["plan"]["legs"]:  # the planned legs themselves are free
            assert not harbour.is_blocked(_dense(np.asarray(leg["waypoints_m"]))).any()


def test_the_ompl_tour_moves_only_along_its_routes_and_the_pier_matters(runs):
    """Every position the OMPL tour's executor reaches, in the env (fading, link failures)
    and in the plan, lies on one of its routes between sites (the executor reacts to the
    nodes' state, so the env's path may leave the planned order, never the routes); on every
    layout the straight line gives stops up at the obstacles, and the OMPL tour routes at
    least one leg round them and gives nothing up."""
    for layout, record in runs[0]["layouts"].items():
        ompl = record["ompl"]
        on_routes = np.concatenate([_dense(np.asarray(route), 0.25) for route in ompl["plan"]["routes"]])
        for path in (np.asarray(ompl["path_m"]), np.asarray(ompl["plan"]["positions_m"])):
            nearest = np.min(np.linalg.norm(path[:, None, :] - on_routes[None, :, :], axis=2), axis=1)
            assert nearest.max() < 0.25, layout
        assert ompl["given_up"] == []
        assert any(leg["source"] == "ompl" for leg in ompl["plan"]["legs"]), layout
        assert record["straight"]["given_up"], layout  # the straight legs hit something


def test_the_ompl_tour_beats_the_straight_line_on_mean_return(runs):
    ompl = [np.mean(r["ompl"]["returns"]) for r in runs[0]["layouts"].values()]
    straight = [np.mean(r["straight"]["returns"]) for r in runs[0]["layouts"].values()]
    assert np.mean(ompl) > np.mean(straight) + 1.0, (ompl, straight)
    assert all(o > s for o, s in zip(ompl, straight)), (ompl, straight)


def test_the_plans_model_return_is_the_envs_replayed_return_on_a_deterministic_channel(runs):
    """No fading and no link failures: the per-step model is the simulator, and the model
    runs the executor's own reactions on its own state, so the plan's model return must be
    the env's return up to float rounding (1e-9 relative), on the same path; the executor
    did react (cut a dwell, skipped a stop or reached the end phase)."""
    for layout, record in runs[0]["deterministic"].items():
        env_return = sum(sum(p.values()) for p in record["parts"])
        model = record["plan"]["model_return"]
        assert model == pytest.approx(env_return, rel=1e-9, abs=1e-9), layout
        path = np.asarray(record["path_m"])
        assert path.shape == np.asarray(record["plan"]["positions_m"]).shape
        assert np.abs(path - np.asarray(record["plan"]["positions_m"])).max() < 1e-6
    reactions = [r["executor"] for r in runs[0]["deterministic"].values()]
    assert any(r["cut"] or r["skipped"] or r["end_phase"] for r in reactions), reactions


def test_the_dwell_programs_value_bounds_what_the_stops_earn(runs):
    """The steps spent at the stops (arrivals and dwells) earn at most the dwell program's
    optimum (their whole steps are a feasible dwell for it, and nodes served on the way hold
    less), and at least that optimum less one step's worth at every stop (the rounding)."""
    for layout, record in runs[0]["deterministic"].items():
        plan = record["plan"]
        hover = np.asarray(plan["hover_points_m"])
        path = np.asarray(record["path_m"])[1:]
        at_stop = np.min(np.linalg.norm(path[:, None, :] - hover[None, :, :], axis=2), axis=1) < ARRIVAL_TOLERANCE_M
        service = np.array([p["throughput"] + p["harvest"] for p in record["parts"]])
        earned = float(service[at_stop].sum())
        travel = float(service[~at_stop].sum())
        assert earned <= plan["dwell_value"] + 1e-9 * max(1.0, plan["dwell_value"]), layout
        best_step = float(service.max())
        # what the travel steps took is no longer there for the stops
        assert earned >= plan["dwell_value"] - travel - len(hover) * best_step, layout


# --------------------------------------------------------------- in this process, no OMPL


def test_travel_and_dwell_fill_the_episode_and_the_model_scores_the_straight_plan():
    """Without obstacles in its way the straight-line plan is executed as planned: its model
    return is the env's return on a deterministic channel; travel + dwell = the episode."""
    env = AuvSwiptContinuousEnv(preset="harbour", layout_seed=4, episode_steps=60, **DETERMINISTIC)
    planner = StraightLinePlanner(0, **SETTINGS)
    result = evaluate(planner, env, 1, seed=0)
    plan = planner.plan_
    assert planner.given_up_ == []
    assert sum(leg.steps for leg in plan.legs) + int(plan.dwell_steps.sum()) == 60
    assert plan.model_return == pytest.approx(result.records[0]["return"], rel=1e-9)
    assert trajectory_return(env.world, plan.positions_m, plan.actions) == pytest.approx(plan.model_return, rel=1e-12)
    assert plan.candidates == {5: plan.model_return}


def test_k_patience_searches_down_from_k_max_and_stops_below_the_best():
    """K from k_max down, stopping k_patience K's below the best so far: the K's it tries
    are the full search's, with the same model returns, and it keeps the best of them."""
    env = AuvSwiptContinuousEnv(preset="harbour", layout_seed=4, episode_steps=60, **DETERMINISTIC)
    full = StraightLinePlanner(0, k_max=4, k_patience=None, search_evaluations=20).make_plan(env.world, env.scenario)
    patient = StraightLinePlanner(0, k_max=4, k_patience=1, search_evaluations=20).make_plan(env.world, env.scenario)
    tried = list(patient.candidates)
    assert tried == list(range(4, 4 - len(tried), -1))
    assert patient.k == max(tried, key=patient.candidates.get)
    assert tried[-1] == max(1, patient.k - 1)  # one K below the best, and no further
    assert all(patient.candidates[k] == full.candidates[k] for k in tried)
    assert sorted(full.candidates) == list(range(1, 5))


def _hand_plan(env, points_m, stops, dwell) -> ContinuousPlan:  # type: ignore[no-untyped-def]
    """A plan over the start and ``points_m`` (sites 1..), straight routes between every
    pair, visiting the sites ``stops`` with the given dwells."""
    world = env.world
    sites = np.vstack([world.start_m, points_m])
    routes = {}
    for i in range(len(sites)):
        for j in range(1, len(sites)):
            if i != j:
                way = np.stack([sites[i], sites[j]])
                routes[i, j] = Leg(way, path_energy_j(way, env.scenario), leg_steps(way, world.max_step_m), "straight")
    legs = tuple(routes[a, b] for a, b in zip((0,) + tuple(stops[:-1]), stops))
    return ContinuousPlan(
        k=len(points_m), hover_points_m=sites[list(stops)], groups=(), legs=legs,
        dwell_steps=np.asarray(dwell, dtype=np.int64), dwell_value=None, dwell_status="given", model_return=0.0,
        positions_m=sites[:1], actions=np.zeros((0, 3), dtype=np.float32), status="by hand", sites_m=sites,
        routes=routes, stop_sites=tuple(stops), site_model=point_model(world, sites),
    )


def _run(env, follower) -> tuple[float, np.ndarray]:  # type: ignore[no-untyped-def]
    """Run ``follower`` in ``env`` for an episode: the return and the path."""
    env.reset(seed=0)
    total, done = 0.0, False
    while not done:
        state = env.state
        action = follower.action(env.position, state.data_left, env.world.capacity - state.energy, state.t)
        _, reward, terminated, truncated, _ = env.step(action)
        total += reward
        done = terminated or truncated
    return total, env.path


def test_the_executor_skips_served_stops_cuts_served_dwells_and_ends_where_it_still_earns():
    """A hand-made tour on a deterministic channel: stop 1 hovers long enough to serve its
    nodes, so its dwell is cut; stop 2, a hair away, covers the same nodes and is skipped;
    the steps left go to site 3, which the tour left out. The model rolls the same executor
    out on its own state: its return and path are the env's."""
    env = AuvSwiptContinuousEnv(preset="harbour", layout_seed=4, episode_steps=60, **DETERMINISTIC)
    planned = StraightLinePlanner(0, **SETTINGS)
    env.reset(seed=0)
    planned.begin_episode(env)
    p, q = planned.plan_.hover_points_m[:2]
    plan = _hand_plan(env, np.stack([p, p + (0.01, 0.0, 0.0), q]), (1, 2), (40, 5))
    follower = Executor(plan, env.world)
    env_return, path = _run(env, follower)
    assert follower.cut == [0] and follower.skipped == [1] and follower.end_phase
    assert np.linalg.norm(path[-1] - q) < ARRIVAL_TOLERANCE_M  # it ended at site 3
    at_p = np.linalg.norm(path - p, axis=1) < ARRIVAL_TOLERANCE_M
    assert 1 <= at_p.sum() < 41  # arrived, left before the planned 40 hover steps

    planner = StraightLinePlanner(0, adaptive=True)
    planner._service = PointService(env.world)
    scored = planner._scored(env.world, plan)
    assert scored.model_return == pytest.approx(env_return, rel=1e-9)
    np.testing.assert_allclose(scored.positions_m, path, atol=1e-9)
    replayed = trajectory_return(env.world, scored.positions_m, scored.actions)
    assert replayed == pytest.approx(scored.model_return, rel=1e-12)

    fixed = Executor(plan, env.world, adaptive=False)  # the plan as planned: no reactions
    fixed_return, fixed_path = _run(env, fixed)
    assert fixed.cut == fixed.skipped == [] and not fixed.end_phase
    assert np.linalg.norm(fixed_path[-1] - plan.sites_m[2]) < ARRIVAL_TOLERANCE_M
    assert env_return > fixed_return


def test_a_blocked_straight_leg_is_given_up_without_entering_the_pier():
    """The executor's rule: a move that makes no progress gives the stop up and heads for the
    next stop straight from where it is."""
    env = AuvSwiptContinuousEnv(preset="harbour", layout_seed=0, start_cell=(3, 7, 2))  # (35, 75, 25)
    north = np.array([35.0, 125.0, 25.0])  # across the pier
    east = np.array([85.0, 75.0, 25.0])
    follower = Executor(_hand_plan(env, np.stack([north, east]), (1, 2), (2, 3)), env.world, adaptive=False)
    env.reset(seed=0)
    for _ in range(12):
        state = env.state
        env.step(follower.action(env.position, state.data_left, env.world.capacity - state.energy, state.t))
    path = env.path
    assert follower.given_up == [0]
    assert not env.scenario.is_blocked(_dense(path)).any()
    assert path[:, 1].max() < 90.0  # stopped at the pier's face (y = 90)
    assert np.linalg.norm(path[-1] - east) < 1e-3  # then went on and hovers at the next stop


@pytest.mark.parametrize(
    ("cls", "setting", "value"),
    [
        (OmplTourPlanner, "k", 0),
        (OmplTourPlanner, "k_max", 2.5),
        (OmplTourPlanner, "ompl_iterations", 0),
        (OmplTourPlanner, "ompl_planner", "PRMstar"),
        (OmplTourPlanner, "ompl_planner", "AORRTC"),
        (OmplTourPlanner, "ompl_legs", "some"),
        (OmplTourPlanner, "clearance_m", -1.0),
        (OmplTourPlanner, "clearance_m", math.inf),
        (StraightLinePlanner, "search_evaluations", -1),
        (StraightLinePlanner, "prune", "yes"),
        (StraightLinePlanner, "tsp_time_limit_s", 0),
        (StraightLinePlanner, "adaptive", 1),
        (OmplTourPlanner, "linger_steps", -1),
        (OmplTourPlanner, "k_patience", 0),
        (StraightLinePlanner, "seed", -1),
    ],
)
def test_bad_settings_are_refused_naming_the_setting(cls, setting, value):
    with pytest.raises(ConfigError) as info:
        cls(**{setting: value})
    assert info.value.field == setting


def test_predict_before_begin_episode_says_what_to_do():
    with pytest.raises(RuntimeError, match="begin_episode"):
        StraightLinePlanner().predict(np.zeros(4))
