"""Scoring "person or avatar?": rate against chance, d', criterion, confidence (issue 37).

The must-show: on scripted answers with known truth (48 answers, 75 % right), the rate, the
binomial p, d' and the criterion equal values computed by hand (math.comb and the standard
library's normal quantile, not scipy).
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from study_tables import scripted_answers

from mirror_avatar.analysis.identification import identify, scored_answers, signal_detection

Z = NormalDist().inv_cdf


def forty_eight_answers() -> pd.DataFrame:
    """24 person partners: 20 called "person" (hits), 4 "avatar" (misses); 24 avatar partners:
    8 called "person" (false alarms), 16 "avatar" (correct rejections). 36 of 48 right."""
    truth = ["person"] * 24 + ["avatar"] * 24
    guesses = ["person"] * 20 + ["avatar"] * 4 + ["person"] * 8 + ["avatar"] * 16
    right = [t == g for t, g in zip(truth, guesses, strict=True)]
    confidence = [0.8 if r else 0.4 for r in right]
    confidence[0], confidence[24] = 0.6, 0.2  # a right and a wrong answer moved, for ties
    return scripted_answers(truth, guesses, confidence)


def test_48_answers_75_percent_right_equal_the_hand_computation() -> None:
    found = identify(forty_eight_answers())
    assert found is not None
    # Rate: 36 right of 48.
    assert (found.answers, found.correct) == (48, 36)
    assert found.rate == 0.75
    # Exact two-sided binomial test against 1/2, symmetric: 2 P(X >= 36), X ~ Bin(48, 1/2).
    hand_p = 2 * sum(math.comb(48, k) for k in range(36, 49)) / 2**48
    assert hand_p == pytest.approx(0.000717270, rel=1e-6)
    assert found.binomial_p == pytest.approx(hand_p, rel=1e-9)
    # Hit rate H = 20/24 = 5/6, false-alarm rate F = 8/24 = 1/3, no rate 0 or 1: no correction.
    # d' = z(5/6) - z(1/3) = 0.967422 - (-0.430727) = 1.398149
    # c = -(z(5/6) + z(1/3)) / 2 = -(0.967422 - 0.430727) / 2 = -0.268347 (leans to "person")
    d = found.detection
    assert (d.hits, d.misses, d.false_alarms, d.correct_rejections) == (20, 4, 8, 16)
    assert not d.corrected
    assert d.hit_rate == pytest.approx(5 / 6) and d.false_alarm_rate == pytest.approx(1 / 3)
    assert d.d_prime == pytest.approx(Z(5 / 6) - Z(1 / 3), rel=1e-9)
    assert d.d_prime == pytest.approx(1.398149, abs=1e-6)
    assert d.criterion == pytest.approx(-(Z(5 / 6) + Z(1 / 3)) / 2, rel=1e-9)
    assert d.criterion == pytest.approx(-0.268347, abs=1e-6)


def test_rate_interval_is_clopper_pearson() -> None:
    found = identify(forty_eight_answers())
    assert found is not None
    # Clopper-Pearson limits: the Beta quantiles of the exact binomial interval.
    assert found.rate_ci_low == pytest.approx(stats.beta.ppf(0.025, 36, 13))
    assert found.rate_ci_high == pytest.approx(stats.beta.ppf(0.975, 37, 12))


def test_log_linear_correction_for_a_rate_of_one() -> None:
    """12 of 12 persons called "person" (H = 1), 3 of 12 avatars (F = 1/4): Hautus (1995) adds
    0.5 to hits and false alarms and 1 to each count: H = 12.5/13, F = 3.5/13."""
    d = signal_detection(hits=12, misses=0, false_alarms=3, correct_rejections=9)
    assert d.corrected
    assert (d.hit_rate, d.false_alarm_rate) == pytest.approx((12.5 / 13, 3.5 / 13))
    assert d.d_prime == pytest.approx(Z(12.5 / 13) - Z(3.5 / 13))
    assert d.d_prime == pytest.approx(2.383966, abs=1e-6)
    assert d.criterion == pytest.approx(-0.576842, abs=1e-6)
    zero = signal_detection(hits=5, misses=5, false_alarms=0, correct_rejections=10)
    assert zero.corrected and zero.false_alarm_rate == pytest.approx(0.5 / 11)


def test_signal_detection_without_one_kind_is_nan() -> None:
    d = signal_detection(hits=3, misses=1, false_alarms=0, correct_rejections=0)
    assert np.isnan(d.d_prime) and np.isnan(d.criterion)


def test_confidence_of_right_against_wrong_answers() -> None:
    answers = forty_eight_answers()
    found = identify(answers)
    assert found is not None
    right = answers.loc[answers["guess_correct"], "guess_confidence"]
    wrong = answers.loc[~answers["guess_correct"], "guess_confidence"]
    # 36 right: 35 at 0.8 and one at 0.6; 12 wrong: 11 at 0.4 and one at 0.2.
    assert found.confidence_right == pytest.approx((35 * 0.8 + 0.6) / 36)
    assert found.confidence_wrong == pytest.approx((11 * 0.4 + 0.2) / 12)
    assert (found.confidence_right_n, found.confidence_wrong_n) == (36, 12)
    direct = stats.mannwhitneyu(right, wrong, alternative="two-sided").pvalue
    assert found.confidence_p == pytest.approx(direct)
    assert found.confidence_p < 0.001


def test_per_person_scores_and_their_d_prime_test() -> None:
    answers = forty_eight_answers()
    found = identify(answers)
    assert found is not None
    assert found.persons == 3
    table = found.per_person
    assert int(table["answers"].sum()) == 48 and int(table["correct"].sum()) == 36
    for participant, group in answers.groupby("participant"):
        participant = f"{participant}/P1"
        hits = int(((group["partner_kind"] == "person") & (group["guess_kind"] == "person")).sum())
        persons = int((group["partner_kind"] == "person").sum())
        alarms = int(
            ((group["partner_kind"] == "avatar") & (group["guess_kind"] == "person")).sum()
        )
        avatars = int((group["partner_kind"] == "avatar").sum())
        own = signal_detection(hits, persons - hits, alarms, avatars - alarms)
        assert table.loc[participant, "d_prime"] == pytest.approx(own.d_prime)
    d_primes = table["d_prime"].astype(float).to_numpy()
    assert found.person_d_prime_mean == pytest.approx(d_primes.mean())
    assert found.person_d_prime_p == pytest.approx(stats.ttest_1samp(d_primes, 0).pvalue)


def test_the_persons_rates_are_tested_against_chance_as_computed_by_hand() -> None:
    """40 answers, answer i person i mod 3's, right at i = 18, 19, 38, 39: rates 2/14, 1/13 and
    1/13; t = (mean - 0.5) / (SD / sqrt(3)) on 2 df."""
    truth = ["person"] * 20 + ["avatar"] * 20
    guesses = ["avatar"] * 18 + ["person"] * 2 + ["person"] * 18 + ["avatar"] * 2
    answers = scripted_answers(truth, guesses, [np.nan] * 40)
    rates = [2 / 14, 1 / 13, 1 / 13]
    mean = sum(rates) / 3
    sd = math.sqrt(sum((r - mean) ** 2 for r in rates) / 2)
    t = (mean - 0.5) / (sd / math.sqrt(3))
    found = identify(answers)
    assert found is not None and found.over_persons
    assert found.person_rate_mean == pytest.approx(mean, rel=1e-12)
    # The two-sided p of t on 2 df in closed form: 1 - |t| / sqrt(t^2 + 2).
    assert found.person_rate_p == pytest.approx(1 - abs(t) / math.sqrt(t * t + 2), rel=1e-9)
    assert found.chance_test == (found.person_rate_mean, found.person_rate_p)


def persons_at_chance(seed: int, persons: int = 10, answers: int = 40) -> pd.DataFrame:
    """Persons each right at their own rate, drawn 0.2 or 0.8: at chance in the population."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(persons):
        own = rng.choice([0.2, 0.8])
        truth = rng.choice(["person", "avatar"], answers)
        right = rng.random(answers) < own
        guess = np.where(right, truth, np.where(truth == "person", "avatar", "person"))
        rows.append(pd.DataFrame({"participant": f"p{i:03d}", "person": "P1",
                                  "player_kind": "person", "condition": "c",
                                  "partner_kind": truth, "guess_kind": guess}))  # fmt: skip
    return pd.concat(rows, ignore_index=True)


