"""run_task decides from the scenario alone (deterministic, and a bound on the search's size)
whether the exact optimum of a task is affordable, and records why when it is not."""

from __future__ import annotations

import planners.bounds
from swiptopt.benchmark.experiment import Experiment
from swiptopt.benchmark.runner import run_task


def tiny_task(**scenario):
    experiment = Experiment.from_dict({
        "name": "tiny-optimum",
        "scenario": {"preset": "tiny", **scenario},
        "layouts": 1,
        "episodes": 1,
        "algorithms": {"random": {}},
    })
    return experiment.tasks()[0].to_dict()


def test_an_unaffordable_optimum_is_skipped_with_its_reason_without_searching(monkeypatch):
    def never(*args, **kwargs):
        raise AssertionError("exact_optimum ran although its bound exceeds the limit")

    monkeypatch.setattr(planners.bounds, "exact_optimum", never)
    result = run_task(tiny_task(episode_steps=30, n_nodes=8))
    extra = result["extra"]
    assert "optimum_return" not in extra
    assert "states" in extra["optimum_skipped"] and f"{planners.bounds.EXACT_STATE_LIMIT:,}" in extra["optimum_skipped"]
    assert len(result["records"]) == 1


def test_an_affordable_optimum_is_computed_and_bounds_the_episode():
    result = run_task(tiny_task())
    extra = result["extra"]
    assert "optimum_skipped" not in extra
    assert result["records"][0]["return"] <= extra["optimum_return"] + 1e-9
    assert extra["optimum_return"] <= extra["upper_bound_return"] + 1e-9


def test_the_instance_decides_not_its_preset_name():
    """A deterministic instance as small as the tiny preset gets its optimum whatever it is
    called; a stochastic one never does."""
    result = run_task(tiny_task(name="small-custom"))
    assert "optimum_return" in result["extra"]
    assert result["records"][0]["return"] <= result["extra"]["optimum_return"] + 1e-9
    fading = run_task(tiny_task(channel="rician"))
    assert "optimum_return" not in fading["extra"] and "optimum_skipped" not in fading["extra"]
