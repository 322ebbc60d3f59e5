"""Reinforcement-learning agents and their training loops (built on ``swiptopt``'s model).

``RandomAgent``, ``QLearningAgent`` and ``SarsaAgent`` (the paper's), ``train`` with a
Python and a compiled backend, and ``paper_protocol`` (train, then evaluate greedily).
"""

from rl.agents import AGENTS, QLearningAgent, RandomAgent, SarsaAgent, make_agent
from rl.config import TabularConfig
from rl.protocol import ProtocolResult, paper_protocol
from rl.training import TrainingLog, train

__all__ = [
    "AGENTS",
    "ProtocolResult",
    "QLearningAgent",
    "RandomAgent",
    "SarsaAgent",
    "TabularConfig",
    "TrainingLog",
    "make_agent",
    "paper_protocol",
    "train",
]
