"""The cyber player: a tabular Q-learning avatar (METHODS section 7) and how it is trained.

Modules, each one idea: `acceleration_player` (what every learned avatar shares, the deep one of
`mirror_avatar.deep` included), `discretisation` (the state cells of the Q-table), `kernels`
(compiled reward, exploration, update and one learning session), `agent` (the `CyberPlayer`, its
greedy policy and its file), `training` (the learning loop both agents share, the `QLearner`
estimator, its exploration schedule and learning curve). The paper's set-up and avatar files,
which play sessions on the engine, are in `mirror_avatar.training`.
"""
