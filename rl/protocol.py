"""The paper's protocol: train on one layout under the stochastic channel, then evaluate
the greedy policy with :func:`swiptopt.evaluate` on separate seeds."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rl.agents import make_agent
from rl.config import TabularConfig
from rl.training import TrainingLog, train
from swiptopt.env import AuvSwiptEnv
from swiptopt.evaluation import EVALUATION_SEED_OFFSET, EvaluationResult, evaluate
from swiptopt.scenario import Scenario

#: Evaluation seeds start here, far from the training seeds of any sweep.


@dataclass(frozen=True, eq=False)
class ProtocolResult:
    """The trained agent, its training log and its greedy evaluation."""

    agent: Any
    log: TrainingLog
    evaluation: EvaluationResult


def paper_protocol(
    scenario: Scenario,
    algorithm: str = "q_learning",
    *,
    train_episodes: int = 2000,
    eval_episodes: int = 20,
    seed: int = 0,
    backend: str = "compiled",
    config: TabularConfig | None = None,
) -> ProtocolResult:
    """Train ``algorithm`` for ``train_episodes`` on ``scenario`` (its fixed layout), then
    evaluate the greedy policy for ``eval_episodes`` on seeds starting at
    ``seed + EVALUATION_SEED_OFFSET``, which training never uses."""
    env = AuvSwiptEnv(scenario)
    agent = make_agent(algorithm, env.observation_space.n, config=config, seed=seed)
    log = train(agent, env, train_episodes, seed=seed, backend=backend)
    evaluation = evaluate(agent, env, eval_episodes, seed=seed + EVALUATION_SEED_OFFSET)
    return ProtocolResult(agent, log, evaluation)
