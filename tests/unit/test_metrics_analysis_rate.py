"""The analysis rate: whole decimation factors, sessions at or below it untouched, anti-aliasing."""

from __future__ import annotations

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.metrics.analysis_rate import (
    ANALYSIS_RATE,
    at_analysis_rate,
    decimation_factor,
    session_rate,
)
from mirror_avatar.metrics.measuring import measure_trial
from mirror_avatar.sessions.session import Session


def session_of(positions: np.ndarray, rate: float) -> Session:
    n = positions.shape[1]
    velocities = np.gradient(positions, 1 / rate, axis=1)
    controls = np.full_like(positions, np.nan)
    controls[:, : n - 1] = 1.0
    return Session(np.arange(n) / rate, positions, velocities, controls, controls.copy())


@pytest.mark.parametrize(
    ("rate", "factor"),
    [(33.3, 1), (100.0, 1), (100.05, 1), (101.0, 2), (150.0, 2), (200.0, 2), (1000.0, 10),
     (1000.5, 11), (240.0, 3)],
)  # fmt: skip
def test_the_factor_is_the_smallest_whole_one_reaching_the_analysis_rate(rate, factor):
    assert decimation_factor(rate) == factor
    assert rate / factor <= ANALYSIS_RATE * 1.001


@pytest.mark.parametrize("n", [0, 1])
def test_a_session_too_short_for_a_rate_is_refused_in_words_and_not_measured(n: int) -> None:
    """A lab trial ended at its first tick has one sample: measuring it once crashed the
    server with a NaN rate; now it has no rate (one line) and no measures."""
    none = np.zeros((2, n))
    session = Session(np.arange(n) / 100.0, none, none, none, none)
    with pytest.raises(InputError, match=f"a session of {n} sample"):
        session_rate(session)
    assert measure_trial(session) is None


def test_a_session_at_or_below_the_analysis_rate_is_returned_as_it_is():
    t = np.arange(500) / 100.0
    session = session_of(np.array([np.sin(t), np.cos(t)]), 100.0)
    assert at_analysis_rate(session) is session


def test_a_1_khz_session_keeps_its_slow_motion_and_loses_what_would_alias():
    rate, n = 1000.0, 20_000
    t = np.arange(n) / rate
    slow = 0.3 * np.sin(2 * np.pi * 0.5 * t) + 0.1 * np.sin(2 * np.pi * 3.0 * t)
    fast = 0.05 * np.sin(2 * np.pi * 310.0 * t)  # at 100 Hz it would alias to 10 Hz
    session = session_of(np.array([slow + fast, slow]) + 0.2, rate)
    analysed = at_analysis_rate(session)
    assert session_rate(analysed) == pytest.approx(100.0)
    np.testing.assert_array_equal(analysed.times, session.times[::10])
    inner = slice(50, -50)  # the filter's ends
    expected = slow[::10] + 0.2
    np.testing.assert_allclose(analysed.positions[0, inner], expected[inner], atol=1e-3)
    np.testing.assert_allclose(analysed.positions[1, inner], expected[inner], atol=1e-3)
    np.testing.assert_array_equal(analysed.controls, session.controls[:, ::10])
    assert analysed.labels == session.labels and analysed.roles == session.roles