def test_persons_at_chance_on_average_are_not_found_above_it_as_pooled_answers_are() -> None:
    """Persons whose own rates differ: the pooled binomial takes 400 answers as independent and
    rejects chance in 40 of 100 seeds or more; the t-test over the 10 persons in at most 10."""
    pooled, over_persons = 0, 0
    for seed in range(100):
        found = identify(persons_at_chance(seed))
        assert found is not None and found.over_persons
        pooled += found.binomial_p < 0.05
        over_persons += found.person_rate_p < 0.05
    assert over_persons <= 10
    assert pooled >= 40


def test_answers_about_mixed_partners_and_rows_without_answers_are_not_scored() -> None:
    answers = forty_eight_answers()
    mixed = answers.iloc[:2].assign(partner_kind="mixed")
    silent = answers.iloc[:3].assign(guess_kind=np.nan)
    found = identify(pd.concat([answers, mixed, silent]))
    assert found is not None
    assert found.answers == 48 and found.left_out == 2
    scored, left_out = scored_answers(pd.concat([mixed, silent]))
    assert scored.empty and left_out == 2
    assert identify(silent) is None


def test_answers_without_confidence_have_no_confidence_test() -> None:
    answers = forty_eight_answers().assign(guess_confidence=np.nan)
    found = identify(answers)
    assert found is not None
    assert np.isnan(found.confidence_right) and np.isnan(found.confidence_p)
    assert found.confidence_right_n == 0


