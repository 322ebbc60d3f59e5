"""Reinforcement-learning agents and their training loops (built on ``swiptopt``'s model).

``RandomAgent``, ``QLearningAgent`` and ``SarsaAgent`` (the paper's), ``UniformRandomAgent``
(random actions in a continuous action space), ``train`` with a Python and a compiled
backend, and ``paper_protocol`` (train, then evaluate greedily). Deep RL (Stable-Baselines3's
PPO, DQN and SAC, the ``deeprl`` extra; the grid world or the continuous one): ``train_deep``,
``load_deep``, ``train_or_load_deep`` in :mod:`rl.deep`, which loads torch only when used.
"""

from rl.agents import AGENTS, QLearningAgent, RandomAgent, SarsaAgent, UniformRandomAgent, make_agent
from rl.config import TabularConfig
from rl.deep import (
    DEEP_ALGORITHMS,
    DeepConfig,
    DeepResult,
    deep_config_hash,
    load_deep,
    model_path,
    save_deep,
    train_deep,
    train_or_load_deep,
)
from rl.protocol import ProtocolResult, paper_protocol
from rl.training import TrainingLog, train

__all__ = [
    "AGENTS",
    "DEEP_ALGORITHMS",
    "DeepConfig",
    "DeepResult",
    "ProtocolResult",
    "QLearningAgent",
    "RandomAgent",
    "SarsaAgent",
    "TabularConfig",
    "TrainingLog",
    "UniformRandomAgent",
    "deep_config_hash",
    "load_deep",
    "make_agent",
    "model_path",
    "paper_protocol",
    "save_deep",
    "train",
    "train_deep",
    "train_or_load_deep",
]
