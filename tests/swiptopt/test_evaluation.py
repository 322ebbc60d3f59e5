import math

import numpy as np
import pytest

import swiptopt
from swiptopt.env import AuvSwiptEnv
from swiptopt.evaluation import Summary, t_quantile_975


class Hover:
    def predict(self, obs, deterministic=True):
        return 6


class Dive:
    """Goes straight down, then hovers; records begin_episode calls."""

    def __init__(self):
        self.begun = 0

    def begin_episode(self, env, obs, info):
        self.begun += 1
        self.steps = 0

    def predict(self, obs, deterministic=True):
        self.steps += 1
        return (4, None) if self.steps < 5 else (6, None)  # SB3-style tuple


def test_evaluate_records_and_summary():
    env = AuvSwiptEnv(preset="paper", n_nodes=10)
    result = swiptopt.evaluate(Dive(), env, episodes=5, seed=100)
    assert [r["seed"] for r in result.records] == [100, 101, 102, 103, 104]
    data = np.array([r["data_bits"] for r in result.records])
    s = result.summary["data_bits"]
    assert s.mean == pytest.approx(data.mean())
    assert s.ci95 == pytest.approx(2.776 * data.std(ddof=1) / math.sqrt(5))
    assert (s.min, s.max, s.n) == (data.min(), data.max(), 5)
    again = swiptopt.evaluate(Dive(), AuvSwiptEnv(preset="paper", n_nodes=10), episodes=5, seed=100)
    assert again.records == result.records
    policy = Dive()
    swiptopt.evaluate(policy, env, episodes=3, seed=0)
    assert policy.begun == 3
    assert len(result.to_dataframe()) == 5


def test_summary_leaves_out_missing_values():
    s = Summary.of([1.0, None, 3.0, float("nan")])
    assert (s.mean, s.n, s.missing) == (2.0, 2, 2)
    assert math.isnan(Summary.of([None]).mean)


def test_t_quantiles():
    assert t_quantile_975(1) == pytest.approx(12.706)
    assert t_quantile_975(30) == pytest.approx(2.042)
    assert t_quantile_975(60) == pytest.approx(2.000, abs=2e-3)
    assert t_quantile_975(10_000) == pytest.approx(1.960, abs=1e-3)


def test_bad_episode_count():
    with pytest.raises(swiptopt.ConfigError, match="episodes"):
        swiptopt.evaluate(Hover(), AuvSwiptEnv(preset="tiny"), episodes=0)
