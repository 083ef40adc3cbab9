"""The Python step loop: N players on a graph advanced together, sample by sample.

Every player observes its neighbours' states at t_k (`mirror_avatar.players.base.Observation`,
gathered by `gather_neighbours`) and all advance simultaneously to t_k + T (METHODS sections 1,
5 and 8: no one sees the future). An `ExternalPlayer` (a person) is not stepped: its state at
each sample is read when the sample is taken. Each completed sample is recorded and passed to
the engine's sinks (for instance a `mirror_avatar.sessions.writer.SessionWriter`, so a live
recording is on disk as it happens). `play` runs a whole session; the Gymnasium environment and the
live server call `Engine.step` themselves.

A stepped player whose position or velocity stops being finite (or exceeds
`mirror_avatar.players.base.DIVERGED_BEYOND`) ends the session: `Engine.step` raises
`mirror_avatar.players.base.PlayerDiverged` naming the player and the sample, which is not taken
(the samples before it are, and stay finite).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import entropy_of, spawn_seeds
from mirror_avatar.players.base import (
    DIVERGED_BEYOND,
    ExternalPlayer,
    Observation,
    Player,
    PlayerDiverged,
    gather_neighbours,
)
from mirror_avatar.sessions.graphs import GraphSource, draw_graph
from mirror_avatar.sessions.session import CHANNELS, Session, default_roles

Array = NDArray[np.float64]
Sink = Callable[[Array], None]
"""Receives each completed sample as a row: time, then each player's four channels."""


def row_positions(row: Array) -> Array:
    """Return the players' positions (units) of a row the engine passes its sinks, shape (N,).

    A row is ``[t, x_0, v_0, u_0, r_0, x_1, ...]``: the time (s), then each player's
    `mirror_avatar.sessions.session.CHANNELS` (position, velocity, control, reference) in player
    order.
    """
    return row[1 :: len(CHANNELS)]


def check_lineup(players: Sequence[Player]) -> float:
    """Check that there are players and that they share one control period; return it (s)."""
    if not players:
        raise InputError("players", "a session needs at least one player")
    period = float(players[0].period)
    for player in players:
        if not math.isclose(period, float(player.period)):
            raise InputError("players", f"control periods differ: {period} s and {player.period} s")
    return period


def spawn_session_seeds(seed: int, n_players: int) -> tuple[list[int], int]:
    """Return the players' seeds (the first N children of ``seed``) and the graph's (child N)."""
    seeds = [int(s) for s in spawn_seeds(seed, n_players + 1)]
    return seeds[:n_players], seeds[n_players]


def count_samples(duration: float, period: float) -> int:
    """Return the samples of a session of ``duration`` s: ``round(duration / period) + 1``."""
    if not duration > period:
        raise InputError("duration", f"must exceed one control period ({period} s)")
    return int(round(duration / period)) + 1


