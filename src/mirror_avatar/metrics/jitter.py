"""Jitter: the 2-3 Hz corrective oscillation of a follower's velocity (Noy, Dekel & Alon 2011).

A follower tracking a leader shows 2-3 Hz oscillations around the leader's smooth trajectory;
players in co-confident motion show none. The index here is the share of a player's velocity in
that band: the velocity is band-passed (zero-phase Butterworth), its instantaneous amplitude is
the modulus of the analytic signal, and both are divided by the RMS of the player's velocity over
the trial (**choice**: one scale per player and trial, so the index of a player is comparable
across the trial).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.trials import zero_phase_filter
from mirror_avatar.metrics.runs import find_runs

Array = NDArray[np.float64]

JITTER_BAND = (2.0, 3.0)
"""The band of jitter (Hz), as Noy, Dekel & Alon (2011) report it."""

FILTER_ORDER = 4
"""Order of the Butterworth band-pass (**choice**; applied forward and backward)."""


def shortest_series(order: int = FILTER_ORDER) -> int:
    """Fewest samples the forward-backward filters of this module accept at ``order``."""
    return 3 * (2 * order + 1) + 1


def _check_velocity(velocity: ArrayLike, rate: float, band: tuple[float, float]) -> Array:
    v = np.asarray(velocity, dtype=float)
    if v.ndim < 1 or v.shape[-1] < 2 or not np.all(np.isfinite(v)):
        raise InputError("velocity", f"need finite series of length >= 2, got {v.shape}")
    low, high = band
    if not (np.isfinite(rate) and 0 < low < high < rate / 2):
        raise InputError(
            "jitter band", f"need 0 < low < high < rate/2, got {band} Hz at {rate:g} Hz"
        )
    return v


@lru_cache(maxsize=32)
def _design(order: int, band: tuple[float, float], rate: float) -> tuple[Array, Array]:
    return _with_initial(signal.butter(order, band, btype="bandpass", fs=rate, output="sos"))


@lru_cache(maxsize=32)
def _low_pass_design(order: int, cutoff: float, rate: float) -> tuple[Array, Array]:
    return _with_initial(signal.butter(order, cutoff, fs=rate, output="sos"))


def _with_initial(sos: Array) -> tuple[Array, Array]:
    """Return second-order sections and their initial state for a unit step (`sosfilt_zi`)."""
    sos = np.asarray(sos, dtype=np.float64)
    return sos, np.asarray(signal.sosfilt_zi(sos), dtype=np.float64)


def _zero_phase(design: tuple[Array, Array], v: Array) -> Array:
    """Filter each series along the last axis forward and backward, as `signal.sosfiltfilt`.

    Its odd extension of 3 (2 n_sections + 1) samples at each end, less the sections' zero
    coefficients, as scipy counts them; the initial state is the design's, solved once
    (`mirror_avatar.files.trials.zero_phase_filter`), where `signal.sosfiltfilt` solves it anew
    on every call.

    Raises
    ------
    InputError
        Series no longer than the extension.
    """
    sos, initial = design
    zeros = min(int(np.sum(sos[:, 2] == 0)), int(np.sum(sos[:, 5] == 0)))
    padlen = 3 * (2 * len(sos) + 1 - zeros)
    n = v.shape[-1]
    if n <= padlen:
        raise InputError("velocity", f"{n} samples are too few for the filter: need over {padlen}")
    columns = zero_phase_filter(sos, initial, np.moveaxis(v, -1, 0).reshape(n, -1), padlen)
    return np.ascontiguousarray(columns.T).reshape(v.shape)


def smooth_part(
    velocity: ArrayLike,
    rate: float,
    band: tuple[float, float] = JITTER_BAND,
    order: int = FILTER_ORDER,
) -> Array:
    """Remove the jitter: zero-phase Butterworth low-pass at the band's low edge (units/s).

    Parameters and shapes as in `band_pass`: each series along the last axis.
    """
    v = _check_velocity(velocity, rate, band)
    return _zero_phase(_low_pass_design(order, band[0], rate), v)


def band_pass(
    velocity: ArrayLike,
    rate: float,
    band: tuple[float, float] = JITTER_BAND,
    order: int = FILTER_ORDER,
) -> Array:
    """Zero-phase band-pass of velocity series (units/s), shape (..., n).

    Parameters
    ----------
    velocity
        Velocity, shape (n,) or (..., n): each series along the last axis, units/s, sampled
        uniformly at ``rate`` (Hz).
    rate
        Sampling rate (Hz).
    band
        Pass band (Hz), low and high edge.
    order
        Butterworth order of each pass (the forward-backward filter has twice the order).
    """
    v = _check_velocity(velocity, rate, band)
    return _zero_phase(_design(order, band, rate), v)


def jitter_index(
    velocity: ArrayLike,
    rate: float,
    band: tuple[float, float] = JITTER_BAND,
    order: int = FILTER_ORDER,
    scale: float | Array | None = None,
) -> Array:
    """Time-resolved jitter of one player (or of each series along the last axis), shape (..., n).

    ``j(t) = |H(b)(t)| / (sqrt(2) RMS(v))`` with ``b`` the band-passed velocity (`band_pass`),
    ``H`` the analytic signal and RMS over the whole series; the sqrt(2) makes the RMS of
    ``j`` over time the per-trial value `jitter_value`. A pure tone in the band whose velocity
    amplitude is ``a`` gives ``j = a / (sqrt(2) RMS(v))``. A player without motion has index 0.

    Parameters
    ----------
    velocity, rate, band, order
        As in `band_pass`.
    scale
        The RMS velocity (units/s) the index is relative to, one per series (shape (...,));
        default each series' own.
    """
    return _index(band_pass(velocity, rate, band, order), velocity, scale)


def _index(b: Array, velocity: ArrayLike, scale: float | Array | None) -> Array:
    """`jitter_index` of the band-passed velocity ``b`` (units/s), shape (..., n)."""
    v = np.asarray(velocity, dtype=float)
    rms = (
        np.sqrt(np.mean(v**2, axis=-1, keepdims=True))
        if scale is None
        else np.asarray(scale, dtype=float)[..., None]
    )
    amplitude = np.abs(signal.hilbert(b))
    scaled = np.sqrt(2.0) * rms
    out = np.zeros_like(amplitude)
    return np.divide(amplitude, scaled, out=out, where=np.broadcast_to(rms > 0, out.shape))


def jitter_value(
    velocity: ArrayLike,
    rate: float,
    band: tuple[float, float] = JITTER_BAND,
    order: int = FILTER_ORDER,
) -> float:
    """Per-trial jitter of one player: ``RMS(b) / RMS(v)`` in [0, 1] (0 without motion).

    The share of the velocity's RMS that lies in the jitter band (``b`` = `band_pass`); its
    square is the share of the velocity's power in the band.
    """
    return _share(band_pass(velocity, rate, band, order), velocity)


def _share(b: Array, velocity: ArrayLike) -> float:
    """`jitter_value` of the band-passed velocity ``b`` (units/s), shape (n,)."""
    power = float(np.mean(np.asarray(velocity, dtype=float) ** 2))
    return float(np.sqrt(np.mean(b**2) / power)) if power > 0 else 0.0


def player_jitter(
    velocity: ArrayLike,
    rate: float,
    band: tuple[float, float] = JITTER_BAND,
    order: int = FILTER_ORDER,
) -> tuple[Array, float]:
    """One player's `jitter_index` (shape (n,)) and `jitter_value`, from one band-pass.

    Parameters as in `band_pass`, ``velocity`` of shape (n,).
    """
    b = band_pass(velocity, rate, band, order)
    return _index(b, velocity, None), _share(b, velocity)


def jitter_episodes(index: ArrayLike, threshold: float) -> NDArray[np.bool_]:
    """Mark the samples in jitter episodes of a time-resolved jitter index, shape (..., n).

    An episode is found where the index exceeds ``threshold`` and spans the samples around
    its peak where the index is at least half that peak (**choice**: a zero-phase band-pass
    turns a tone switched on and off into an envelope that crosses half its plateau at the
    switching times, whatever the tone's amplitude, so the edges do not move with the
    threshold).

    Parameters
    ----------
    index
        Jitter index (`jitter_index`), shape (n,) or (..., n): each series along the last axis.
    threshold
        Smallest index that makes an episode (dimensionless).
    """
    j = np.asarray(index, dtype=float)
    if j.ndim > 1:
        return np.array([jitter_episodes(row, threshold) for row in j]).reshape(j.shape)
    out = np.zeros(j.shape, dtype=bool)
    for start, stop in find_runs(j > threshold):
        peak = start + int(np.argmax(j[start:stop]))
        below = np.flatnonzero(~(j >= j[peak] / 2.0))
        after = int(np.searchsorted(below, peak))
        first = below[after - 1] + 1 if after > 0 else 0
        last = below[after] if after < below.size else j.size
        out[first:last] = True
    return out
