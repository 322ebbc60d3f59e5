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
    OmplTourPlanner,
    StraightLinePlanner,
    _Follower,
    Leg,
    trajectory_return,
)
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
    }


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
        out["deterministic"][str(layout)] = {"plan": _plan_record(planner), "parts": parts, "path_m": env.path.tolist()}
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


def test_the_ompl_tour_follows_its_waypoints_and_the_pier_matters(runs):
    """The executed path of the OMPL tour is its planned trajectory (which runs along the
    legs' waypoints); on every layout the straight line gives stops up at the obstacles,
    and the OMPL tour routes at least one leg round them and gives nothing up."""
    for layout, record in runs[0]["layouts"].items():
        ompl = record["ompl"]
        path = np.asarray(ompl["path_m"])
        planned = np.asarray(ompl["plan"]["positions_m"])[: len(path)]
        assert np.abs(path - planned).max() < 1e-6, layout
        on_legs = np.concatenate([_dense(np.asarray(leg["waypoints_m"]), 0.5) for leg in ompl["plan"]["legs"]])
        # every planned position is a waypoint, on a leg, or a hover point
        for position in planned:
            nearest = np.min(np.linalg.norm(on_legs - position, axis=1))
            assert nearest < 0.5, (layout, position)
        assert ompl["given_up"] == []
        assert any(leg["source"] == "ompl" for leg in ompl["plan"]["legs"]), layout
        assert record["straight"]["given_up"], layout  # the straight legs hit something


def test_the_ompl_tour_beats_the_straight_line_on_mean_return(runs):
    ompl = [np.mean(r["ompl"]["returns"]) for r in runs[0]["layouts"].values()]
    straight = [np.mean(r["straight"]["returns"]) for r in runs[0]["layouts"].values()]
    assert np.mean(ompl) > np.mean(straight) + 1.0, (ompl, straight)
    assert all(o > s for o, s in zip(ompl, straight)), (ompl, straight)


def test_the_plans_model_return_is_the_envs_replayed_return_on_a_deterministic_channel(runs):
    """No fading and no link failures: the per-step model is the simulator, so the plan's
    model return must be the env's return up to float rounding (1e-9 relative)."""
    for layout, record in runs[0]["deterministic"].items():
        env_return = sum(sum(p.values()) for p in record["parts"])
        model = record["plan"]["model_return"]
        assert model == pytest.approx(env_return, rel=1e-9, abs=1e-9), layout
        path = np.asarray(record["path_m"])
        assert np.abs(path - np.asarray(record["plan"]["positions_m"])[: len(path)]).max() < 1e-6


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
    assert trajectory_return(env.world, plan.positions_m, plan.actions) == plan.model_return
    assert plan.candidates == {5: plan.model_return}


def test_a_blocked_straight_leg_is_given_up_without_entering_the_pier():
    """The executor's rule: a move that makes no progress gives the stop up and heads for the
    next stop straight from where it is."""
    env = AuvSwiptContinuousEnv(preset="harbour", layout_seed=0, start_cell=(3, 7, 2))  # (35, 75, 25)
    env.reset(seed=0)
    north = np.array([35.0, 125.0, 25.0])  # across the pier
    east = np.array([85.0, 75.0, 25.0])
    legs = (Leg(np.array([[35.0, 75.0, 25.0], north]), 0.0, 5, "straight (obstacles ignored)"),
            Leg(np.array([north, east]), 0.0, 8, "straight (obstacles ignored)"))
    follower = _Follower(legs, np.array([2, 3]), env.world.max_step_m)
    for _ in range(12):
        env.step(follower.action(env.position))
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
