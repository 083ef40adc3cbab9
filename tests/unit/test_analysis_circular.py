"""Circular statistics of angle measures: checked against scipy, an exact null by simulation,
a slow enumeration of sign flips, and simulated studies whose directions wrap at +-pi."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy import optimize, stats

from mirror_avatar.analysis.circular import (
    DIRECTION_TEST,
    EXACT_PARTICIPANTS,
    circular_contrasts,
    circular_mean,
    circular_sd,
    circular_summaries,
    paired_direction_test,
    rayleigh_test,
    resultant_length,
    sign_flip_p,
    wrapped,
)

ANGLES = np.array([3.0, -3.1, 2.9, 3.05, -2.95, 2.5, -2.7])


def test_mean_length_and_sd_equal_scipys() -> None:
    rng = np.random.default_rng(0)
    for angles in (ANGLES, rng.vonmises(1.0, 2.0, 50), rng.uniform(-np.pi, np.pi, 9)):
        assert circular_mean(angles) == pytest.approx(
            stats.circmean(angles, high=np.pi, low=-np.pi) - 2 * np.pi * (
                stats.circmean(angles, high=np.pi, low=-np.pi) > np.pi - 1e-15), abs=1e-12
        )  # fmt: skip
        vectors = np.column_stack([np.cos(angles), np.sin(angles)])
        found = stats.directional_stats(vectors)
        assert resultant_length(angles) == pytest.approx(found.mean_resultant_length, rel=1e-12)
        assert circular_sd(resultant_length(angles)) == pytest.approx(
            stats.circstd(angles, high=np.pi, low=-np.pi), rel=1e-12
        )
    # Around +-pi the arithmetic mean (-0.04) points the opposite way; the circular mean does not.
    assert abs(circular_mean(ANGLES)) > 3.0
    assert math.isnan(circular_mean([0.0, np.pi])) and math.isnan(circular_mean([]))


def test_rayleigh_p_is_the_tail_of_uniform_angles_by_simulation() -> None:
    """Angles spread evenly over an arc sized for Zar's p = 0.05 or 0.01, at n = 6, 10 and 20;
    the exact null of R for n uniform angles by 400000 simulated samples (Monte Carlo SE at
    most 0.0004): Zar's p within 0.003 of its tail."""
    rng = np.random.default_rng(1)
    for n in (6, 10, 20):
        null = rng.uniform(-np.pi, np.pi, (400_000, n))
        lengths = np.hypot(np.sin(null).mean(axis=1), np.cos(null).mean(axis=1))
        for target in (0.05, 0.01):
            arc = optimize.brentq(
                lambda a, n=n, t=target: rayleigh_test(np.linspace(-a, a, n)).p - t, 0.1, np.pi
            )
            angles = np.linspace(-arc, arc, n)
            found = rayleigh_test(angles)
            tail = float(np.mean(lengths >= resultant_length(angles)))
            assert found.z == pytest.approx(n * resultant_length(angles) ** 2, rel=1e-12)
            assert found.p == pytest.approx(tail, abs=0.003)
    assert math.isnan(rayleigh_test([1.0]).p)


def slow_sign_flip_p(differences: np.ndarray, alternative: str = "two-sided") -> float:
    """Every sign flip enumerated one by one, by the bits of its number."""
    statistic = {"two-sided": abs, "greater": lambda s: s, "less": lambda s: -s}[alternative]
    n = differences.size
    observed = statistic(sum(math.sin(d) for d in differences))
    count = 0
    for number in range(2**n):
        flipped = sum(math.sin(d) * (-1 if number >> i & 1 else 1) for i, d in
                      enumerate(differences))  # fmt: skip
        count += statistic(flipped) >= observed - 1e-12
    return count / 2**n


def test_one_sided_sign_flips_of_three_later_directions() -> None:
    # three differences all later in the cycle: of the 8 flips only the observed one reaches
    # its sum (1/8); either sign of it, two of 8 (2/8); none is earlier, all 8 reach (8/8)
    sines = np.sin(np.array([[0.2, 0.5, 0.9]]))
    rng = np.random.default_rng(0)
    assert sign_flip_p(sines, "greater", rng)[0] == pytest.approx(1 / 8)
    assert sign_flip_p(sines, "two-sided", rng)[0] == pytest.approx(2 / 8)
    assert sign_flip_p(sines, "less", rng)[0] == pytest.approx(1.0)


