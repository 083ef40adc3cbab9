"""A recorded trial replayed open-loop: the player ignores its neighbours.

`recorded_step` is the compiled step, called by `RecordedPlayer.step` and, through the
recordings' kind (`KIND`, `mirror_avatar.players.kinds`), by the compiled batch loop.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.files.trials import PLAYING_RANGE, Trial
from mirror_avatar.players.base import Observation, Player, PlayerPlan
from mirror_avatar.players.kinds import PlayerKind, register_kind

Array = NDArray[np.float64]
Ints = NDArray[np.int64]


@njit(cache=True, nogil=True)
def recorded_step(track: Array, k: int) -> tuple[float, float]:
    """Return the recording at sample k + 1; past its end, the last position at rest.

    Parameters
    ----------
    track
        Positions (units) and velocities (units/s) on the control grid, shape (2, L).
    k
        The current sample.
    """
    if k + 1 < track.shape[1]:
        return track[0, k + 1], track[1, k + 1]
    return track[0, track.shape[1] - 1], 0.0


class RecordedPlayer(Player):
    """A recorded trial replayed as it was recorded (see the module docstring).

    Positions and velocities (METHODS section 2) are interpolated onto the control grid; after
    the end of the recording the player stays still at its last position.

    Parameters
    ----------
    trial
        The recording.
    period
        Control period (s).

    Attributes
    ----------
    track : ndarray, shape (2, L)
        Positions (units) and velocities (units/s) on the control grid.
    recording : tuple of float
        The recording's span from first to last sample and its mean sampling interval as
        recorded (s, `Trial.recorded_step`).
    outside : float
        Share of the control grid's positions that lay outside `PLAYING_RANGE` and were
        clipped to it.
    """

    def __init__(self, trial: Trial, period: float = CONTROL_PERIOD) -> None:
        offsets = trial.times - trial.times[0]
        n_steps = int(math.floor(offsets[-1] / period)) + 1
        grid = np.arange(n_steps) * period
        recorded = np.interp(grid, offsets, trial.positions)
        positions = np.clip(recorded, *PLAYING_RANGE)
        self.outside = float(np.mean(positions != recorded))
        self.track = np.vstack([positions, np.interp(grid, offsets, trial.velocity())])
        self.period = period
        self.recording = (float(offsets[-1]), trial.recorded_step)
        self.label = trial.label or "recorded trial"
        self.source = str(trial.metadata.get("source", ""))

    @classmethod
    def on_grid(
        cls, positions: Array, velocities: Array, period: float, label: str = "recorded player"
    ) -> RecordedPlayer:
        """Replay positions (units) and velocities (units/s) already on the control grid, (L,)."""
        player = cls.__new__(cls)
        player.track = np.vstack([positions, velocities]).astype(np.float64)
        player.period = period
        player.recording = ((player.track.shape[1] - 1) * period, period)
        player.outside = 0.0
        player.label = label
        player.source = ""
        return player

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Rewind to the start of the recording (``seed`` changes nothing)."""
        self._k = 0
        return float(self.track[0, 0]), float(self.track[1, 0])

    def step(self, observation: Observation) -> tuple[float, float]:
        """Return the recording one period later, whatever the neighbours do."""
        x, v = recorded_step(self.track, self._k)
        self._k += 1
        return x, v

    def describe(self) -> dict[str, Any]:
        """Class, label and the recording's source."""
        return super().describe() | {"source": self.source}

    def plan(self, seed: int, n_steps: int) -> PlayerPlan:
        """Return the recording on the control grid (``seed`` changes nothing)."""
        start = (float(self.track[0, 0]), float(self.track[1, 0]))
        return PlayerPlan(KIND.name, start, track=self.track)


class Recordings(NamedTuple):
    """A session's K recordings as the compiled batch loop reads them."""

    tracks: Array
    """Each one's positions and velocities on the control grid, padded, shape (K, 2, L)."""
    lengths: Ints
    """Each one's length, shape (K,)."""


def pack_recordings(plans: Sequence[PlayerPlan], players: Ints) -> Recordings:
    """Pack a session's recordings (their plans; their rows in the session are not needed)."""
    lengths = np.array([0 if p.track is None else p.track.shape[1] for p in plans], np.int64)
    tracks = np.full((len(plans), 2, max(int(lengths.max()), 1)), np.nan)
    for slot, plan in enumerate(plans):
        if plan.track is not None:
            tracks[slot, :, : lengths[slot]] = plan.track
    return Recordings(tracks, lengths)


@njit(cache=True, nogil=True, inline="always")
def replay_recording(
    tracks: Array,
    lengths: Ints,
    slot: int,
    k: int,
    x: float,
    v: float,
    positions: Array,
    velocities: Array,
    previous: Array,
    reference: float,
) -> tuple[float, float, float]:
    """`recorded_step` of recording ``slot``, with no control (NaN).

    The first arguments are the fields of `Recordings`, the others a kind's step's
    (`mirror_avatar.players.kinds`).
    """
    x, v = recorded_step(tracks[slot, :, : lengths[slot]], k)
    return x, v, np.nan


KIND = register_kind(PlayerKind("recorded", Recordings, pack_recordings, replay_recording))
"""The recordings' kind in the compiled batch loop."""
