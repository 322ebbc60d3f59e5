import math

import gymnasium as gym
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


# ----------------------------------------------------------------- wrappers and vector envs


class ByObservation:
    """Acts on the observation alone (a single one or a batch): the same actions whatever runs it."""

    def predict(self, obs, deterministic=True):
        return np.asarray(obs) % 7, None


class Left:
    def predict(self, obs, deterministic=True):
        return 0


def _reference(make, episodes=5, seed=7):
    return swiptopt.evaluate(ByObservation(), make(), episodes, seed=seed).records


def _tiny(**kw):
    return AuvSwiptEnv(preset="tiny", **kw)


def test_evaluate_through_standard_wrappers():
    from gymnasium.wrappers import FlattenObservation, RecordEpisodeStatistics, TimeLimit

    reference = swiptopt.evaluate(Dive(), _tiny(), 4, seed=3).records
    for wrap in (
        lambda e: gym.make(swiptopt.ENV_ID, scenario=e.scenario),
        RecordEpisodeStatistics,
        FlattenObservation,  # one-hot tabular observations
        lambda e: TimeLimit(e, 100),  # longer than the episode: changes nothing
        lambda e: RecordEpisodeStatistics(FlattenObservation(TimeLimit(e, 100))),
    ):
        assert swiptopt.evaluate(Dive(), wrap(_tiny()), 4, seed=3).records == reference
    monitor = pytest.importorskip("stable_baselines3.common.monitor").Monitor
    assert swiptopt.evaluate(Dive(), monitor(_tiny()), 4, seed=3).records == reference


def test_a_shorter_time_limit_still_yields_the_metrics():
    from gymnasium.wrappers import TimeLimit

    cut = swiptopt.evaluate(Dive(), TimeLimit(_tiny(), 5), 4, seed=3).records
    short = swiptopt.evaluate(Dive(), _tiny(episode_steps=5), 4, seed=3).records
    assert [r["length"] for r in cut] == [5] * 4
    assert cut == short  # the same five steps, whoever ends the episode
    made = swiptopt.evaluate(Dive(), gym.make(swiptopt.ENV_ID, preset="tiny", max_episode_steps=5), 4, seed=3)
    assert made.records == short


@pytest.mark.parametrize("episodes", [1, 4, 5])
def test_gymnasium_vector_envs_give_the_single_env_records(episodes):
    from gymnasium.vector import AutoresetMode

    reference = _reference(lambda: _tiny(layout_seeds=range(10)), episodes)
    assert len({r["layout_seed"] for r in reference}) > 1 or episodes == 1
    for mode in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP, AutoresetMode.DISABLED):
        envs = gym.vector.SyncVectorEnv([lambda: _tiny(layout_seeds=range(10))] * 2, autoreset_mode=mode)
        assert swiptopt.evaluate(ByObservation(), envs, episodes, seed=7).records == reference, mode


@pytest.mark.parametrize("n_envs", [1, 2, 3])
def test_sb3_vector_envs_give_the_single_env_records(n_envs):
    vec_env = pytest.importorskip("stable_baselines3.common.vec_env")
    monitor = pytest.importorskip("stable_baselines3.common.monitor").Monitor
    reference = _reference(lambda: _tiny(layout_seeds=range(10)))
    venv = vec_env.DummyVecEnv([lambda: monitor(_tiny(layout_seeds=range(10)))] * n_envs)
    assert swiptopt.evaluate(ByObservation(), venv, 5, seed=7).records == reference
    wrapped = vec_env.VecNormalize(venv, norm_obs=False, norm_reward=False, training=False)
    assert swiptopt.evaluate(ByObservation(), wrapped, 5, seed=7).records == reference


def test_vector_envs_refuse_what_they_cannot_do():
    from gymnasium.wrappers import TimeLimit

    envs = gym.vector.SyncVectorEnv([lambda: TimeLimit(_tiny(), 5)] * 2)
    with pytest.raises(swiptopt.ConfigError, match="episode_steps"):
        swiptopt.evaluate(ByObservation(), envs, 2)
    with pytest.raises(swiptopt.ConfigError, match="single env"):
        swiptopt.evaluate(Dive(), gym.vector.SyncVectorEnv([_tiny] * 2), 2)


def test_evaluate_needs_a_swiptopt_env():
    with pytest.raises(swiptopt.ConfigError, match="swiptopt"):
        swiptopt.evaluate(Left(), gym.make("FrozenLake-v1"), 1)  # until its TimeLimit ends it
