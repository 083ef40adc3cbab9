"""The cyber player: a tabular Q-learning avatar (METHODS section 7) and how it is trained.

Modules, each one idea: `discretisation` (the state cells of the Q-table), `kernels` (compiled
reward, exploration, update and one learning session), `agent` (the `CyberPlayer` and its greedy
policy), `files` (saving and loading a trained player), `training` (the `QLearner` estimator, its
exploration schedule and learning curve) and `imitation` (the paper's set-up: virtual trainers
VT1..VT6 and training a cyber player to imitate one of them).
"""
