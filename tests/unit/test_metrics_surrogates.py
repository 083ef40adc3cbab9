"""Chance levels: p-values by hand, the weak-null test against multiSyncPy, and 100 seeded pairs."""

from __future__ import annotations

import numpy as np
import pytest
from multiSyncPy import synchrony_metrics
from scipy import stats

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import spawn_seeds
from mirror_avatar.metrics.measures import (
    MeasureOptions,
    coordination_statistics,
)
from mirror_avatar.metrics.registry import measures_tested
from mirror_avatar.metrics.surrogates import (
    kuramoto_weak_null,
    p_value,
    pseudo_session,
    shift_offsets,
    shifted,
)
from mirror_avatar.metrics.synchrony_episodes import find_synchrony_episodes
from mirror_avatar.testing import smooth_motion

RATE = 25.0
N_SAMPLES = 500
N_SURROGATES = 39
"""A small null (p down to 0.025) keeps 100 pairs quick; evaluate's default is 99."""


def test_p_values_by_hand():
    null = np.array([0.1, 0.5, 0.9, np.nan])
    assert p_value(0.6, null) == pytest.approx(2 / 4)
    assert p_value(1.0, null) == pytest.approx(1 / 4)
    assert p_value(0.5, null) == pytest.approx(3 / 4)  # ties count against the measure
    assert p_value(0.05, null, greater=False) == pytest.approx(1 / 4)
    assert np.isnan(p_value(np.nan, null)) and np.isnan(p_value(1.0, [np.nan]))


def test_circular_shifts_keep_player_0_and_stay_away_from_the_ends(rng):
    offsets = shift_offsets(100, 3, 500, 20, rng)
    assert np.all(offsets[:, 0] == 0)
    assert offsets[:, 1:].min() >= 20 and offsets[:, 1:].max() <= 80
    series = np.arange(30.0).reshape(3, 10)
    np.testing.assert_array_equal(shifted(series, [0, 2, 9])[1], np.roll(series[1], 2))
    with pytest.raises(InputError, match="min-shift"):
        shift_offsets(30, 2, 5, 15, rng)


def test_pseudo_sessions_take_player_0_from_one_and_partners_from_another():
    own, other = np.zeros((3, 8)), np.ones((3, 6))
    got = pseudo_session(own, other)
    assert got.shape == (3, 6)
    np.testing.assert_array_equal(got[0], 0.0)
    np.testing.assert_array_equal(got[1:], 1.0)


def test_weak_null_against_multisyncpy_and_scipy(rng):
    """The same t-test as multiSyncPy's kuramoto_weak_null, which divides by the population SD."""
    common = rng.uniform(0, 2 * np.pi, size=(1, 300))
    sample = [common + rng.normal(0, s, size=(4, 300)) for s in (0.5, 1.0, 2.0, 3.0, 4.0)]
    ours = kuramoto_weak_null(sample)
    p, t, df = synchrony_metrics.kuramoto_weak_null(sample)
    r = len(sample)
    assert ours.df == df
    assert ours.t * np.sqrt(r / (r - 1)) == pytest.approx(t, rel=1e-12)
    assert ours.p == pytest.approx(stats.t.sf(ours.t, df), rel=1e-12)
    assert p == pytest.approx(stats.t.sf(t, df), rel=1e-12)
    assert ours.chance == 0.25 and ours.mean_r2 > 0.25


def test_weak_null_of_independent_groups_is_not_significant(rng):
    sample = [rng.uniform(0, 2 * np.pi, size=(3, 400)) for _ in range(8)]
    result = kuramoto_weak_null(sample)
    assert result.p > 0.05 and result.mean_r2 == pytest.approx(1 / 3, abs=0.02)
    with pytest.raises(InputError, match="two or more"):
        kuramoto_weak_null(sample[:1])


def test_synchrony_episodes_against_a_loop():
    """Locked (dphi = 0.3) for 4 s, drifting 4 s, locked again: one entry, one exit, and the
    windowed locking of every sample as a loop over its window computes it."""
    t = np.arange(1200) / 100.0
    dphi = np.where((t >= 4) & (t < 8), 2 * np.pi * 1.0 * t, 0.3)
    episodes = find_synchrony_episodes(dphi, 100.0, window=1.0, threshold=0.9)
    padded = np.concatenate((np.full(50, dphi[0]), dphi, np.full(49, dphi[-1])))
    loop = [abs(np.mean(np.exp(1j * padded[i : i + 100]))) for i in range(dphi.size)]
    np.testing.assert_allclose(episodes.locking, loop, atol=1e-12)
    assert episodes.entries == 1 and episodes.exits == 1
    (start0, end0), (start1, end1) = episodes.episodes
    assert start0 == 0.0 and 3.5 < end0 < 4.0 and 8.0 < start1 < 8.5 and end1 == 12.0
    assert episodes.mean_dwell == pytest.approx((end0 + end1 - start1) / 2)
    assert episodes.mean_gap == pytest.approx(start1 - end0)


def pair_p_values(x: np.ndarray, options: MeasureOptions, seed: int) -> dict[str, float]:
    """p-values of the tested measures of one pair of positions (shape (2, n))."""
    v = np.gradient(x, 1 / RATE, axis=1)
    observed = coordination_statistics(x, v, RATE, options)
    rng = np.random.default_rng(seed)
    offsets = shift_offsets(x.shape[1], 2, N_SURROGATES, round(options.min_shift * RATE), rng)
    draws = [coordination_statistics(shifted(x, k), shifted(v, k), RATE, options) for k in offsets]
    return {
        name: p_value(observed[name], [d[name] for d in draws], greater)
        for name, greater in measures_tested(2).items()
    }


@pytest.mark.long
@pytest.mark.parametrize(
    ("n_pairs", "most"),
    [(30, 5), pytest.param(100, 10, marks=pytest.mark.slow)],
)
def test_independent_pairs_rarely_beat_their_surrogates_and_coupled_pairs_always_do(n_pairs, most):
    """Seeded pairs: independent, at most ``most`` significant per measure (5 % of the pairs and
    a binomial margin: P(X > most) < 0.02); coupled (player 1 repeats player 0 40 ms later,
    with a little noise), every measure in every pair, except the transfer entropy from the
    follower to the leader, which has nothing to transfer."""
    options = MeasureOptions(lead_window=3.0, min_shift=2.0)
    significant = dict.fromkeys(measures_tested(2), 0)
    for seed in spawn_seeds(2026, n_pairs):
        rng = np.random.default_rng(int(seed))
        x = np.array([smooth_motion(rng, N_SAMPLES, RATE), smooth_motion(rng, N_SAMPLES, RATE)])
        for name, p in pair_p_values(x, options, int(seed)).items():
            significant[name] += p < 0.05
    assert stats.binom.sf(most, n_pairs, 0.05) < 0.02
    assert max(significant.values()) <= most, significant
    for seed in spawn_seeds(2027, n_pairs // 3):
        rng = np.random.default_rng(int(seed))
        s = smooth_motion(rng, N_SAMPLES + 1, RATE)
        x = np.array([s[1:], s[:-1] + rng.normal(0, 0.01 * s.std(), N_SAMPLES)])
        p = pair_p_values(x, options, int(seed))
        follower_to_leader = p.pop("transfer_entropy_1_to_0")
        assert all(value < 0.05 for value in p.values()), p
        assert follower_to_leader >= 0.05
