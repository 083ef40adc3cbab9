"""Short-time Fourier framing and weighted overlap-add synthesis (METHODS section 4, steps 1, 2, 5).

A position signal is cut into frames of ``window`` samples every ``hop`` samples, each multiplied
by a periodic Hamming window and Fourier transformed (FFT length = window, so ``window // 2 + 1``
one-sided bins). Synthesis inverts each frame, multiplies it by the same window again and divides
the overlapped sum by the overlapped sum of squared windows (Griffin-Lim weighted overlap-add), so
the unmodified STFT of a signal gives the signal back to rounding error wherever a frame covers it.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

Array = NDArray[np.float64]


def hamming_window(length: int) -> Array:
    """Periodic Hamming window ``0.54 - 0.46 cos(2 pi n / length)``, shape (length,)."""
    n = np.arange(length)
    return 0.54 - 0.46 * np.cos(2.0 * np.pi * n / length)


def frame_signal(signal: Array, window: int, hop: int) -> Array:
    """Frames of ``signal``, shape (n_frames, window), starting every ``hop`` samples."""
    n_frames = 1 + (signal.size - window) // hop
    if n_frames < 1:
        return np.empty((0, window))
    starts = hop * np.arange(n_frames)
    return signal[starts[:, None] + np.arange(window)]


def compute_stft(signal: Array, window: int, hop: int) -> NDArray[np.complex128]:
    """One-sided spectra of the windowed frames, shape (n_frames, window // 2 + 1)."""
    return np.fft.rfft(frame_signal(signal, window, hop) * hamming_window(window), axis=1)


def spectra_to_features(spectra: NDArray[np.complex128]) -> Array:
    """Real feature vectors ``[Re X0..Re X_{m-1}, Im X1..Im X_{m-2}]``, shape (n, window).

    The imaginary parts of the DC and Nyquist bins are zero for a real even-length frame and are
    left out (window must be even).
    """
    return np.hstack([spectra.real, spectra.imag[:, 1:-1]])


def features_to_spectra(features: Array, window: int) -> NDArray[np.complex128]:
    """Inverse of `spectra_to_features`, shape (n, window // 2 + 1)."""
    n_bins = window // 2 + 1
    spectra = features[:, :n_bins].astype(np.complex128)
    spectra[:, 1:-1] += 1j * features[:, n_bins:]
    return spectra


def synthesis_frames(spectra: NDArray[np.complex128], window: int) -> Array:
    """Time-domain frames ready for overlap-add: inverse FFT times the window, (n, window)."""
    return np.fft.irfft(spectra, n=window, axis=1) * hamming_window(window)


def overlap_add(
    frames: Array, sequence: NDArray[np.int64], hop: int, window_squared: Array
) -> Array:
    """Weighted overlap-add of ``frames[sequence[m]]`` placed every ``hop`` samples.

    Parameters
    ----------
    frames
        Synthesis frames, shape (n_codes, window) (see `synthesis_frames`).
    sequence
        Which frame goes at each position, shape (n_frames,).
    hop
        Samples between frame starts.
    window_squared
        The squared analysis window, shape (window,).

    Returns
    -------
    numpy.ndarray
        Signal of ``hop * (n_frames - 1) + window`` samples; samples no frame covers are 0.
    """
    norm = overlap_norm(sequence.size, hop, window_squared)
    signal = np.empty(norm.size)
    overlap_add_into(frames, sequence, hop, norm, 0, -np.inf, np.inf, signal)
    return signal


@njit(cache=True, nogil=True)
def overlap_norm(n_frames: int, hop: int, window_squared: Array) -> Array:
    """Return the overlapped sum of squared windows of ``n_frames`` frames every ``hop`` samples.

    Shape ``(hop * (n_frames - 1) + window,)``: what `overlap_add` divides by.
    """
    norm = np.zeros(hop * (n_frames - 1) + window_squared.size)
    for m in range(n_frames):
        _add_at(norm, m * hop, window_squared)
    return norm


@njit(cache=True, nogil=True, error_model="numpy")
def overlap_add_into(
    frames: Array,
    sequence: NDArray[np.int64],
    hop: int,
    norm: Array,
    start: int,
    low: float,
    high: float,
    out: Array,
) -> None:
    """Write samples ``start .. start + out.size - 1`` of `overlap_add`, clipped, into ``out``.

    ``norm`` is `overlap_norm` of the sequence; ``low`` and ``high`` clip as `numpy.clip`.
    """
    total = np.zeros(norm.size)
    for m in range(sequence.size):
        _add_at(total, m * hop, frames[sequence[m]])
    for i in range(out.size):
        value = total[start + i]
        value = value / norm[start + i] if norm[start + i] > 1e-12 else value
        out[i] = low if value < low else (high if value > high else value)


@njit(cache=True, nogil=True, inline="always")
def _add_at(signal: Array, start: int, frame: Array) -> None:
    """Add ``frame`` to ``signal`` from sample ``start`` on, in place.

    Through a view of the segment, which the compiler vectorises (indexing ``signal`` at
    ``start + i`` it does not).
    """
    segment = signal[start : start + frame.size]
    for i in range(frame.size):
        segment[i] += frame[i]


def resynthesise(spectra: NDArray[np.complex128], window: int, hop: int) -> Array:
    """Signal from a sequence of one-sided spectra by weighted overlap-add."""
    frames = synthesis_frames(spectra, window)
    sequence = np.arange(frames.shape[0], dtype=np.int64)
    return overlap_add(frames, sequence, hop, hamming_window(window) ** 2)
