"""Entering and leaving synchrony: windows of phase locking above a threshold, counted and timed.

The relative phase of the pair (METHODS section 6) is locked over a centred window of
``window`` seconds when its mean resultant length over the window (the windowed CV) is at least
``threshold``. An episode of synchrony is a run of locked samples; the pair enters synchrony at
each episode's start (not at the first sample) and leaves it at each episode's end (not at the
last). Dwell times are the episodes' lengths, and the gaps between them. **Choice**: window 2 s,
threshold 0.9, both options.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import uniform_filter1d

from mirror_avatar.common.errors import InputError
from mirror_avatar.metrics.runs import find_runs

Array = NDArray[np.float64]

WINDOW = 2.0
"""Window of the windowed phase locking (s, **choice**)."""

THRESHOLD = 0.9
"""Windowed phase locking at and above which the pair is in synchrony (**choice**)."""


@dataclass(frozen=True)
class SynchronyEpisodes:
    """Episodes of synchrony of a pair.

    Attributes
    ----------
    locking
        Windowed phase locking, shape (n,), in [0, 1].
    mask
        True where the pair is in synchrony, shape (n,).
    episodes
        Start and end (s from the first sample) of each episode, shape (k, 2).
    entries, exits
        Times the pair entered and left synchrony.
    """

    locking: Array
    mask: NDArray[np.bool_]
    episodes: Array
    entries: int
    exits: int

    @property
    def share(self) -> float:
        """Share of the samples in synchrony, in [0, 1]."""
        return float(self.mask.mean())

    @property
    def mean_dwell(self) -> float:
        """Mean length of the episodes (s); NaN without one."""
        lengths = np.diff(self.episodes, axis=1).ravel()
        return float(lengths.mean()) if lengths.size else float("nan")

    @property
    def mean_gap(self) -> float:
        """Mean time between one episode's end and the next's start (s); NaN without a gap."""
        gaps = self.episodes[1:, 0] - self.episodes[:-1, 1]
        return float(gaps.mean()) if gaps.size else float("nan")


def windowed_phase_locking(relative_phase: ArrayLike, rate: float, window: float = WINDOW) -> Array:
    """Mean resultant length of the relative phase over a centred window, shape (n,).

    Parameters
    ----------
    relative_phase
        Relative phase (rad), shape (n,), uniform at ``rate`` (Hz).
    rate
        Sampling rate (Hz).
    window
        Window length (s); edges repeat the nearest sample.
    """
    d = np.asarray(relative_phase, dtype=float)
    if d.ndim != 1 or d.size == 0 or not np.all(np.isfinite(d)) or window <= 0:
        raise InputError("relative phase", "need a finite 1-D series and a positive window")
    size = max(1, round(window * rate))
    c = uniform_filter1d(np.cos(d), size, mode="nearest")
    s = uniform_filter1d(np.sin(d), size, mode="nearest")
    return np.asarray(np.hypot(c, s), dtype=np.float64)


def find_synchrony_episodes(
    relative_phase: ArrayLike, rate: float, window: float = WINDOW, threshold: float = THRESHOLD
) -> SynchronyEpisodes:
    """Episodes of synchrony, entries and exits (module docstring).

    Parameters
    ----------
    relative_phase
        Relative phase of the pair (rad), shape (n,), uniform at ``rate`` (Hz).
    rate
        Sampling rate (Hz).
    window, threshold
        Window (s) of the phase locking and its threshold in [0, 1].
    """
    locking = windowed_phase_locking(relative_phase, rate, window)
    mask = locking >= threshold
    runs = find_runs(mask)
    return SynchronyEpisodes(
        locking=locking,
        mask=mask,
        episodes=runs.astype(np.float64) / rate,
        entries=int(np.sum(runs[:, 0] > 0)),
        exits=int(np.sum(runs[:, 1] < mask.size)),
    )