@pytest.mark.parametrize("alternative", ["greater", "less", "two-sided"])
def test_sign_flip_p_of_many_samples_equals_each_enumerated(alternative: str) -> None:
    rng = np.random.default_rng(4)
    differences = wrapped(rng.normal(0.2, 0.8, size=(3, 5, 8)))
    found = sign_flip_p(np.sin(differences), alternative, rng)
    assert found.shape == (3, 5)
    for index in np.ndindex(3, 5):
        expected = slow_sign_flip_p(differences[index], alternative)
        assert found[index] == pytest.approx(expected, abs=1e-12)


def test_sign_flip_p_equals_a_slow_enumeration_and_draws_come_close() -> None:
    rng = np.random.default_rng(2)
    reference = rng.uniform(-np.pi, np.pi, 10)
    condition = reference + 0.3 + rng.normal(0, 0.5, 10)
    found = paired_direction_test(reference, condition)
    assert found.exact
    assert found.p == pytest.approx(slow_sign_flip_p(wrapped(condition - reference)), abs=1e-12)
    many = EXACT_PARTICIPANTS + 2
    reference = rng.uniform(-np.pi, np.pi, many)
    condition = reference + 0.2 + rng.normal(0, 0.6, many)
    drawn = paired_direction_test(reference, condition, seed=3)
    assert not drawn.exact
    exact = slow_sign_flip_p(wrapped(condition - reference))
    assert drawn.p == pytest.approx(exact, abs=0.015)  # 9999 draws: SE at most 0.005


def test_no_shift_is_seldom_found_and_a_shift_across_pi_is_found() -> None:
    """12 participants, directions near pi (von Mises, kappa 8) in both conditions: p < 0.05
    in at most 10 of 100 seeds; the condition 0.5 rad later, wrapping past pi: found in 80 of
    100 or more, with the difference within 0.1 rad of 0.5 on average."""
    false, found, differences = 0, 0, []
    for seed in range(100):
        rng = np.random.default_rng(seed)
        own = np.pi + rng.normal(0, 0.3, 12)
        reference = wrapped(own + rng.vonmises(0.0, 8.0, 12))
        same = wrapped(own + rng.vonmises(0.0, 8.0, 12))
        later = wrapped(own + 0.5 + rng.vonmises(0.0, 8.0, 12))
        false += paired_direction_test(reference, same).p < 0.05
        shifted = paired_direction_test(reference, later)
        found += shifted.p < 0.05 and shifted.difference > 0
        differences.append(shifted.difference)
    assert false <= 10 and found >= 80
    assert np.mean(differences) == pytest.approx(0.5, abs=0.1)


def angle_rows(seed: int, shift: float) -> pd.DataFrame:
    """Trials of 12 participants in two conditions, mean relative phase near pi."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(12):
        own = np.pi + rng.normal(0, 0.3)
        for condition, moved in (("near", 0.0), ("far", shift)):
            for trial in range(3):
                rows.append(
                    {
                        "participant": f"p{i:02d}",
                        "condition": condition,
                        "trial": trial,
                        "mean_relative_phase": float(wrapped(own + moved + rng.vonmises(0.0, 4.0))),
                    }
                )
    return pd.DataFrame(rows)


def test_contrasts_and_summaries_of_an_angle_measure() -> None:
    rows = angle_rows(5, shift=0.6)
    model = circular_contrasts(rows, "mean_relative_phase", ["near", "far"], "near")
    assert model is not None and model.fixed_effects == DIRECTION_TEST and model.converged
    (contrast,) = model.contrasts
    assert contrast.p < 0.01 and contrast.difference == pytest.approx(0.6, abs=0.2)
    # The arithmetic difference of the same means is far from 0.6: the angles wrap at +-pi.
    means = rows.groupby("condition")["mean_relative_phase"].mean()
    assert abs(means["far"] - means["near"] - 0.6) > 1.0
    near, far = circular_summaries(rows, "mean_relative_phase", ["near", "far"])
    assert near["participants"] == far["participants"] == 12
    assert abs(near["mean"]) > 2.8 and near["rayleigh_p"] < 0.001
    assert near["resultant_length"] == pytest.approx(
        resultant_length(rows[rows["condition"] == "near"].groupby("participant")[
            "mean_relative_phase"].agg(circular_mean)), rel=1e-12
    )  # fmt: skip
    assert contrast.reference_mean == pytest.approx(near["mean"], abs=1e-12)
    assert circular_contrasts(rows[rows["condition"] == "near"], "mean_relative_phase",
                              ["near", "far"], "near") is None  # fmt: skip
