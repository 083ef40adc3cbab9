"""Co-confidence segments and the jitter index: a smooth pair with 2.5 Hz jitter in known places."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from mirror_avatar.metrics.co_confidence import (
    find_co_confidence,
    relative_velocity_difference,
    timing_gap,
    zero_velocity_times,
)
from mirror_avatar.metrics.jitter import jitter_episodes, jitter_index, jitter_value
from mirror_avatar.metrics.runs import find_runs, keep_long_runs
from mirror_avatar.testing import smooth_motion

RATE = 100.0
JITTERED = ((6.0, 11.0), (17.0, 21.0))
"""Intervals (s) in which player 1 jitters; CC is everywhere else in the 30 s."""


def jittered_pair(rng: np.random.Generator, amplitude: float) -> tuple[np.ndarray, np.ndarray]:
    """Velocities of two players moving together, player 1 with 2.5 Hz jitter in `JITTERED`.

    The motion never rests (two slow sines), so every sample outside `JITTERED` is CC.
    """
    t = np.arange(3000) / RATE
    phase = rng.uniform(0, 2 * np.pi, 2)
    x = 0.25 * np.sin(2 * np.pi * 0.45 * t + phase[0]) + 0.1 * np.sin(
        2 * np.pi * 0.23 * t + phase[1]
    )
    on = np.zeros(t.size, dtype=bool)
    for start, end in JITTERED:
        on |= (t >= start) & (t < end)
    x1 = x + amplitude * np.sin(2 * np.pi * 2.5 * t) * on
    return np.gradient(x, 1 / RATE), np.gradient(x1, 1 / RATE)


@pytest.mark.parametrize(("seed", "amplitude"), [(0, 0.01), (1, 0.02), (2, 0.006), (3, 0.04)])
def test_cc_segments_are_found_where_they_were_made(seed, amplitude):
    v0, v1 = jittered_pair(np.random.default_rng(seed), amplitude)
    cc = find_co_confidence(v0, v1, RATE)
    expected = [(0.0, 6.0), (11.0, 17.0), (21.0, 30.0)]
    assert len(cc.segments) == len(expected)
    for segment, (start, end) in zip(cc.segments, expected, strict=True):
        assert segment.start == pytest.approx(start, abs=0.2)
        assert segment.end == pytest.approx(end, abs=0.2)
        assert segment.dv < 0.1 and segment.dt < 0.05
    assert cc.rate == pytest.approx(21 / 30, abs=0.02)
    assert cc.mean_length == pytest.approx(7.0, abs=0.2)


def test_the_jitter_index_peaks_on_the_jittered_player(rng):
    v0, v1 = jittered_pair(rng, 0.01)
    j0, j1 = jitter_index(v0, RATE), jitter_index(v1, RATE)
    t = np.arange(v0.size) / RATE
    for start, end in JITTERED:
        inside = (t >= start + 0.5) & (t < end - 0.5)
        assert start <= t[inside][np.argmax(j1[inside])] <= end
        assert np.min(j1[inside]) > 5 * np.max(j0[inside])
    assert start <= t[np.argmax(j1)] <= end or JITTERED[0][0] <= t[np.argmax(j1)] <= JITTERED[0][1]
    assert jitter_value(v1, RATE) > 10 * jitter_value(v0, RATE)


def test_jitter_value_of_two_tones_by_hand_and_by_welch():
    """v = a sin(2 pi 0.5 t) + b sin(2 pi 2.45 t): the 2-3 Hz share of the RMS is b / |(a, b)|."""
    t = np.arange(20000) / RATE
    a, b = 1.0, 0.3
    v = a * np.sin(2 * np.pi * 0.5 * t) + b * np.sin(2 * np.pi * 2.45 * t)
    assert jitter_value(v, RATE) == pytest.approx(b / np.hypot(a, b), rel=0.01)
    f, power = signal.welch(v, fs=RATE, nperseg=4000, window="boxcar")
    band = (f >= 2.0) & (f <= 3.0)
    assert jitter_value(v, RATE) ** 2 == pytest.approx(power[band].sum() / power.sum(), rel=0.02)


def test_jitter_index_of_a_pure_tone_is_one_inside():
    t = np.arange(3000) / RATE
    index = jitter_index(0.4 * np.sin(2 * np.pi * 2.45 * t), RATE)
    assert np.median(index[500:-500]) == pytest.approx(1.0, abs=0.01)


def test_jitter_episode_edges_at_half_the_peak():
    index = np.array([0, 0.1, 0.3, 0.6, 1.0, 0.9, 0.45, 0.2, 0, 0.2, 0.4, 0.1])
    np.testing.assert_array_equal(
        np.flatnonzero(jitter_episodes(index, threshold=0.35)), [3, 4, 5, 9, 10]
    )


def test_relative_velocity_difference_by_hand():
    dv = relative_velocity_difference(np.ones(50), np.full(50, 0.5), RATE, 0.1)
    np.testing.assert_allclose(dv, 0.5 / 0.75)
    assert np.all(np.isinf(relative_velocity_difference(np.zeros(5), np.zeros(5), RATE, 0.1)))


def test_zero_velocity_events_and_timing_gap_by_hand():
    t = np.arange(1000) / RATE
    events = zero_velocity_times(np.cos(2 * np.pi * 0.5 * t), RATE)
    np.testing.assert_allclose(
        events, [0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.5, 7.5, 8.5, 9.5], atol=1e-4
    )
    gap = timing_gap(np.array([1.0, 2.0, 3.0, 12.0]), np.array([1.1, 2.3]), 0.0, 10.0)
    assert gap == pytest.approx((0.1 + 0.3 + 0.7) / 3)
    assert np.isnan(timing_gap(np.array([20.0]), np.array([1.0]), 0.0, 10.0))


def test_timing_gap_equals_the_gap_to_every_event_of_the_other():
    rng = np.random.default_rng(3)
    for size in (1, 2, 3, 50):
        events0 = np.sort(rng.uniform(0, 60, 80))
        events1 = np.sort(rng.uniform(0, 60, size))
        own = events0[(events0 >= 5.0) & (events0 <= 40.0)]
        every = np.abs(own[:, None] - events1[None, :]).min(axis=1).mean()
        assert timing_gap(events0, events1, 5.0, 40.0) == pytest.approx(every, rel=1e-15)


def test_runs_by_hand():
    mask = np.array([1, 1, 0, 1, 0, 0, 1, 1, 1], dtype=bool)
    np.testing.assert_array_equal(find_runs(mask), [[0, 2], [3, 4], [6, 9]])
    np.testing.assert_array_equal(keep_long_runs(mask, 2), [1, 1, 0, 0, 0, 0, 1, 1, 1])
    assert find_runs(np.zeros(3, dtype=bool)).shape == (0, 2)


def test_pairs_at_rest_or_apart_have_no_cc(rng):
    assert find_co_confidence(np.zeros(1000), np.zeros(1000), RATE).segments == ()
    v0 = np.gradient(smooth_motion(rng, 3000, RATE), 1 / RATE)
    v1 = np.gradient(smooth_motion(rng, 3000, RATE), 1 / RATE)
    assert find_co_confidence(v0, v1, RATE).rate < 0.1
