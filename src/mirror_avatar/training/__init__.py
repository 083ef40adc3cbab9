"""Training set-ups that play sessions on the engine and teach cyber players from them.

`agents` is the one registry of the agents a cyber player can be (tabular or deep: player,
learner, scores, file); `imitation` is the paper's set-up (virtual trainers VT1..VT6, training a
cyber player to imitate one of them in a dyad or a group); `avatar` is a person's avatar file
(their generator and both trained players). The package sits above `mirror_avatar.engine`,
whose batch engine plays the training sessions, and above `mirror_avatar.learning` and
`mirror_avatar.deep`, whose learners it drives.
"""
