"""Co-confidence (CC) motion: stretches in which two players move smoothly and together.

Noy, Dekel & Alon (2011, PNAS 108:20947) call co-confident the moments of joint improvisation
in which both players move without jitter and in close synchrony, as one unit; Brezis et al.
(2017) and Noy, Weiser & Friedman (2017) use it operationally as segments longer than 2 s of
smooth (jitter-free), synchronised joint motion. Here a sample is CC when, at once,

- both players are smooth: their velocity difference ``v0 - v1`` is not in a jitter episode
  (`mirror_avatar.metrics.jitter.jitter_episodes`: its jitter index, relative to the pair's RMS
  speed ``sqrt(mean((v0² + v1²) / 2))``, above ``jitter_threshold``, edges at half the
  episode's peak), so 2-3 Hz motion both players share, as a follower matching a leader's
  quick strokes, is not jitter, and one player's jitter alone is;
- they move together: the relative velocity difference over a centred window,
  ``dV(t) = mean|u0 - u1| / mean((|u0| + |u1|) / 2)``, is below ``dv_threshold``, with
  ``u`` the velocities without jitter (`mirror_avatar.metrics.jitter.smooth_part`: low-passed
  below the jitter band), so that jitter, judged by the first criterion, does not spill over
  the window into this one;
- they move: the pair's mean speed ``(|u0| + |u1|) / 2`` over that window is at least
  ``rest_fraction`` times the pair's RMS speed over the trial (joint rest is not CC motion);

and a CC segment is a run of CC samples at least ``min_duration`` long. Each segment reports
its dV (over the segment, of ``u``) and its dT, the mean gap (s) between each zero-velocity
event of player 0 in the segment and the nearest zero-velocity event of player 1 (events of
``u``). The thresholds are a **choice** (the papers
name the criteria, not numbers that carry over between set-ups); all are options.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import uniform_filter1d

from mirror_avatar.common.errors import InputError
from mirror_avatar.metrics.jitter import (
    FILTER_ORDER,
    JITTER_BAND,
    jitter_episodes,
    jitter_index,
    smooth_part,
)
from mirror_avatar.metrics.runs import find_runs, keep_long_runs

Array = NDArray[np.float64]

MIN_DURATION = 2.0
"""Shortest CC segment (s), as Noy et al. (2011) define it."""

JITTER_THRESHOLD = 0.1
"""Largest jitter index of a smooth sample (**choice**)."""

DV_THRESHOLD = 0.3
"""Largest windowed relative velocity difference of a joint sample (**choice**)."""

DV_WINDOW = 1.0
"""Length of the centred window of dV and of the pair's speed (s, **choice**)."""

REST_FRACTION = 0.05
"""Below this share of the pair's RMS speed the pair is at rest (**choice**)."""


@dataclass(frozen=True)
class CCSegment:
    """One co-confident segment.

    ``start`` and ``end`` (s from the first sample), ``dv`` (relative velocity difference over
    the segment) and ``dt`` (mean timing gap between zero-velocity events, s; NaN without
    events).
    """

    start: float
    end: float
    dv: float
    dt: float

    @property
    def length(self) -> float:
        """Duration (s)."""
        return self.end - self.start


@dataclass(frozen=True)
class CoConfidence:
    """The CC analysis of a pair: ``mask`` (n,) of CC samples and its ``segments``.

    Attributes
    ----------
    mask
        True where the sample is in a CC segment, shape (n,).
    segments
        The segments, in order of time.
    """

    mask: NDArray[np.bool_]
    segments: tuple[CCSegment, ...]

    @property
    def rate(self) -> float:
        """Share of the samples in CC segments, in [0, 1] (the CC rate)."""
        return float(self.mask.mean()) if self.mask.size else 0.0

    @property
    def mean_length(self) -> float:
        """Mean segment length (s); NaN without segments."""
        lengths = [segment.length for segment in self.segments]
        return float(np.mean(lengths)) if lengths else float("nan")


def relative_velocity_difference(v0: Array, v1: Array, rate: float, window: float) -> Array:
    """Windowed ``dV(t) = mean|v0 - v1| / mean((|v0| + |v1|) / 2)``, shape (..., n).

    Series along the last axis (``v0`` and ``v1`` broadcast together); means over a centred
    window of ``window`` seconds (edges: nearest value repeated); inf where
    neither player moves over the window.
    """
    size = max(1, round(window * rate))
    difference = uniform_filter1d(np.abs(v0 - v1), size, mode="nearest")
    speed = uniform_filter1d((np.abs(v0) + np.abs(v1)) / 2.0, size, mode="nearest")
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(speed > 0, difference / speed, np.inf)


def zero_velocity_times(velocity: Array, rate: float) -> Array:
    """Find the times (s from the first sample) where the velocity changes sign (interpolated)."""
    v = np.asarray(velocity, dtype=float)
    i = np.flatnonzero((v[:-1] > 0) & (v[1:] <= 0) | (v[:-1] < 0) & (v[1:] >= 0))
    fraction = v[i] / (v[i] - v[i + 1])
    return np.asarray((i + fraction) / rate, dtype=np.float64)


