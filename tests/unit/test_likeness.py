"""The human-likeness battery: permutation tests, distances and the classifier test."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.stats

from mirror_avatar.common.errors import InputError
from mirror_avatar.signatures.likeness import (
    amplitude_distances,
    classifier_test,
    compare_distances,
    ims_distances,
    spectrum_distances,
    stroke_amplitudes,
)
from mirror_avatar.signatures.permutations import between_and_within, permutation_test
from mirror_avatar.signatures.signature import compute_emd, compute_ims

RATE = 100.0


def _sine_velocity(amplitude: float, frequency: float, seconds: float = 60.0) -> np.ndarray:
    """Velocity (units/s) of the position ``amplitude * sin(2 pi f t)``."""
    t = np.arange(round(seconds * RATE)) / RATE
    return amplitude * 2 * np.pi * frequency * np.cos(2 * np.pi * frequency * t)


def test_exact_permutation_p_value_by_hand() -> None:
    values = np.array([1.0, 2.0, 3.0, 4.0])
    test = permutation_test(lambda side: values[side].mean() - values[~side].mean(), [0, 0, 1, 1])
    # six ways to choose two of four; only {3, 4} gives a difference as large as 2
    assert test.exact
    assert test.statistic == pytest.approx(2.0)
    assert test.p_value == pytest.approx(1 / 6)


def test_permutation_p_value_matches_scipy(rng: np.random.Generator) -> None:
    a, b = rng.normal(0.0, 1.0, 6), rng.normal(0.8, 1.0, 5)
    values = np.concatenate([a, b])
    labels = np.arange(11) >= 6
    ours = permutation_test(lambda side: values[side].mean() - values[~side].mean(), labels, 500)
    theirs = scipy.stats.permutation_test(
        (b, a),
        lambda x, y: np.mean(x) - np.mean(y),
        permutation_type="independent",
        alternative="greater",
        n_resamples=500,
    )
    assert ours.exact  # 11 choose 5 = 462 relabellings, all tried
    assert ours.p_value == pytest.approx(theirs.pvalue)


def test_random_permutation_p_value_counts_the_observed() -> None:
    values = np.arange(40.0)
    test = permutation_test(lambda side: values[side].mean(), values >= 20, 99, seed=3)
    assert not test.exact
    assert test.p_value == pytest.approx((1 + np.sum(test.null >= test.statistic)) / 100)
    assert test.p_value == pytest.approx(0.01)


def test_one_sided_labels_are_refused() -> None:
    with pytest.raises(InputError, match="both sides"):
        permutation_test(lambda side: 0.0, [1, 1, 1])


def test_between_and_within_by_hand() -> None:
    d = np.array([[0, 1, 4, 5], [1, 0, 6, 7], [4, 6, 0, 2], [5, 7, 2, 0]], dtype=float)
    between, within = between_and_within(d, np.array([False, False, True, True]))
    assert between == pytest.approx((4 + 5 + 6 + 7) / 4)
    assert within == pytest.approx((1 + 2) / 2)


def test_ims_distances_are_the_signature_emd(rng: np.random.Generator) -> None:
    signals = [rng.normal(0, s, 3000) for s in (0.3, 0.5, 0.9)]
    d = ims_distances(signals)
    assert d[0, 2] == pytest.approx(compute_emd(compute_ims(signals[0]), compute_ims(signals[2])))


def test_stroke_amplitude_of_a_sine_is_twice_its_amplitude() -> None:
    amplitudes = stroke_amplitudes(_sine_velocity(0.2, 0.5), RATE)
    assert amplitudes.size == 59  # 60 reversals in 60 s, the first and last strokes incomplete
    np.testing.assert_allclose(amplitudes, 0.4, rtol=2e-3)


def test_amplitude_and_spectrum_distances_of_sines() -> None:
    signals = [_sine_velocity(0.2, 1.0), _sine_velocity(0.3, 1.0), _sine_velocity(0.2, 2.0)]
    amplitude = amplitude_distances(signals, RATE)
    spectrum = spectrum_distances(signals, RATE)
    assert amplitude[0, 1] == pytest.approx(0.2, rel=5e-3)  # strokes of 0.4 and 0.6 units
    assert spectrum[0, 1] == pytest.approx(0.0, abs=1e-9)  # same frequency
    assert spectrum[0, 2] == pytest.approx(1.0, abs=0.02)  # power moved from 1 Hz to 2 Hz


def test_distance_ratio_is_to_the_persons_own(rng: np.random.Generator) -> None:
    person = [rng.normal(0, 0.5, 6000) for _ in range(4)]
    other = [rng.normal(0, 1.0, 6000) for _ in range(4)]
    emd = next(d for d in compare_distances(person, other) if d.measure == "velocity IMS EMD")
    cross = [compute_emd(compute_ims(a), compute_ims(b)) for a in other for b in person]
    own = [
        compute_emd(compute_ims(a), compute_ims(b)) for a, b in itertools.combinations(person, 2)
    ]
    assert emd.to_reference == pytest.approx(np.mean(cross))
    assert emd.ratio == pytest.approx(np.mean(cross) / np.mean(own))
    assert emd.distinguishable
    assert emd.verdict().startswith("distinguishable: velocity IMS EMD")


def test_classifier_cuts_a_single_trial_in_halves(rng: np.random.Generator) -> None:
    slow = [_sine_velocity(0.2, 0.3) + rng.normal(0, 0.02, 6000)]
    fast = [_sine_velocity(0.2, 1.5) + rng.normal(0, 0.02, 6000) for _ in range(3)]
    test = classifier_test(slow, fast)
    assert test.halves and test.n_reference == 2
    assert test.auc == pytest.approx(1.0)
    # two halves against three trials: ten relabellings, so p is at best 1/10
    assert test.test.exact and test.test.p_value == pytest.approx(0.1)
    assert test.verdict().startswith("indistinguishable at this data size: classifier AUC 1.00")


def test_a_distance_that_cannot_be_measured_says_so(rng: np.random.Generator) -> None:
    still = [np.full(3000, 0.2) for _ in range(3)]  # moving one way: no complete stroke
    moving = [_sine_velocity(0.2, 1.0, 30.0) + rng.normal(0, 0.01, 3000) for _ in range(3)]
    amplitude = next(d for d in compare_distances(moving, still) if d.measure == "amplitude")
    assert np.isnan(amplitude.test.p_value) and not amplitude.distinguishable
    assert amplitude.verdict().startswith("not measured: amplitude")


def test_classifier_groups_by_the_units_given(rng: np.random.Generator) -> None:
    slow = [_sine_velocity(0.2, 0.3, 20.0) + rng.normal(0, 0.02, 2000) for _ in range(4)]
    fast = [_sine_velocity(0.2, 1.5, 20.0) + rng.normal(0, 0.02, 2000) for _ in range(4)]
    people = ["p1", "p1", "p2", "p2", "q1", "q1", "q2", "q2"]
    test = classifier_test(slow, fast, units=people)
    assert (test.n_reference, test.n_candidate, test.folds) == (2, 2, 2)
    assert test.test.exact and test.test.null.size == 6  # 4 people choose 2
    with pytest.raises(InputError, match="both sides"):
        classifier_test(slow, fast, units=["p1"] * 5 + ["q1"] * 3)


def test_trials_too_short_for_the_classifier_are_judged_by_the_distances_alone():
    from mirror_avatar.datasets import load_zhai2017
    from mirror_avatar.signatures.likeness import compare_motion, trial_velocity

    rate = 1 / 0.03
    short = [trial_velocity(t, rate)[: round(8 * rate)] for t in load_zhai2017()[:4]]
    result = compare_motion(short[3:], short[:2], short, rate, n_permutations=19, seed=0)
    assert result.classifier is None
    assert result.verdict().startswith("not measured: classifier")
    assert "classifier AUC (0.5 = chance)" not in result.table().index
    assert result.to_json_dict()["classifier"] is None
