"""The cyber player: a tabular Q-learning avatar (METHODS section 7) and how it is trained.

Modules, each one idea: `acceleration_player` (what every learned avatar shares, the deep one of
`mirror_avatar.deep` included), `discretisation` (the state cells of the Q-table), `kernels`
(compiled reward, exploration, update and one learning session), `agent` (the `CyberPlayer`, its
greedy policy and its file), `training` (the learning loop both agents share, the `QLearner`
estimator, its exploration schedule and learning curve), `imitation` (the paper's set-up:
virtual trainers VT1..VT6 and training a tabular or deep cyber player to imitate one of them)
and `avatar` (a person's avatar file).
"""