def timing_gap(events0: Array, events1: Array, start: float, end: float) -> float:
    """Mean gap (s) from each event of player 0 in [start, end] to the nearest of player 1.

    ``events1`` must be sorted (as `zero_velocity_times` gives them): each event's nearest is
    one of the two around it (`numpy.searchsorted`), so time and memory grow with the events'
    number, not with its square.
    """
    own = events0[(events0 >= start) & (events0 <= end)]
    if own.size == 0 or events1.size == 0:
        return float("nan")
    if events1.size == 1:
        return float(np.mean(np.abs(own - events1[0])))
    after = np.clip(np.searchsorted(events1, own), 1, events1.size - 1)
    gaps = np.minimum(np.abs(own - events1[after]), np.abs(own - events1[after - 1]))
    return float(np.mean(gaps))


def find_co_confidence(
    v0: ArrayLike,
    v1: ArrayLike,
    rate: float,
    min_duration: float = MIN_DURATION,
    jitter_threshold: float = JITTER_THRESHOLD,
    dv_threshold: float = DV_THRESHOLD,
    dv_window: float = DV_WINDOW,
    rest_fraction: float = REST_FRACTION,
    band: tuple[float, float] = JITTER_BAND,
    order: int = FILTER_ORDER,
) -> CoConfidence:
    """CC segments of two velocity series (module docstring).

    Parameters
    ----------
    v0, v1
        Velocities of the two players, shape (n,), units/s, uniform at ``rate`` (Hz).
    rate
        Sampling rate (Hz).
    min_duration
        Shortest segment (s).
    jitter_threshold, dv_threshold, dv_window, rest_fraction
        The criteria of a CC sample (module docstring), all **choice**.
    band, order
        Jitter band (Hz) and filter order, as in `mirror_avatar.metrics.jitter.jitter_index`.

    Returns
    -------
    CoConfidence
        The CC samples and segments; times in seconds from the first sample.
    """
    b = np.asarray(v1, dtype=float)
    if b.ndim != 1:
        raise InputError("velocities", f"need two series of equal length, got {b.shape}")
    mask, a, b = co_confidence_masks(
        v0, b, rate, min_duration, jitter_threshold, dv_threshold, dv_window, rest_fraction,
        band, order,
    )  # fmt: skip
    events0, events1 = zero_velocity_times(a, rate), zero_velocity_times(b, rate)
    segments = []
    for start, stop in find_runs(mask):
        dv = np.sum(np.abs(a[start:stop] - b[start:stop])) / np.sum(
            (np.abs(a[start:stop]) + np.abs(b[start:stop])) / 2.0
        )
        t0, t1 = start / rate, stop / rate
        segments.append(
            CCSegment(float(t0), float(t1), float(dv), timing_gap(events0, events1, t0, t1))
        )
    return CoConfidence(mask=mask, segments=tuple(segments))


def co_confidence_masks(
    v0: ArrayLike, v1: ArrayLike, rate: float, min_duration: float, jitter_threshold: float,
    dv_threshold: float, dv_window: float, rest_fraction: float, band: tuple[float, float],
    order: int,
) -> tuple[NDArray[np.bool_], Array, Array]:  # fmt: skip
    """Find the CC samples of player 0 with each of several player 1 series (module docstring).

    Player 0's smooth part is computed once and the series of player 1 are filtered together,
    so that circular-shift surrogates of a pair (player 1 rolled) cost one pass each.

    Parameters
    ----------
    v0
        Velocity of player 0, shape (n,), units/s, uniform at ``rate`` (Hz).
    v1
        Velocities of player 1, shape (n,) or (..., n): each series along the last axis.
    rate, min_duration, jitter_threshold, dv_threshold, dv_window, rest_fraction, band, order
        As in `find_co_confidence`.

    Returns
    -------
    mask, smooth0, smooth1
        The CC samples, shape of ``v1``; the smooth parts (units/s) of ``v0`` (shape (n,)) and
        ``v1`` (shape of ``v1``).
    """
    a, b = np.asarray(v0, dtype=float), np.asarray(v1, dtype=float)
    if a.ndim != 1 or b.shape[-1:] != a.shape:
        raise InputError("velocities", f"need two series of equal length, got {a.shape}, {b.shape}")
    if min_duration <= 0 or dv_window <= 0 or jitter_threshold <= 0 or dv_threshold <= 0:
        raise InputError(
            "co-confidence",
            "--cc-min-duration, --dv-window, --jitter-threshold and --dv-threshold must be > 0",
        )
    pair_rms = np.sqrt(np.mean((a**2 + b**2) / 2.0, axis=-1))
    smooth = ~jitter_episodes(jitter_index(a - b, rate, band, order, pair_rms), jitter_threshold)
    a, b = smooth_part(a, rate, band, order), smooth_part(b, rate, band, order)
    together = relative_velocity_difference(a, b, rate, dv_window) < dv_threshold
    size = max(1, round(dv_window * rate))
    speed = uniform_filter1d((np.abs(a) + np.abs(b)) / 2.0, size, mode="nearest")
    moving = speed >= rest_fraction * pair_rms[..., None]
    mask = keep_long_runs(smooth & together & moving, max(1, round(min_duration * rate)))
    return mask, a, b
