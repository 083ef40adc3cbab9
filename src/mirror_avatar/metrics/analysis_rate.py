"""The analysis rate: sessions recorded faster than the measures need are decimated first.

The coordination metrics and measures look at motion below about 10 Hz (velocities are
low-passed at 10 Hz, METHODS section 2; jitter is a 2-3 Hz band; lags are resolved to a
sample), so a session sampled faster than `ANALYSIS_RATE` carries nothing they use above it,
while it multiplies their time and memory (the windowed cross-correlation of leadership grows
with the square of the rate). `at_analysis_rate` keeps every ``q``-th sample, with ``q`` the
smallest whole factor that brings the rate to `ANALYSIS_RATE` or below, after an
anti-aliasing low-pass (`scipy.signal.resample_poly`: its default Kaiser-window FIR filter,
cut-off at the new Nyquist frequency, applied without phase shift, the series' linear trend
between its ends removed before filtering so that its ends do not ring). Positions and
velocities are filtered so; controls and references (piecewise constant over a control
period, NaN where a player has none) are sampled as they are. A session at or below
`ANALYSIS_RATE` is returned as it is, so its numbers do not change.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import signal

from mirror_avatar.common.errors import InputError
from mirror_avatar.sessions.session import Session

ANALYSIS_RATE = 100.0
"""Highest rate (Hz) the metrics and measures are computed at (**choice**: ten times the
10 Hz cut-off of the velocities, and the rate of the toolkit's trials)."""

RATE_TOLERANCE = 1e-3
"""Relative excess over `ANALYSIS_RATE` still taken as that rate (time stamps are rounded)."""


def session_rate(session: Session) -> float:
    """Return the sampling rate (Hz) of a session: one over its median sample interval.

    Raises
    ------
    mirror_avatar.common.errors.InputError
        A session of fewer than two samples (it has no interval).
    """
    if session.n_samples < 2:
        raise InputError(None, f"a session of {session.n_samples} sample(s) has no sampling rate")
    return 1.0 / float(np.median(np.diff(session.times)))


def decimation_factor(rate: float, target: float = ANALYSIS_RATE) -> int:
    """Smallest whole ``q`` with ``rate / q`` at most ``target`` (within `RATE_TOLERANCE`)."""
    return max(1, math.ceil(rate / target - RATE_TOLERANCE))


def at_analysis_rate(session: Session, target: float = ANALYSIS_RATE) -> Session:
    """Return ``session`` decimated to ``target`` Hz or below (module docstring).

    Parameters
    ----------
    session
        Any session, uniformly sampled.
    target
        Highest rate kept (Hz).

    Returns
    -------
    Session
        ``session`` itself when its rate is at most ``target``; otherwise a session with every
        ``q``-th sample time (`decimation_factor`), its positions and velocities anti-aliased.
    """
    q = decimation_factor(session_rate(session), target)
    if q == 1:
        return session
    n = math.ceil(session.n_samples / q)

    def filtered(channel: np.ndarray) -> np.ndarray:
        out = signal.resample_poly(channel, 1, q, axis=1, padtype="line")
        return np.asarray(out[:, :n], dtype=np.float64)

    return replace(
        session,
        times=session.times[::q],
        positions=filtered(session.positions),
        velocities=filtered(session.velocities),
        controls=session.controls[:, ::q],
        references=session.references[:, ::q],
    )
