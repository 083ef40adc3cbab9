"""Coordination between two position series (METHODS section 6), as functions on arrays.

Every function checks its inputs at the door and raises :class:`InputError` on bad input.
Sign convention everywhere: positive relative phase and positive time lag mean series 1 leads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import ArrayLike, NDArray
from scipy import signal, stats

from mirror_avatar.common.errors import InputError

PHASE_METHODS = ("hilbert", "kralemann")

MAX_LAG = 1.5
"""Largest time lag searched by the cross-correlation (s, METHODS section 6)."""


def _check_pair(x1: ArrayLike, x2: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    a = np.asarray(x1, dtype=float)
    b = np.asarray(x2, dtype=float)
    if a.ndim != 1 or a.shape != b.shape or a.size < 2:
        raise InputError(
            "positions", f"need two 1-D series of equal length >= 2, got {a.shape} and {b.shape}"
        )
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise InputError("positions", "contain NaN or infinite values")
    return a, b


def compute_rmse(x1: ArrayLike, x2: ArrayLike) -> float:
    """Root mean square of the position difference ``x1 - x2`` (units of the positions)."""
    a, b = _check_pair(x1, x2)
    return float(np.sqrt(np.mean((a - b) ** 2)))


def _protophase(x: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.unwrap(np.angle(signal.hilbert(x - x.mean(axis=-1, keepdims=True))), axis=-1)


def compute_phase(x: ArrayLike, method: str = "hilbert", n_terms: int = 10) -> NDArray[np.float64]:
    """Unwrapped phase of one position series, shape (n,), or of each of several, radians.

    Parameters
    ----------
    x
        Positions, shape (n,), n >= 2, or (..., n): each series along the last axis.
    method
        ``"hilbert"``: phase of the analytic signal of the mean-removed position (METHODS 6).
        ``"kralemann"``: that protophase refined to a phase by the Fourier-series transform of
        its density (Kralemann et al. 2008), a **choice** offered as an option.
    n_terms
        Number of Fourier terms of the Kralemann transform (**choice**, default 10).
    """
    a = np.asarray(x, dtype=float)
    if a.ndim < 1 or a.shape[-1] < 2 or not np.all(np.isfinite(a)):
        raise InputError("positions", f"need finite series of length >= 2, got {a.shape}")
    if method not in PHASE_METHODS:
        raise InputError("method", f"unknown phase method {method!r}; use one of {PHASE_METHODS}")
    theta = _protophase(a)
    return _kralemann_phase(theta, n_terms) if method == "kralemann" else theta


def _kralemann_phase(theta: NDArray[np.float64], n_terms: int) -> NDArray[np.float64]:
    """Map a protophase to a phase (Kralemann et al. 2008).

    ``phi = theta + sum_{n != 0} S_n (exp(i n theta) - 1) / (i n)``,
    ``S_n = mean(exp(-i n theta))``.
    """
    phi = theta.astype(float).copy()
    for n in range(1, n_terms + 1):
        s_n = np.mean(np.exp(-1j * n * theta), axis=-1, keepdims=True)
        term = s_n / (1j * n) * (np.exp(1j * n * theta) - 1.0)
        phi += 2.0 * term.real
    return phi


def compute_relative_phase(
    x1: ArrayLike, x2: ArrayLike, method: str = "hilbert", n_terms: int = 10
) -> NDArray[np.float64]:
    """Relative phase ``phi_1 - phi_2`` wrapped to [-pi, pi], shape (n,), radians.

    Parameters
    ----------
    x1, x2
        Positions of player 1 and 2, shape (n,).
    method, n_terms
        As in `compute_phase`.

    Returns
    -------
    ndarray
        Positive values mean player 1 is ahead (leading).
    """
    a, b = _check_pair(x1, x2)
    return wrap_phase(compute_phase(a, method, n_terms) - compute_phase(b, method, n_terms))


def wrap_phase(phase: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles to [-pi, pi] (radians)."""
    return np.angle(np.exp(1j * np.asarray(phase, dtype=float)))


def _check_phase(phase_difference: ArrayLike) -> NDArray[np.float64]:
    d = np.asarray(phase_difference, dtype=float)
    if d.ndim != 1 or d.size == 0 or not np.all(np.isfinite(d)):
        raise InputError("phase difference", "need a non-empty finite 1-D array")
    return d


