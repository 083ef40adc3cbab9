"""Trials: one player's position time series, its validation, resampling and velocity.

Follows METHODS section 2: recordings at any rate (possibly with irregular timestamps) are
interpolated onto a uniform grid before anything else; velocity is the position low-passed by a
zero-phase Butterworth filter (order 4, 10 Hz cut-off) and differentiated by a 4th-order finite
difference (central inside, one-sided 5-point formulas at the two ends). Tracking drop-outs (runs of
identical samples) are kept: they are part of real data.

Units: time in seconds, position in normalised units (playing range [-0.5, 0.5]), velocity in
units/s.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cache
from typing import Any, Literal

import numpy as np
from numba import njit, types
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import PchipInterpolator
from scipy.signal import butter, sosfilt_zi

from mirror_avatar.common.errors import InputError

PLAYING_RANGE = (-0.5, 0.5)
"""Normalised positions a player can reach (units); the Bristol set-up maps 60 cm to 1 unit."""

DEFAULT_RATE = 100.0
"""Analysis sampling rate (Hz); the paper upsamples its 10 Hz recordings to 100 Hz."""

MIN_SAMPLES = 20
"""Fewest samples a trial may have: shorter ones cannot be filtered or differentiated."""

MIN_RATE, MAX_RATE = 1.0, 10_000.0
"""Plausible mean sampling rates (Hz); anything outside is a unit error, not a recording."""

MAX_ABS_POSITION = 5.0
"""Largest plausible |position| (units); larger values mean the file is not normalised."""

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Trial:
    """One player's position time series.

    Parameters
    ----------
    times
        Sample times, shape (n,), seconds, strictly increasing.
    positions
        Positions, shape (n,), normalised units.
    label
        A name for the trial (for instance the file stem).
    group
        The player or style the trial belongs to (used to group trials in analyses).
    metadata
        Anything else worth keeping (source file, participant, mode, seeds...); JSON-serialisable.
    """

    times: Array
    positions: Array
    label: str = ""
    group: str = ""
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.times.size)

    @property
    def duration(self) -> float:
        """Time from the first to the last sample (s)."""
        return float(self.times[-1] - self.times[0])

    @property
    def rate(self) -> float:
        """Mean sampling rate (Hz)."""
        return (self.n_samples - 1) / self.duration

    @property
    def recorded_step(self) -> float:
        """Mean sampling interval of the recording (s): before resampling, if resampled."""
        return 1.0 / float(self.metadata.get("resampled_from", self.rate))

    @property
    def is_uniform(self) -> bool:
        """Whether the samples are equally spaced (to 1e-6 of the mean step)."""
        steps = np.diff(self.times)
        return bool(np.all(np.abs(steps - steps.mean()) <= 1e-6 * steps.mean()))

    def resampled(
        self, rate: float = DEFAULT_RATE, method: Literal["pchip", "linear"] = "pchip"
    ) -> Trial:
        """Return this trial interpolated onto a uniform grid at ``rate`` Hz (see `resample`)."""
        return resample(self, rate, method)

    def velocity(self, cutoff: float | None = 10.0) -> Array:
        """Velocity (units/s), shape (n,); the trial must be uniformly sampled (see `resample`)."""
        if not self.is_uniform:
            raise InputError(
                self.label or None, "velocity needs uniform sampling: use trial.resampled() first"
            )
        return compute_velocity(self.positions, self.rate, cutoff=cutoff)

    def held_runs(self) -> Array:
        """Tracking drop-outs: each run of identical consecutive positions, shape (m, 2).

        Each row is the run's first and last sample time (s from the trial's first sample).
        """
        offsets = self.times - self.times[0]
        held = np.diff(self.positions) == 0.0
        edges = np.flatnonzero(np.diff(np.concatenate([[False], held, [False]]).astype(np.int8)))
        starts, stops = edges[0::2], edges[1::2]
        return np.column_stack([offsets[starts], offsets[stops]])


def make_trial(
    times: ArrayLike,
    positions: ArrayLike,
    *,
    source: str | None = None,
    label: str = "",
    group: str = "",
    metadata: dict[str, Any] | None = None,
) -> Trial:
    """Validate samples and build a `Trial`.

    Parameters
    ----------
    times, positions
        Sample times (s) and positions (units), shape (n,) each.
    source
        Where the samples came from (a file path), named in error messages.
    label, group, metadata
        As in `Trial`.

    Raises
    ------
    InputError
        One line naming ``source`` and the problem: wrong shape, NaN or infinite values,
        non-increasing time, too few samples, an absurd sampling rate or positions far outside
        the normalised range. Flat runs (tracking drop-outs) are valid.
    """
    t = _as_float_vector(times, "time", source)
    x = _as_float_vector(positions, "position", source)
    if t.size != x.size:
        raise InputError(source, f"{t.size} times but {x.size} positions")
    if t.size < MIN_SAMPLES:
        raise InputError(source, f"only {t.size} samples; at least {MIN_SAMPLES} are needed")
    with np.errstate(over="ignore"):  # a span beyond float range gives an absurd rate below
        steps = np.diff(t)
        if np.any(steps <= 0):
            i = int(np.argmax(steps <= 0))
            raise InputError(
                source, f"time does not increase at sample {i + 1} (t = {t[i + 1]:g} s)"
            )
        rate = (t.size - 1) / (t[-1] - t[0])
    if not MIN_RATE <= rate <= MAX_RATE:
        raise InputError(
            source,
            f"mean sampling rate {rate:.3g} Hz is outside {MIN_RATE:g}-{MAX_RATE:g} Hz: if time "
            "is not in seconds, give --time-unit ms, us, epoch, epoch_ms or epoch_us",
        )
    peak = float(np.max(np.abs(x)))
    if peak > MAX_ABS_POSITION:
        raise InputError(
            source,
            f"|position| reaches {peak:.3g}, beyond the normalised playing range "
            f"{PLAYING_RANGE[0]} to {PLAYING_RANGE[1]}: give the unit with --position-unit "
            "mm, cm or m (and --playing-range, the centimetres that make one unit)",
        )
    meta = dict(metadata or {})
    if source is not None:
        meta.setdefault("source", str(source))
    return Trial(t, x, label=label, group=group, metadata=meta)


def _as_float_vector(values: ArrayLike, name: str, source: str | None) -> Array:
    try:
        array = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(source, f"{name} column has non-numeric values") from None
    if array.ndim != 1:
        raise InputError(source, f"{name} must be one-dimensional, got shape {array.shape}")
    bad = ~np.isfinite(array)
    if np.any(bad):
        i = int(np.argmax(bad))
        raise InputError(source, f"{name} is {array[i]} at sample {i}; NaN and inf are not allowed")
    return array


def resample(
    trial: Trial, rate: float = DEFAULT_RATE, method: Literal["pchip", "linear"] = "pchip"
) -> Trial:
    """Interpolate a trial onto a uniform grid.

    Parameters
    ----------
    trial
        Any valid trial, regularly or irregularly sampled.
    rate
        Target rate (Hz). The grid starts at the first sample and steps by ``1/rate`` up to the
        last sample.
    method
        ``"pchip"`` (default, **choice**: shape-preserving cubic, so no overshoot at drop-outs
        and a continuous velocity) or ``"linear"``.

    Returns
    -------
    Trial
        A new trial with the same label, group and metadata, plus ``metadata["resampled_from"]``
        (the original mean rate, Hz: that of the recording, kept when a trial is resampled
        again).
    """
    if not MIN_RATE <= rate <= MAX_RATE:
        raise InputError("rate", f"{rate:g} Hz is outside {MIN_RATE:g}-{MAX_RATE:g} Hz")
    n = int(np.floor(trial.duration * rate + 1e-9)) + 1
    grid = trial.times[0] + np.arange(n) / rate
    if method == "pchip":
        positions = PchipInterpolator(trial.times, trial.positions)(grid)
    elif method == "linear":
        positions = np.interp(grid, trial.times, trial.positions)
    else:
        raise InputError("method", f"unknown interpolation {method!r}; use 'pchip' or 'linear'")
    metadata = {"resampled_from": trial.rate, **trial.metadata}
    return replace(trial, times=grid, positions=np.asarray(positions), metadata=metadata)


@cache
def butterworth_lowpass(order: int, cutoff: float, rate: float) -> tuple[Array, Array]:
    """Return a Butterworth low-pass filter, designed once per setting.

    Returns
    -------
    sos, initial : ndarray
        Second-order sections, shape (n_sections, 6), and their steady-state initial
        conditions for a unit step (`scipy.signal.sosfilt_zi`), shape (n_sections, 2). Shared:
        callers must not modify them.
    """
    sos = np.asarray(butter(order, cutoff, btype="low", fs=rate, output="sos"), dtype=np.float64)
    return sos, np.asarray(sosfilt_zi(sos), dtype=np.float64)


@njit(cache=True, nogil=True, inline="always")
def _section(
    x: float, z0: float, z1: float, b0: float, b1: float, b2: float, a1: float, a2: float
) -> tuple[float, float, float]:
    """One sample through a second-order section (direct form II transposed): ``(y, z0, z1)``."""
    y = b0 * x + z0
    return y, b1 * x - a1 * y + z1, b2 * x - a2 * y


@njit(cache=True, nogil=True)
def _cascade(sos: Array, signals: Array, initial: Array, scale: Array, backward: bool) -> None:
    """Second-order sections in direct form II transposed, in place (as `scipy.signal.sosfilt`).

    ``signals`` (n, L) holds L signals as columns, filtered side by side (the loop over them
    vectorises; each one's arithmetic is that of a signal filtered alone; one signal keeps its
    state in registers). ``initial`` (n_sections, 2) times ``scale[j]`` is signal j's initial
    state. With ``backward`` the signals are filtered from their last sample to their first.
    Sections are applied two at a time in one pass (their recursions overlap in the processor).
    """
    n, n_signals = signals.shape
    z0, z1 = np.empty(n_signals), np.empty(n_signals)
    w0, w1 = np.empty(n_signals), np.empty(n_signals)
    for s in range(0, sos.shape[0], 2):
        pair = s + 1 < sos.shape[0]
        b0, b1, b2, a1, a2 = sos[s, 0], sos[s, 1], sos[s, 2], sos[s, 4], sos[s, 5]
        t = s + 1 if pair else s
        c0, c1, c2, e1, e2 = sos[t, 0], sos[t, 1], sos[t, 2], sos[t, 4], sos[t, 5]
        for j in range(n_signals):
            z0[j], z1[j] = initial[s, 0] * scale[j], initial[s, 1] * scale[j]
            w0[j], w1[j] = initial[t, 0] * scale[j], initial[t, 1] * scale[j]
        if n_signals == 1:
            signal, u0, u1, v0, v1 = signals.reshape(n), z0[0], z1[0], w0[0], w1[0]
            for k in range(n):
                i = n - 1 - k if backward else k
                y, u0, u1 = _section(signal[i], u0, u1, b0, b1, b2, a1, a2)
                if pair:
                    y, v0, v1 = _section(y, v0, v1, c0, c1, c2, e1, e2)
                signal[i] = y
            continue
        for k in range(n):
            row = signals[n - 1 - k if backward else k]
            for j in range(n_signals):
                y, z0[j], z1[j] = _section(row[j], z0[j], z1[j], b0, b1, b2, a1, a2)
                if pair:
                    y, w0[j], w1[j] = _section(y, w0[j], w1[j], c0, c1, c2, e1, e2)
                row[j] = y


def zero_phase_filter(sos: Array, initial: Array, signal: Array, padlen: int) -> Array:
    """Forward-backward filtering with odd extension, as `scipy.signal.sosfiltfilt`.

    Parameters
    ----------
    sos
        Second-order sections, shape (n_sections, 6), ``a0 = 1``.
    initial
        Steady-state initial conditions for a unit step (`scipy.signal.sosfilt_zi`),
        shape (n_sections, 2).
    signal
        Signal, shape (n,), or signals as columns, shape (n, L), filtered side by side;
        n > padlen.
    padlen
        Samples of odd extension at each end.

    Returns
    -------
    numpy.ndarray
        Filtered signal(s), the shape of ``signal``.
    """
    signals = np.ascontiguousarray(signal, dtype=np.float64)
    filtered = _zero_phase_columns(sos, initial, signals.reshape(signals.shape[0], -1), padlen)
    return filtered.reshape(signals.shape)


_READ_ONLY_MATRIX = types.Array(types.float64, 2, "C", readonly=True)
"""A C-contiguous float64 matrix the kernel only reads: writable arrays are taken as it too."""


@njit(
    (_READ_ONLY_MATRIX, _READ_ONLY_MATRIX, _READ_ONLY_MATRIX, types.int64), cache=True, nogil=True
)
def _zero_phase_columns(sos: Array, initial: Array, signals: Array, padlen: int) -> Array:
    """`zero_phase_filter` of the columns of ``signals`` (n, L), C-contiguous.

    The signals are copied into the extended array as one flat block (numba copies a 2-D slice
    element by element), and the filtered signals are returned as a view of it. The arguments
    are declared read-only, so one compiled version serves writable arrays and read-only ones
    (a file's columns read without a copy) alike.
    """
    n = signals.shape[0]
    extended = np.empty((n + 2 * padlen, signals.shape[1]))
    for i in range(padlen):
        for j in range(signals.shape[1]):
            extended[i, j] = 2.0 * signals[0, j] - signals[padlen - i, j]
            extended[n + padlen + i, j] = 2.0 * signals[n - 1, j] - signals[n - 2 - i, j]
    width = signals.shape[1]
    extended.reshape(-1)[padlen * width : (padlen + n) * width] = signals.reshape(-1)
    _cascade(sos, extended, initial, extended[0].copy(), False)
    _cascade(sos, extended, initial, extended[-1].copy(), True)
    return extended[padlen : padlen + n]


def lowpass(signal: ArrayLike, rate: float, cutoff: float = 10.0, order: int = 4) -> Array:
    """Zero-phase Butterworth low-pass filter (`scipy.signal.sosfiltfilt`'s method, compiled).

    Parameters
    ----------
    signal
        Uniformly sampled signal, shape (n,), or signals as columns, shape (n, L).
    rate
        Sampling rate (Hz).
    cutoff
        Cut-off frequency (Hz). When it is at or above the Nyquist frequency the signal is
        returned unfiltered (there is nothing above it to remove).
    order
        Filter order (the forward-backward pass doubles the effective order).
    """
    x = np.asarray(signal, dtype=np.float64)
    if cutoff >= rate / 2:
        return x.copy()
    sos, initial = butterworth_lowpass(order, cutoff, rate)
    padlen = min(3 * (2 * len(sos) + 1), x.shape[0] - 1)
    return zero_phase_filter(sos, initial, x, padlen)


def finite_difference(signal: ArrayLike, step: float) -> Array:
    """Fourth-order finite-difference derivative.

    Central ``(x[i-2]/12 - 2x[i-1]/3 + 2x[i+1]/3 - x[i+2]/12)/h`` inside; the one-sided
    5-point formulas of the same order for the first two and the last two samples. Exact on
    polynomials up to degree 4.

    Parameters
    ----------
    signal
        Uniformly sampled signal, shape (n,), or signals as columns, shape (n, L); n >= 5.
    step
        Sample spacing h (s).

    Returns
    -------
    numpy.ndarray
        Derivative, the shape of ``signal``, in signal units per second.
    """
    x = np.asarray(signal, dtype=np.float64)
    if x.shape[0] < 5:
        raise InputError(None, f"finite difference needs at least 5 samples, got {x.shape[0]}")
    return _differences(x.reshape(x.shape[0], -1), step).reshape(x.shape)


@njit(cache=True, nogil=True, inline="always")
def _central(before2: float, before: float, after: float, after2: float, step: float) -> float:
    """Return the fourth-order central difference from the two samples on each side."""
    return (before2 / 12 - 2 * before / 3 + 2 * after / 3 - after2 / 12) / step


@njit(cache=True, nogil=True)
def _differences(x: Array, step: float) -> Array:
    """`finite_difference` of the columns of ``x`` (n, L), n >= 5, compiled.

    The interior loop runs along the samples for one signal and across the signals for several,
    so it vectorises either way.
    """
    n, n_signals = x.shape
    d = np.empty_like(x)
    if n_signals == 1:
        signal, derivative = x.reshape(n), d.reshape(n)
        for i in range(2, n - 2):
            derivative[i] = _central(
                signal[i - 2], signal[i - 1], signal[i + 1], signal[i + 2], step
            )
    else:
        for i in range(2, n - 2):
            for j in range(n_signals):
                d[i, j] = _central(x[i - 2, j], x[i - 1, j], x[i + 1, j], x[i + 2, j], step)
    for j in range(n_signals):
        a, b, c, e, f = x[0, j], x[1, j], x[2, j], x[3, j], x[4, j]
        d[0, j] = (-25 * a + 48 * b - 36 * c + 16 * e - 3 * f) / (12 * step)
        d[1, j] = (-3 * a - 10 * b + 18 * c - 6 * e + f) / (12 * step)
        a, b, c, e, f = x[n - 1, j], x[n - 2, j], x[n - 3, j], x[n - 4, j], x[n - 5, j]
        d[n - 1, j] = (25 * a - 48 * b + 36 * c - 16 * e + 3 * f) / (12 * step)
        d[n - 2, j] = (3 * a + 10 * b - 18 * c + 6 * e - f) / (12 * step)
    return d


def compute_velocity(
    positions: ArrayLike, rate: float, cutoff: float | None = 10.0, order: int = 4
) -> Array:
    """Velocity of a uniformly sampled position signal (METHODS section 2).

    Parameters
    ----------
    positions
        Positions, shape (n,), units, sampled at ``rate``; or several signals as columns,
        shape (n, L), filtered side by side.
    rate
        Sampling rate (Hz).
    cutoff
        Low-pass cut-off (Hz) applied before differentiating; ``None`` skips the filter.
    order
        Butterworth order.

    Returns
    -------
    numpy.ndarray
        Velocity, the shape of ``positions``, units/s.
    """
    x = np.asarray(positions, dtype=np.float64)
    if cutoff is not None:
        x = lowpass(x, rate, cutoff, order)
    return finite_difference(x, 1.0 / rate)
