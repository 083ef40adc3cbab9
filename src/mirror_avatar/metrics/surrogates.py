"""Chance levels: surrogate pairs and groups, p-values, and the weak-null test of group synchrony.

A coordination measure means something only against what it takes for players who do not
interact. Two kinds of surrogate keep each player's own motion and break the interaction:

- circular shifts (e.g. Lancaster et al. 2018, Phys Rep 748:1): every player but player 0 is
  rotated in time by its own random offset of at least ``min_shift`` seconds from either end;
- pseudo-pairs (Bernieri et al. 1988; Ramseyer & Tschacher 2010): player 0 of one session with
  the partners of another session of the same size, cut to the shorter length.

The p-value of an observed value against ``m`` surrogate values is ``(1 + b) / (1 + m)``, with
``b`` the surrogates at least as extreme (Phipson & Smyth 2010), so it is never 0. For a sample
of sessions, the weak-null test of Frank & Richardson (2010, Physica D 239:2084) asks whether the
mean squared Kuramoto order parameter exceeds ``1/N``, its expectation for N independent uniform
phases (one-sided one-sample t-test; multiSyncPy's ``kuramoto_weak_null`` is the same test with
the population SD, the tests compare the two).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats

from mirror_avatar.common.errors import InputError

Array = NDArray[np.float64]

MIN_SHIFT = 2.0
"""Smallest circular shift (s) from either end (**choice**)."""


def shift_offsets(
    n_samples: int, n_players: int, n_surrogates: int, min_samples: int, rng: np.random.Generator
) -> NDArray[np.int64]:
    """Random circular-shift offsets, shape (n_surrogates, n_players); player 0's are 0.

    Each other player's offset is uniform on ``[min_samples, n_samples - min_samples]``.
    """
    if n_samples - 2 * min_samples < 1:
        raise InputError(
            "surrogates",
            f"{n_samples} samples are too few for circular shifts of at least {min_samples} "
            "samples (lower --min-shift)",
        )
    offsets = rng.integers(min_samples, n_samples - min_samples + 1, (n_surrogates, n_players))
    offsets[:, 0] = 0
    return offsets.astype(np.int64)


def shifted(series: ArrayLike, offsets: ArrayLike) -> Array:
    """Each row of ``series`` (shape (N, n)) rolled by its offset (shape (N,))."""
    s = np.asarray(series, dtype=float)
    return np.array([np.roll(row, int(k)) for row, k in zip(s, np.asarray(offsets), strict=True)])


def pseudo_session(own: ArrayLike, partners: ArrayLike) -> Array:
    """Player 0 of ``own`` (shape (N, n)) with players 1.. of ``partners`` (shape (N, n')).

    Both are cut to the shorter length from their start; the result has shape
    (N, min(n, n')). Call it once per channel (positions, velocities).
    """
    a, b = np.asarray(own, dtype=float), np.asarray(partners, dtype=float)
    if a.ndim != 2 or a.shape[0] != b.shape[0]:
        raise InputError("surrogates", "pseudo-pairs need sessions with as many players")
    n = min(a.shape[1], b.shape[1])
    out = b[:, :n].copy()
    out[0] = a[0, :n]
    return out


def p_value(observed: float, null: ArrayLike, greater: bool = True) -> float:
    """``(1 + b) / (1 + m)``: share of ``m`` finite surrogates at least as extreme, plus one.

    Parameters
    ----------
    observed
        The measure on the real data; NaN gives NaN.
    null
        The measure on each surrogate; NaN values are left out.
    greater
        True when larger values mean more coordination, False when smaller do (RMS).
    """
    values = np.asarray(null, dtype=float)
    values = values[np.isfinite(values)]
    if not np.isfinite(observed) or values.size == 0:
        return float("nan")
    extreme = values >= observed if greater else values <= observed
    return float((1 + np.sum(extreme)) / (1 + values.size))


@dataclass(frozen=True)
class WeakNull:
    """The weak-null test of a sample of sessions.

    One-sided ``p``, ``t``, degrees of freedom ``df``, the mean squared order parameter of the
    sample ``mean_r2`` and ``chance`` = 1/N.
    """

    p: float
    t: float
    df: int
    mean_r2: float
    chance: float

    def __str__(self) -> str:
        return (
            f"mean r^2 {self.mean_r2:.4f} against chance {self.chance:.4f}: "
            f"t({self.df}) = {self.t:.3f}, one-sided p = {self.p:.3g}"
        )


def kuramoto_weak_null(phases: Sequence[ArrayLike]) -> WeakNull:
    """Weak-null test of group synchrony over a sample of sessions (module docstring).

    Parameters
    ----------
    phases
        One array per session of the players' phases (rad), shape (N, n_s); every session has
        the same N >= 2 players, lengths may differ; at least two sessions.
    """
    arrays = [np.asarray(p, dtype=float) for p in phases]
    sizes = {a.shape[0] for a in arrays if a.ndim == 2}
    if len(arrays) < 2 or len(sizes) != 1 or any(a.ndim != 2 for a in arrays):
        raise InputError("weak null", "needs two or more sessions with the same number of players")
    players = sizes.pop()
    y = np.array([np.mean(np.abs(np.mean(np.exp(1j * a), axis=0)) ** 2) for a in arrays])
    chance = 1.0 / players
    test = stats.ttest_1samp(y, chance, alternative="greater")
    return WeakNull(
        p=float(test.pvalue), t=float(test.statistic), df=y.size - 1,
        mean_r2=float(y.mean()), chance=chance,
    )  # fmt: skip
