"""Why the battery tells two sets apart: the groups and features it names, against known truth."""

import numpy as np
import pytest
import scipy.signal

from mirror_avatar.signatures.likeness import (
    FEATURE_GROUPS,
    FEATURE_NAMES,
    classifier_test,
    compare_motion,
    window_features,
)
from mirror_avatar.signatures.separation import GROUP_AUC, Separation, feature_shifts

RATE = 100.0
N = 3000


def smooth_motion(rng: np.random.Generator, scale: float = 5.0) -> np.ndarray:
    """Velocity with its power below about 1 Hz, as a hand's in the mirror game."""
    b, a = scipy.signal.butter(2, 1.0, fs=RATE)
    return scipy.signal.filtfilt(b, a, rng.normal(size=N)) * scale


def sets(change, seed: int = 1) -> tuple[list[np.ndarray], list[np.ndarray]]:
    rng = np.random.default_rng(seed)
    reference = [smooth_motion(rng) for _ in range(6)]
    candidate = [change(smooth_motion(rng)) for _ in range(6)]
    return reference, candidate


def test_every_feature_has_words_and_one_group():
    columns = window_features(np.random.default_rng(0).normal(size=N), RATE).shape[1]
    assert len(FEATURE_NAMES) == columns
    grouped = sorted(c for group in FEATURE_GROUPS.values() for c in group)
    assert grouped == list(range(columns))


def test_a_ripple_is_named_as_the_spectrum_and_its_band():
    ripple = 0.05 * np.sin(2 * np.pi * 4.0 * np.arange(N) / RATE)
    reference, candidate = sets(lambda v: v + ripple)
    test = classifier_test(reference, candidate, RATE, n_permutations=50, seed=0)
    assert test.distinguishable
    assert test.separation.separating_groups[0] == "spectrum"
    top = test.separation.shifts[0]
    assert top.feature == "share of velocity power in 3-5 Hz"
    assert top.standardised_difference > 0
    assert top.candidate_median > 10 * top.reference_median
    assert "told apart by spectrum" in test.verdict()
    assert "higher share of velocity power in 3-5 Hz" in test.verdict()


def test_a_larger_motion_is_named_by_its_amplitude_and_speed():
    reference, candidate = sets(lambda v: 2.0 * v)
    test = classifier_test(reference, candidate, RATE, n_permutations=50, seed=0)
    separating = test.separation.separating_groups
    assert "amplitude" in separating and "velocity distribution" in separating
    assert "spectrum" not in separating  # the same shape of spectrum, only twice the size
    assert all(shift.standardised_difference > 0 for shift in test.separation.shifts)


def test_an_indistinguishable_verdict_gives_no_reason_but_the_json_keeps_the_numbers():
    reference, candidate = sets(lambda v: v)
    likeness = compare_motion(reference, candidate, rate=RATE, n_permutations=50, seed=0)
    assert likeness.classifier is not None and not likeness.classifier.distinguishable
    assert "told apart" not in likeness.verdict()
    separation = likeness.to_json_dict()["classifier"]["separation"]
    assert set(separation["group_auc"]) == set(FEATURE_GROUPS)
    assert all(auc < GROUP_AUC for auc in separation["group_auc"].values())
    assert separation["separating_groups"] == []


def test_shifts_are_standardised_differences_against_a_hand_computation():
    rng = np.random.default_rng(3)
    reference = rng.normal(0.0, 2.0, size=(200, 3))
    candidate = rng.normal([0.0, 1.0, -3.0], 2.0, size=(100, 3))
    features = np.vstack([reference, candidate])
    is_candidate = np.r_[np.zeros(200, bool), np.ones(100, bool)]
    shifts = feature_shifts(features, is_candidate, ["a", "b", "c"])
    pooled_c = np.sqrt((reference[:, 2].var() * 200 + candidate[:, 2].var() * 100) / 300)
    expected_c = (candidate[:, 2].mean() - reference[:, 2].mean()) / pooled_c
    assert [s.feature for s in shifts[:2]] == ["c", "b"]
    assert shifts[0].standardised_difference == pytest.approx(expected_c, rel=1e-12)
    assert shifts[0].words().startswith("lower c (")


def test_a_constant_feature_is_never_named():
    features = np.column_stack([np.ones(10), np.r_[np.zeros(5), np.ones(5)]])
    shifts = feature_shifts(features, np.r_[np.zeros(5, bool), np.ones(5, bool)], ["k", "x"])
    assert [s.feature for s in shifts] == ["x"]


def test_words_without_a_separating_group_still_name_the_largest_shifts():
    separation = Separation(group_auc={"spectrum": 0.6}, shifts=())
    assert separation.words() == f"no group of features alone reaches AUC {GROUP_AUC:g}"