def compute_phase_locking(phase_difference: ArrayLike) -> float:
    """Compute the paper's "circular variance", ``|mean(exp(i dphi))|`` in [0, 1].

    It is the mean resultant length of the relative phase.

    1 means perfect phase locking, 0 no consistent relation. This follows the paper and its
    predecessors; it is NOT the statistician's circular variance ``1 - R``.
    """
    d = _check_phase(phase_difference)
    return float(np.abs(np.mean(np.exp(1j * d))))


def compute_mean_relative_phase(phase_difference: ArrayLike) -> float:
    """Circular mean ``angle(mean(exp(i dphi)))`` of a relative phase, radians in [-pi, pi]."""
    d = _check_phase(phase_difference)
    return float(np.angle(np.mean(np.exp(1j * d))))


def compute_circular_sd(resultant_length: float) -> float:
    """Circular standard deviation ``sqrt(-2 ln R)`` (radians) of a mean resultant length R."""
    return float(np.sqrt(-2.0 * np.log(max(resultant_length, 1e-12))))


def compute_time_lag(x1: ArrayLike, x2: ArrayLike, rate: float, max_lag: float = MAX_LAG) -> float:
    """Lag (s) maximising the normalised cross-correlation within +-``max_lag``.

    Positive lag = ``x1`` leads: ``x2(t) ~ x1(t - lag)``, the sign of the relative phase
    ``phase(x1) - phase(x2)`` (`compute_relative_phase`) for the same delay.
    """
    return compute_cross_correlation_peak(x1, x2, rate, max_lag)[0]


def compute_cross_correlation_peak(
    x1: ArrayLike, x2: ArrayLike, rate: float, max_lag: float = MAX_LAG
) -> tuple[float, float]:
    """Lag (s) and value of the largest normalised cross-correlation within +-``max_lag``.

    The correlation is ``sum(a(t) b(t + lag)) / sqrt(sum a² sum b²)`` of the mean-removed series
    (1 for identical shapes). Positive lag = ``x1`` leads, as in `compute_time_lag`.
    """
    a, b = _check_pair(x1, x2)
    if not (np.isfinite(rate) and rate > 0 and np.isfinite(max_lag) and max_lag >= 0):
        raise InputError("rate/max_lag", f"need rate > 0 and max_lag >= 0, got {rate}, {max_lag}")
    lags, values = cross_correlation_peaks(a, b, rate, max_lag)
    if np.isnan(values):
        raise InputError("positions", "a constant series has no cross-correlation")
    return float(lags), float(values)


def cross_correlation_peaks(
    x1: NDArray[np.float64], x2: NDArray[np.float64], rate: float, max_lag: float = MAX_LAG
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """`compute_cross_correlation_peak` of ``x1`` with each of several series at once.

    Each lag's correlation is summed directly over the samples the two series share (no
    transform), for the lags within +-``max_lag`` only.

    Parameters
    ----------
    x1
        Positions, shape (n,), finite.
    x2
        Positions, shape (n,) or (..., n): each series along the last axis, finite.
    rate, max_lag
        Sampling rate (Hz, > 0) and largest lag (s, >= 0).

    Returns
    -------
    lags, values
        Lag (s) and value of each series' peak, shape (...,); the value is NaN when either
        series is constant (no correlation).
    """
    a = x1 - x1.mean()
    b = x2 - x2.mean(axis=-1, keepdims=True)
    norm = np.sqrt(np.sum(a**2) * np.sum(b**2, axis=-1))
    m = min(round(max_lag * rate), a.size - 1)
    padded = np.concatenate((np.zeros((*b.shape[:-1], m)), b, np.zeros((*b.shape[:-1], m))), -1)
    corr = np.einsum("...lt,t->...l", sliding_window_view(padded, a.size, axis=-1), a)
    best = np.argmax(corr, axis=-1)
    with np.errstate(invalid="ignore"):
        peak = np.take_along_axis(corr, best[..., None], axis=-1)[..., 0] / norm
    return (best - m) / rate, peak


@dataclass(frozen=True)
class TTest:
    """Result of a paired t-test: statistic ``t``, degrees of freedom ``df``, two-sided ``p``."""

    t: float
    df: int
    p: float

    def __str__(self) -> str:
        return f"t({self.df}) = {self.t:.3f}, p = {self.p:.3g}"


def paired_ttest(a: ArrayLike, b: ArrayLike) -> TTest:
    """Paired two-sided t-test between conditions ``a`` and ``b`` (scipy.stats.ttest_rel)."""
    x, y = _check_pair(a, b)
    res = stats.ttest_rel(x, y)
    return TTest(t=float(res.statistic), df=x.size - 1, p=float(res.pvalue))
