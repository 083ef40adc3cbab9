"""Reinforcement-learning interfaces: Gymnasium and PettingZoo environments (the ``rl`` extra).

`env` (the cyber player's view of a recorded session), `multi_agent` (several learning agents
playing one group live on the engine's step loop).
"""
