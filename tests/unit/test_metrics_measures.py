"""session_measures on sessions of every shape: short, still, shorter than a leadership window."""

from __future__ import annotations

import numpy as np
import pytest

from mirror_avatar.metrics.measures import MeasureOptions, session_measures
from mirror_avatar.sessions.session import Session
from mirror_avatar.testing import smooth_motion

RATE = 50.0


def make_session(positions: np.ndarray) -> Session:
    n = positions.shape[1]
    nan = np.full(positions.shape, np.nan)
    velocities = np.gradient(positions, 1 / RATE, axis=1)
    return Session(np.arange(n) / RATE, positions, velocities, nan, nan)


def test_a_session_too_short_for_the_filters_has_no_measures():
    session = make_session(np.sin(np.arange(20) / 5.0)[None, :].repeat(2, axis=0))
    assert session_measures(session).values == {}


def test_a_still_player_leaves_only_the_jitter(rng):
    x = np.array([smooth_motion(rng, 500, RATE), np.zeros(500)])
    values = session_measures(make_session(x)).values
    assert set(values) == {"jitter_index_player_0", "jitter_index_player_1"}
    assert values["jitter_index_player_1"] == 0.0


def test_a_session_shorter_than_a_leadership_window(rng):
    """5 s: no window of 4 s with lags of 1 s each side, so no leader; shifts of 1 s still fit."""
    s = smooth_motion(rng, 255, RATE)
    session = make_session(np.array([s[5:], s[:-5]]))
    found = session_measures(session, options=MeasureOptions(n_surrogates=9, min_shift=1.0))
    assert found.values["leader"] == "none" and np.isnan(found.values["leader_share"])
    assert "leadership" not in found.details and found.values["surrogates"]["n"] == 9
    assert found.values["phase_locking_p_value"] == pytest.approx(0.1)
    short = session_measures(session, options=MeasureOptions(n_surrogates=9, min_shift=3.0))
    assert short.values["surrogates"]["n"] == 0 and "phase_locking_p_value" not in short.values