def test_per_condition_rates_of_a_three_arm_design() -> None:
    """Llobera et al.'s arms: a person, a coupled avatar, an uncoupled avatar; 10 answers each.
    "person" said 8, 6 and 1 times: right 8, 4 and 9 times."""
    truth = ["person"] * 10 + ["avatar"] * 20
    guesses = (["person"] * 8 + ["avatar"] * 2 + ["person"] * 6 + ["avatar"] * 4
               + ["person"] * 1 + ["avatar"] * 9)  # fmt: skip
    answers = scripted_answers(truth, guesses, [np.nan] * 30)
    answers["condition"] = ["human"] * 10 + ["coupled"] * 10 + ["uncoupled"] * 10
    found = identify(answers)
    assert found is not None
    table = found.per_condition
    assert list(table.index) == ["human", "coupled", "uncoupled"]
    assert list(table["partners"]) == ["person", "avatar", "avatar"]
    assert list(table["said_person"]) == pytest.approx([0.8, 0.6, 0.1])
    assert list(table["correct"]) == [8, 4, 9]
    two_sided = [2 * sum(math.comb(10, j) for j in range(max(k, 10 - k), 11)) / 2**10
                 for k in (8, 4, 9)]  # fmt: skip
    assert list(table["binomial_p"]) == pytest.approx(two_sided)
    assert found.to_dict()["per_condition"][2]["condition"] == "uncoupled"


def test_a_recording_replayed_is_scored_as_a_person_s_motion() -> None:
    answers = forty_eight_answers()
    recorded = answers.assign(partner_kind=answers["partner_kind"].replace({"person": "recording"}))
    found, as_persons = identify(recorded), identify(answers)
    assert found is not None and as_persons is not None
    assert (found.correct, found.binomial_p) == (36, as_persons.binomial_p)
    assert found.detection == as_persons.detection
    assert set(found.per_condition["partners"]) == {"avatar, recording"}
