"""The engine: N players on a coupling graph, advanced together one control period at a time.

`loop` is the Python step loop (`Engine`, `play`): any `mirror_avatar.players.base.Player`,
used for single sessions, the Gymnasium environment and live play. `compiled` runs a whole
session of built-in players in one compiled loop calling the same per-kind step kernels, and
`batch` streams thousands of such sessions from local threads or a Dask cluster. Both loops
gather the neighbours with `mirror_avatar.players.base.gather_neighbours` and record samples the
same way, so a session is the same whichever loop played it.
"""
