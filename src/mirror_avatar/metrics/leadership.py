"""Leadership over time: windowed lagged cross-correlation with peak picking (Boker et al. 2002).

Boker, Xu, Rotondo & King (2002, Psychological Methods 7:338) slide a window of ``window``
seconds along two series and, in each window, correlate the segment of one with the segment of
the other shifted by every lag up to ``max_lag``; peak picking then takes, in each window, the
local maximum of the correlation nearest lag zero. Feniger-Schaal et al. (2021, J Nonverbal
Behav 45:49) use the method to tell who leads in the mirror game. The lag of the picked peak says
who leads and by how much: positive when player 0 leads (player 1 repeats player 0's motion
``lag`` seconds later), the project's sign everywhere.

**Choice**: the method runs on velocities by default (positions' slow drifts inflate
correlations at every lag); the window (4 s), step (0.5 s), largest lag (1 s) and the smallest
correlation of a peak (0.5) are options, as Boker et al. ask of a user.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import ArrayLike, NDArray

from mirror_avatar.common.errors import InputError

Array = NDArray[np.float64]

WINDOW = 4.0
"""Window length (s, **choice**)."""

STEP = 0.5
"""Step between windows (s, **choice**)."""

MAX_LAG = 1.0
"""Largest lag searched (s, **choice**)."""

MIN_PEAK = 0.5
"""Smallest correlation of a picked peak (**choice**); a window without one has no leader."""

LEADER_SHARE = 0.6
"""Share of all windows that a player must lead to lead the session (**choice**)."""


@dataclass(frozen=True)
class Leadership:
    """Windowed lagged cross-correlation of a pair and its picked peaks.

    Attributes
    ----------
    times
        Centre of each window (s from the first sample), shape (w,).
    lags
        The lags searched (s), shape (m,).
    correlations
        Pearson correlation of player 0's window with player 1's shifted by each lag, shape
        (w, m).
    peak_lags, peak_values
        Lag (s, positive = player 0 leads) and correlation of each window's picked peak, shape
        (w,); NaN where a window has no peak.
    """

    times: Array
    lags: Array
    correlations: Array
    peak_lags: Array
    peak_values: Array

    def leaders(self, rate: float) -> NDArray[np.int64]:
        """Leader of each window: 0, 1, or -1 (no peak, or a lag below half a sample)."""
        half = 0.5 / rate
        out = np.full(self.peak_lags.shape, -1, dtype=np.int64)
        out[self.peak_lags > half] = 0
        out[self.peak_lags < -half] = 1
        return out

    def leader(self, rate: float, share: float = LEADER_SHARE) -> tuple[int | None, float]:
        """Name the session's leader, and the share of all windows it leads.

        The player leading most windows leads the session if it leads at least ``share`` of
        all windows (windows without a peak lead nobody); otherwise None (no leader).
        """
        each = self.leaders(rate)
        if each.size == 0:
            return None, float("nan")
        counts = [int(np.sum(each == k)) for k in (0, 1)]
        best = int(np.argmax(counts))
        fraction = counts[best] / each.size
        return (best if fraction >= share else None), fraction

    def leader_lag(self, player: int, rate: float) -> float:
        """Median lag (s, > 0) of the windows that ``player`` leads; NaN if none."""
        each = self.leaders(rate)
        lags = np.abs(self.peak_lags[each == player])
        return float(np.median(lags)) if lags.size else float("nan")


def windowed_cross_correlation(
    s0: ArrayLike, s1: ArrayLike, rate: float, window: float = WINDOW, step: float = STEP,
    max_lag: float = MAX_LAG,
) -> tuple[Array, Array, Array]:  # fmt: skip
    """Pearson correlation of windows of ``s0`` with lagged windows of ``s1``.

    Parameters
    ----------
    s0
        The first series, shape (n,), uniform at ``rate`` (Hz).
    s1
        The second, shape (n,), or several, shape (..., n), each along the last axis: player 0's
        standardised windows are computed once for all of them.
    rate
        Sampling rate (Hz).
    window, step, max_lag
        Window length, step between windows and largest lag (s).

    Returns
    -------
    times, lags, correlations
        Window centres (s), shape (w,); lags (s), shape (m,); correlations, shape (..., w, m):
        ``corr(s0[i : i + W], s1[i + L : i + L + W])`` for window start ``i`` and lag ``L``
        samples, positive ``L`` when player 0 leads. Windows start from ``max_lag`` so that
        every lag fits; a constant segment correlates as 0.
    """
    a, b = np.asarray(s0, dtype=float), np.asarray(s1, dtype=float)
    w, h, m = round(window * rate), max(1, round(step * rate)), round(max_lag * rate)
    if m < 1 or w < 3:
        option, value, fewest = (
            ("--lead-max-lag", max_lag, 1) if m < 1 else ("--lead-window", window, 3)
        )
        raise InputError(
            option,
            f"{value:g} s is under {fewest} sample(s) at {rate:g} Hz; give at least "
            f"{fewest / rate:g} s",
        )
    if a.ndim != 1 or b.shape[-1:] != a.shape or a.size < w + 2 * m:
        raise InputError(
            "leadership",
            f"need two equal series longer than --lead-window + 2 --lead-max-lag, got {b.shape}",
        )
    starts = np.arange(m, a.size - w - m + 1, h)
    sd_b = _window_sd(b, w)[..., starts[:, None] + np.arange(-m, m + 1)[None, :]]
    own = _standardised(sliding_window_view(a, w)[starts])
    lagged = sliding_window_view(b, w, axis=-1)
    dot = np.stack(
        [np.einsum("...lt,t->...l", lagged[..., i - m : i + m + 1, :], own[k])
         for k, i in enumerate(starts)],
        axis=-2,
    ) / w  # fmt: skip
    floor = 1e-12 * (1 + np.abs(b).max(axis=-1))[..., None, None]
    corr = np.divide(dot, sd_b, out=np.zeros_like(dot), where=sd_b > floor)
    times = np.asarray((starts + w / 2) / rate, dtype=np.float64)
    return times, np.arange(-m, m + 1) / rate, np.asarray(corr, dtype=np.float64)


def _standardised(windows: Array) -> Array:
    centred = windows - windows.mean(axis=-1, keepdims=True)
    sd = centred.std(axis=-1, keepdims=True)
    return np.asarray(np.divide(centred, sd, out=np.zeros_like(centred), where=sd > 0))


def _window_sd(x: Array, w: int) -> Array:
    """SD of every window of ``w`` samples along the last axis, shape (..., n - w + 1)."""
    centred = x - x.mean(axis=-1, keepdims=True)
    zero = np.zeros((*x.shape[:-1], 1))
    c1 = np.concatenate((zero, np.cumsum(centred, axis=-1)), axis=-1)
    c2 = np.concatenate((zero, np.cumsum(centred**2, axis=-1)), axis=-1)
    mean = (c1[..., w:] - c1[..., :-w]) / w
    return np.sqrt(np.maximum((c2[..., w:] - c2[..., :-w]) / w - mean**2, 0.0))


def pick_peaks(lags: Array, correlations: Array, min_peak: float = MIN_PEAK) -> tuple[Array, Array]:
    """Each window's local maximum of correlation nearest lag zero (Boker et al. 2002).

    Parameters
    ----------
    lags
        Lags (s), shape (m,), increasing.
    correlations
        Shape (w, m).
    min_peak
        Smallest correlation of a peak. A peak is larger than the value before it and at least
        the value after it; the ends of the lag range are never peaks. Of two peaks equally
        near lag zero, the negative lag's is taken.

    Returns
    -------
    peak_lags, peak_values
        Shape (w,); NaN for a window without a peak.
    """
    r = np.asarray(correlations, dtype=float)
    inner = r[:, 1:-1]
    is_peak = (inner > r[:, :-2]) & (inner >= r[:, 2:]) & (inner >= min_peak)
    distance = np.where(is_peak, np.abs(lags[1:-1])[None, :], np.inf)
    best = np.argmin(distance, axis=1)
    found = np.isfinite(distance[np.arange(r.shape[0]), best])
    peak_lags = np.where(found, lags[1:-1][best], np.nan)
    peak_values = np.where(found, inner[np.arange(r.shape[0]), best], np.nan)
    return peak_lags, peak_values


def compute_leadership(
    s0: ArrayLike, s1: ArrayLike, rate: float, window: float = WINDOW, step: float = STEP,
    max_lag: float = MAX_LAG, min_peak: float = MIN_PEAK,
) -> Leadership:  # fmt: skip
    """Windowed lagged cross-correlation of two series and its picked peaks (module docstring).

    Parameters
    ----------
    s0, s1
        Velocities (or positions) of players 0 and 1, shape (n,), uniform at ``rate`` (Hz).
    rate, window, step, max_lag
        As in `windowed_cross_correlation`.
    min_peak
        As in `pick_peaks`.
    """
    times, lags, corr = windowed_cross_correlation(s0, s1, rate, window, step, max_lag)
    peak_lags, peak_values = pick_peaks(lags, corr, min_peak)
    return Leadership(times, lags, corr, peak_lags, peak_values)