class Engine:
    """N players on a graph and what they have played so far.

    Parameters
    ----------
    players
        The players, all with the same control period.
    graph
        Adjacency matrix (N, N), ``graph[k, j] = 1`` when player k observes player j, or a
        function drawing one for each session (`mirror_avatar.sessions.graphs.GraphSource`);
        default the complete graph.
    roles
        The players' roles, recorded in the session (default `default_roles`).
    labels
        The players' names, recorded in the session (default each player's ``label``).
    sinks
        Callables receiving every completed sample (see `Sink`).
    """

    def __init__(
        self,
        players: Sequence[Player],
        graph: GraphSource = None,
        roles: Sequence[str] | None = None,
        labels: Sequence[str] | None = None,
        sinks: Sequence[Sink] = (),
    ) -> None:
        self.players = list(players)
        self.period = check_lineup(self.players)
        self._graph_source = graph
        self.graph = draw_graph(None if callable(graph) else graph, len(self.players), 0)
        self.roles = tuple(roles) if roles is not None else default_roles(len(self.players))
        self.labels = (
            tuple(labels)
            if labels is not None
            else tuple(p.label or f"player {i}" for i, p in enumerate(self.players))
        )
        self.sinks = list(sinks)
        self.k = 0

    def reset(self, seed: int | None, n_samples: int) -> None:
        """Start a session of at most ``n_samples`` samples; reset every player.

        The players are reset with seeds spawned from ``seed`` (`mirror_avatar.common.seeds`), so
        the same seed replays the same session; None draws fresh entropy, kept in ``seed``. A drawn
        graph is drawn from the session seed as well.
        """
        self.seed = entropy_of(seed)
        self.player_seeds, graph_seed = spawn_session_seeds(self.seed, len(self.players))
        self.graph = draw_graph(self._graph_source, len(self.players), graph_seed)
        self._neighbours = [np.flatnonzero(row).astype(np.int64) for row in self.graph]
        self.n_samples = n_samples
        self._data = np.full((4, len(self.players), n_samples), np.nan)
        for i, player in enumerate(self.players):
            self._data[:2, i, 0] = player.reset(seed=self.player_seeds[i])
        self.k = 0
        self.n_taken = 0
        self._stepped = np.flatnonzero([not isinstance(p, ExternalPlayer) for p in self.players])
        self._check_finite(0)

    def step(self) -> None:
        """Take sample k (reading the external players) and advance everyone to k + 1.

        Raises
        ------
        PlayerDiverged
            When a stepped player's state at k + 1 has diverged (sample k is taken, k + 1 not).
        """
        k, data = self.k, self._data
        if k + 1 >= self.n_samples:
            raise InputError("session", f"the session holds {self.n_samples} samples")
        self._read_external(k)
        for i, player in enumerate(self.players):
            if isinstance(player, ExternalPlayer):
                continue
            data[:2, i, k + 1] = player.step(self._observe(i, k))
            data[2, i, k] = player.last_control
            data[3, i, k] = player.last_reference
        self._emit(k)
        self.k += 1
        self._check_finite(self.k)

    def _check_finite(self, k: int) -> None:
        """Raise `PlayerDiverged` for the first stepped player whose state at k has diverged."""
        bounded = (np.abs(self._data[:2, self._stepped, k]) <= DIVERGED_BEYOND).all(axis=0)
        if not bounded.all():
            i = int(self._stepped[np.argmin(bounded)])
            x, v = (float(value) for value in self._data[:2, i, k])
            raise PlayerDiverged(i, self.labels[i], k, self.period, (x, v))

    def finish(self) -> Session:
        """Take the last sample (reading the external players) and return the session."""
        self._read_external(self.k)
        self._emit(self.k)
        return self.session()

    def state(self, i: int) -> tuple[float, float]:
        """Return player i's position (units) and velocity (units/s) at the current sample."""
        return float(self._data[0, i, self.k]), float(self._data[1, i, self.k])

    def session(self) -> Session:
        """Return the samples taken so far (those passed to the sinks) as a `Session`."""
        n = self.n_taken
        data = self._data[:, :, :n]
        return Session(
            np.arange(n, dtype=np.float64) * self.period,
            data[0].copy(),
            data[1].copy(),
            data[2].copy(),
            data[3].copy(),
            labels=self.labels,
            roles=self.roles,
            graph=self.graph,
            metadata={
                "seed": self.seed,
                "player_seeds": self.player_seeds,
                "players": [p.describe() for p in self.players],
            },
        )

    def observe(self, i: int) -> Observation:
        """Return what player i sees at the current sample."""
        return self._observe(i, self.k)

    def _observe(self, i: int, k: int) -> Observation:
        index = self._neighbours[i]
        xs, vs, previous = np.empty(index.size), np.empty(index.size), np.empty(index.size)
        gather_neighbours(self._data[0], self._data[1], k, index, xs, vs, previous)
        return Observation(k, xs, vs, previous)

    def _read_external(self, k: int) -> None:
        for i, player in enumerate(self.players):
            if isinstance(player, ExternalPlayer):
                self._data[:2, i, k] = player.current_state()

    def _emit(self, k: int) -> None:
        self.n_taken = k + 1
        if self.sinks:
            row = np.concatenate([[k * self.period], self._data[:, :, k].T.ravel()])
            for sink in self.sinks:
                sink(row)


def play(
    players: Sequence[Player],
    duration: float = 60.0,
    seed: int | None = None,
    roles: Sequence[str] | None = None,
    graph: GraphSource = None,
) -> Session:
    """Play one session of N players in the Python step loop.

    Parameters
    ----------
    players
        The players, all with the same control period.
    duration
        Session length (s); ``round(duration / period)`` periods are played.
    seed
        Session seed; the players are reset with seeds spawned from it, so the same seed replays
        the same session. None draws fresh entropy (recorded in the metadata).
    roles
        The players' roles, recorded in the session.
    graph
        Who observes whom (default: everyone observes everyone; see `Engine`).

    Returns
    -------
    Session
        ``round(duration / period) + 1`` samples.
    """
    engine = Engine(players, graph, roles)
    engine.reset(seed, count_samples(duration, engine.period))
    for _ in range(engine.n_samples - 1):
        engine.step()
    return engine.finish()
