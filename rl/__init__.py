"""Reinforcement-learning agents and their training loops (built on ``swiptopt``'s model)."""
