"""Windowed lagged cross-correlation and peak picking: a known leader whose role swaps halfway."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal, stats

from mirror_avatar.common.errors import InputError
from mirror_avatar.metrics.leadership import (
    compute_leadership,
    pick_peaks,
    windowed_cross_correlation,
)
from mirror_avatar.testing import smooth_motion, swapped_roles

RATE = 50.0


@pytest.mark.parametrize("delay", [5, 10, 17])
def test_the_right_leader_in_windows_away_from_the_swap(rng, delay):
    n = 3000
    x0, x1 = swapped_roles(rng, n, delay, RATE)
    v0, v1 = np.gradient(x0) * RATE, np.gradient(x1) * RATE
    lead = compute_leadership(v0, v1, RATE)
    swap = n / 2 / RATE
    away = np.abs(lead.times - swap) > 4.0 / 2 + 1.0  # half a window plus the largest lag
    leaders = lead.leaders(RATE)
    before, after = away & (lead.times < swap), away & (lead.times > swap)
    assert np.mean(leaders[before] == 0) >= 0.95
    assert np.mean(leaders[after] == 1) >= 0.95
    right = np.where(lead.times < swap, 1.0, -1.0) * delay / RATE
    assert np.all(np.abs(lead.peak_lags[away] - right[away]) <= 1.0 / RATE + 1e-12)
    assert lead.leader(RATE) == (None, pytest.approx(0.5, abs=0.05))


def test_a_constant_leader_leads_the_session(rng):
    s = smooth_motion(rng, 2010, RATE)
    lead = compute_leadership(s[10:], s[:-10], RATE)
    leader, share = lead.leader(RATE)
    assert leader == 0 and share == 1.0
    assert lead.leader_lag(0, RATE) == pytest.approx(10 / RATE)


def test_window_correlations_are_pearson_correlations(rng):
    """Every cell against scipy.stats.pearsonr of the two windows it names."""
    a, b = rng.normal(size=400), rng.normal(size=400)
    times, lags, corr = windowed_cross_correlation(a, b, 10.0, window=5.0, step=2.0, max_lag=1.0)
    w, m = 50, 10
    starts = np.round(times * 10.0 - w / 2).astype(int)
    assert starts[0] == m and np.all(np.diff(starts) == 20)
    for i, start in enumerate(starts):
        for j, lag in enumerate(np.round(lags * 10.0).astype(int)):
            expected = stats.pearsonr(a[start : start + w], b[start + lag : start + lag + w])
            assert corr[i, j] == pytest.approx(expected.statistic, abs=1e-9)


def test_peak_picking_takes_the_local_maximum_nearest_lag_zero():
    lags = np.array([-3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0])
    rows = np.array(
        [
            [0.0, 0.9, 0.1, 0.2, 0.7, 0.1, 0.0],  # peaks at -2 (0.9) and +1 (0.7): +1 is nearer
            [0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.95],  # maxima only at the ends: no peak
            [0.0, 0.1, 0.3, 0.4, 0.3, 0.1, 0.0],  # a peak below the threshold
        ]
    )
    peak_lags, peak_values = pick_peaks(lags, rows, min_peak=0.5)
    np.testing.assert_array_equal(peak_lags, [1.0, np.nan, np.nan])
    np.testing.assert_array_equal(peak_values, [0.7, np.nan, np.nan])


def test_peaks_agree_with_scipy_find_peaks(rng):
    lags = np.linspace(-1, 1, 41)
    rows = signal.sosfiltfilt(signal.butter(2, 0.2, output="sos"), rng.normal(size=(200, 41)))
    peak_lags, _ = pick_peaks(lags, rows, min_peak=0.0)
    for row, got in zip(rows, peak_lags, strict=True):
        found, _ = signal.find_peaks(row, height=0.0)
        expected = lags[found[np.argmin(np.abs(lags[found]))]] if found.size else np.nan
        np.testing.assert_equal(got, expected)


def test_too_short_series_are_refused():
    with pytest.raises(InputError, match="window"):
        compute_leadership(np.zeros(100), np.zeros(100), RATE)
