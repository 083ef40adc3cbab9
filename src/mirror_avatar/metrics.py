"""Coordination metrics between two players (METHODS section 6).

Every function checks its inputs at the door and raises :class:`InputError` on bad input.
Sign convention everywhere: positive relative phase and positive time lag mean player 1 leads.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal, stats

from mirror_avatar.errors import InputError
from mirror_avatar.signature import compute_emd, compute_ims

if TYPE_CHECKING:
    from mirror_avatar.game import Session

PHASE_METHODS = ("hilbert", "kralemann")


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
    return np.unwrap(np.angle(signal.hilbert(x - x.mean())))


def _kralemann_phase(theta: NDArray[np.float64], n_terms: int) -> NDArray[np.float64]:
    """Map a protophase to a phase (Kralemann et al. 2008).

    ``phi = theta + sum_{n != 0} S_n (exp(i n theta) - 1) / (i n)``,
    ``S_n = mean(exp(-i n theta))``.
    """
    phi = theta.astype(float).copy()
    for n in range(1, n_terms + 1):
        s_n = np.mean(np.exp(-1j * n * theta))
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
    method
        ``"hilbert"``: phase of the analytic signal of the mean-removed position (METHODS 6).
        ``"kralemann"``: that protophase refined to a phase by the Fourier-series transform of
        its density (Kralemann et al. 2008), a **choice** offered as an option.
    n_terms
        Number of Fourier terms of the Kralemann transform (**choice**, default 10).

    Returns
    -------
    ndarray
        Positive values mean player 1 is ahead (leading).
    """
    a, b = _check_pair(x1, x2)
    if method not in PHASE_METHODS:
        raise InputError("method", f"unknown phase method {method!r}; use one of {PHASE_METHODS}")
    p1, p2 = _protophase(a), _protophase(b)
    if method == "kralemann":
        p1, p2 = _kralemann_phase(p1, n_terms), _kralemann_phase(p2, n_terms)
    return np.angle(np.exp(1j * (p1 - p2)))


def _check_phase(phase_difference: ArrayLike) -> NDArray[np.float64]:
    d = np.asarray(phase_difference, dtype=float)
    if d.ndim != 1 or d.size == 0 or not np.all(np.isfinite(d)):
        raise InputError("phase difference", "need a non-empty finite 1-D array")
    return d


def compute_circular_variance(phase_difference: ArrayLike) -> float:
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


def compute_time_lag(x1: ArrayLike, x2: ArrayLike, rate: float, max_lag: float = 1.5) -> float:
    """Lag (s) maximising the normalised cross-correlation within +-``max_lag``.

    Positive lag = player 1 leads: ``x2(t) ~ x1(t - lag)``, consistent with the relative phase.
    """
    a, b = _check_pair(x1, x2)
    if not (np.isfinite(rate) and rate > 0 and np.isfinite(max_lag) and max_lag >= 0):
        raise InputError("rate/max_lag", f"need rate > 0 and max_lag >= 0, got {rate}, {max_lag}")
    a, b = a - a.mean(), b - b.mean()
    norm = np.sqrt(np.sum(a**2) * np.sum(b**2))
    if norm == 0:
        raise InputError("positions", "a constant series has no cross-correlation")
    corr = signal.correlate(b, a, mode="full") / norm
    lags = signal.correlation_lags(b.size, a.size, mode="full")
    keep = np.abs(lags) <= round(max_lag * rate)
    return float(lags[keep][np.argmax(corr[keep])] / rate)


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


def session_metrics(session: Session, trim: float = 0.0) -> dict[str, float | None]:
    """All coordination metrics of one two-player session (METHODS section 6).

    Relative phase and time lag are of player 0 with respect to player 1: positive when player 0
    is ahead.

    Parameters
    ----------
    session
        A `mirror_avatar.game.Session` (times (n,) s, positions and velocities (2, n), reference
        velocities (2, n), NaN where a player has none).
    trim
        Seconds dropped at the start (transient), a **choice**.

    Returns
    -------
    dict
        ``rmse`` (units), ``circular_variance`` (the paper's name for the mean resultant length),
        ``mean_relative_phase`` and ``sd_relative_phase`` (circular SD) (rad), ``time_lag`` (s),
        ``emd_players`` (between the two players' velocity IMS) and ``emd_reference_0`` /
        ``emd_reference_1`` (each player's IMS to the IMS of its reference velocities; None for
        a player without references).
    """
    times = np.asarray(session.times, dtype=float)
    keep = times >= times[0] + trim
    if keep.sum() < 2:
        raise InputError("trim", f"{trim} s leaves fewer than two samples")
    rate = 1.0 / float(np.median(np.diff(times)))
    x = np.asarray(session.positions, dtype=float)[:, keep]
    v = np.asarray(session.velocities, dtype=float)[:, keep]
    references = np.asarray(session.references, dtype=float)[:, keep]
    dphi = compute_relative_phase(x[0], x[1])
    r = compute_circular_variance(dphi)
    ims = [compute_ims(v[i]) for i in range(2)]
    out: dict[str, float | None] = {
        "rmse": compute_rmse(x[0], x[1]),
        "circular_variance": r,
        "mean_relative_phase": compute_mean_relative_phase(dphi),
        "sd_relative_phase": float(np.sqrt(-2.0 * np.log(max(r, 1e-12)))),
        "time_lag": compute_time_lag(x[0], x[1], rate),
        "emd_players": compute_emd(ims[0], ims[1]),
    }
    for i in range(2):
        finite = references[i][np.isfinite(references[i])]
        emd = compute_emd(ims[i], compute_ims(finite)) if finite.size else None
        out[f"emd_reference_{i}"] = emd
    return out
