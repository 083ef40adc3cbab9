"""Conditions compared within participants: bootstrap CIs, mixed models, effect sizes.

Checked against scipy and statsmodels called directly, a hand-written bootstrap, hand-computed
effect sizes, and synthetic studies with known effects (issue 37's must-show: with both
conditions identical, p >= 0.05 in at least 18 of 20 seeds; a true effect found with its sign).
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest
import statsmodels.formula.api as smf
from scipy import stats
from statsmodels.tools.sm_exceptions import ConvergenceWarning
from study_tables import CONDITIONS, make_study_rows

from mirror_avatar.analysis.statistics import (
    bootstrap_mean_ci,
    condition_summaries,
    fit_contrasts,
    paired_effect,
    participant_means,
    trial_labels,
    trial_values,
)

NO_DELAY, DELAY = CONDITIONS


def persons(rows: pd.DataFrame) -> pd.DataFrame:
    return rows[rows["player_kind"] == "person"]


def test_participant_means_average_each_participants_trials_first() -> None:
    rows = pd.DataFrame({
        "participant": ["a", "a", "a", "b"], "condition": ["x", "x", "y", "x"],
        "rms": [1.0, 3.0, 5.0, 7.0],
    })  # fmt: skip
    means = participant_means(rows, "rms", ["x", "y"])
    assert means.loc["a", "x"] == 2.0 and means.loc["a", "y"] == 5.0
    assert means.loc["b", "x"] == 7.0 and np.isnan(means.loc["b", "y"])


@pytest.mark.parametrize("method", ["BCa", "percentile"])
def test_bootstrap_ci_is_scipys_with_the_same_seed(method: str) -> None:
    values = np.random.default_rng(1).gamma(2.0, size=12)
    found = bootstrap_mean_ci(values, seed=7, resamples=2000, method=method)  # type: ignore[arg-type]
    direct = stats.bootstrap(
        (values,), np.mean, n_resamples=2000, method=method, rng=np.random.default_rng(7)
    ).confidence_interval
    assert found == pytest.approx((direct.low, direct.high), rel=1e-12)


def test_percentile_bootstrap_equals_a_hand_written_one() -> None:
    """Resample the participants with replacement, take the 2.5 and 97.5 percentiles."""
    values = np.random.default_rng(2).normal(size=12)
    draws = np.random.default_rng(5).integers(0, values.size, (9999, values.size))
    hand = np.percentile(values[draws].mean(axis=1), [2.5, 97.5])
    assert bootstrap_mean_ci(values, seed=5, method="percentile") == pytest.approx(hand)


def test_bootstrap_ci_of_equal_or_too_few_values() -> None:
    assert bootstrap_mean_ci([0.3, 0.3, 0.3], seed=0) == (0.3, 0.3)
    assert all(np.isnan(bootstrap_mean_ci([0.3], seed=0)))


def test_condition_summaries_are_over_participant_means() -> None:
    rows = persons(make_study_rows(0, effects={"rms": 0.05}))
    summaries = condition_summaries(rows, ["rms"], CONDITIONS, seed=3, resamples=999)
    means = participant_means(rows, "rms", CONDITIONS)
    for condition, row in summaries.set_index("condition").iterrows():
        values = means[condition].to_numpy()
        assert row["participants"] == 12
        assert row["mean"] == pytest.approx(values.mean())
        assert row["sd"] == pytest.approx(values.std(ddof=1))
        ci = bootstrap_mean_ci(values, seed=3, resamples=999)
        assert (row["ci_low"], row["ci_high"]) == pytest.approx(ci)
        assert row["ci_low"] < row["mean"] < row["ci_high"]


def test_mixed_model_equals_statsmodels_formula() -> None:
    rows = persons(make_study_rows(4, effects={"rms": 0.03}, order_effect=0.01))
    model = fit_contrasts(rows, "rms", CONDITIONS, NO_DELAY)
    assert model is not None
    with warnings.catch_warnings():  # its boundary check is in absolute units: RMS is small
        warnings.simplefilter("ignore", ConvergenceWarning)
        direct = smf.mixedlm(
            f"rms ~ C(condition, Treatment(reference='{NO_DELAY}')) + position",
            rows, groups=rows["participant"],
        ).fit(reml=True)  # fmt: skip
    name = f"C(condition, Treatment(reference='{NO_DELAY}'))[T.{DELAY}]"
    (contrast,) = model.contrasts
    assert contrast.difference == pytest.approx(direct.fe_params[name], rel=1e-4)
    t = direct.tvalues[name]  # statsmodels' z, tested here on Satterthwaite's df
    assert 50 < contrast.df < len(rows) - 2
    assert contrast.p == pytest.approx(2 * stats.t.sf(abs(t), contrast.df), rel=1e-2)
    half = stats.t.ppf(0.975, contrast.df) * direct.bse[name]
    assert (contrast.ci_low, contrast.ci_high) == pytest.approx(
        (direct.fe_params[name] - half, direct.fe_params[name] + half), rel=1e-3
    )
    assert model.position_slope == pytest.approx(direct.fe_params["position"], rel=1e-3)
    assert model.participant_variance == pytest.approx(direct.cov_re.iloc[0, 0], rel=1e-3)
    assert model.residual_variance == pytest.approx(direct.scale, rel=1e-3)
    total = np.sqrt(direct.cov_re.iloc[0, 0] + direct.scale)
    assert contrast.standardised == pytest.approx(direct.fe_params[name] / total, rel=1e-3)


@pytest.mark.long
def test_mixed_model_recovers_known_condition_and_order_effects() -> None:
    """Over 20 seeds: unbiased estimates, 95 % intervals holding the truth about 95 % of times."""
    differences, slopes, covered = [], [], 0
    for seed in range(20):
        rows = persons(make_study_rows(seed, trials=8, effects={"rms": 0.05}, order_effect=0.02))
        model = fit_contrasts(rows, "rms", CONDITIONS, NO_DELAY)
        assert model is not None and model.position_in_model
        (contrast,) = model.contrasts
        assert contrast.p < 0.001 and contrast.difference > 0
        differences.append(contrast.difference)
        slopes.append(model.position_slope)
        covered += contrast.ci_low < 0.05 < contrast.ci_high
    assert np.mean(differences) == pytest.approx(0.05, abs=0.003)
    assert np.mean(slopes) == pytest.approx(0.02, abs=0.003)
    assert covered >= 17


def test_one_trial_per_condition_in_one_order_is_the_paired_t_test() -> None:
    """Position confounded with condition is left out: the model is the paired t-test."""
    rows = persons(make_study_rows(3, participants=7, trials=1, effects={"rms": 0.02}))
    rows = rows.assign(position=np.where(rows["condition"] == NO_DELAY, 1, 2))
    model = fit_contrasts(rows, "rms", CONDITIONS, NO_DELAY)
    assert model is not None and not model.position_in_model
    (contrast,) = model.contrasts
    assert contrast.df == pytest.approx(6.0, abs=0.01)
    assert contrast.p == pytest.approx(contrast.t_p, abs=1e-4)
    assert 0.001 < contrast.p < 0.5


def test_paired_effect_against_hand_and_scipy() -> None:
    before = np.array([0.10, 0.12, 0.11, 0.14, 0.09])
    after = np.array([0.15, 0.16, 0.12, 0.19, 0.15])
    differences = after - before  # 0.05, 0.04, 0.01, 0.05, 0.06: mean 0.042
    sd = np.sqrt(((differences - 0.042) ** 2).sum() / 4)  # sample SD of the differences
    effect = paired_effect(before, after)
    assert effect["d_z"] == pytest.approx(0.042 / sd)
    assert effect["t"] == pytest.approx(0.042 / (sd / np.sqrt(5)))
    assert effect["t_p"] == pytest.approx(stats.ttest_rel(after, before).pvalue)
    assert effect["wilcoxon_p"] == pytest.approx(stats.wilcoxon(differences).pvalue)
    assert effect["wilcoxon_p"] == pytest.approx(2 / 2**5)  # all 5 signs positive, exact


def test_contrast_cross_checks_are_of_participant_means() -> None:
    rows = persons(make_study_rows(6, effects={"phase_locking": -0.1}))
    model = fit_contrasts(rows, "phase_locking", CONDITIONS, NO_DELAY)
    assert model is not None
    (contrast,) = model.contrasts
    means = participant_means(rows, "phase_locking", CONDITIONS)
    assert contrast.participants == 12
    assert contrast.reference_mean == pytest.approx(means[NO_DELAY].mean())
    assert contrast.condition_mean == pytest.approx(means[DELAY].mean())
    assert contrast.t_p == pytest.approx(stats.ttest_rel(means[DELAY], means[NO_DELAY]).pvalue)


def test_order_confounded_with_condition_is_left_out_and_said() -> None:
    rows = persons(make_study_rows(7))
    rows = rows.assign(position=np.where(rows["condition"] == NO_DELAY, 1, 2))
    model = fit_contrasts(rows, "rms", CONDITIONS, NO_DELAY)
    assert model is not None and not model.position_in_model
    assert np.isnan(model.position_slope)
    assert any("confounded with condition" in note for note in model.notes)


def test_three_conditions_have_holm_corrected_contrasts() -> None:
    three = ("a", "b", "c")
    rows = persons(make_study_rows(8, effects={"rms": 0.01}, conditions=three))
    model = fit_contrasts(rows, "rms", three, "a")
    assert model is not None
    assert [c.condition for c in model.contrasts] == ["b", "c"]
    smaller, larger = sorted(c.p for c in model.contrasts)
    holm = sorted(c.p_holm for c in model.contrasts)
    assert holm == pytest.approx([min(1.0, 2 * smaller), min(1.0, max(2 * smaller, larger))])


def test_one_condition_gives_no_model() -> None:
    rows = persons(make_study_rows(9))
    assert fit_contrasts(rows[rows["condition"] == NO_DELAY], "rms", CONDITIONS, NO_DELAY) is None


@pytest.mark.long
def test_identical_conditions_are_not_found_different_in_18_of_20_seeds() -> None:
    """Issue 37: with both conditions identical, p >= 0.05 in at least 18 of 20 seeds."""
    for measure in ("rms", "phase_locking"):
        p_values = []
        for seed in range(20):
            model = fit_contrasts(persons(make_study_rows(seed)), measure, CONDITIONS, NO_DELAY)
            assert model is not None
            p_values.append(model.contrasts[0].p)
        assert sum(p >= 0.05 for p in p_values) >= 18, (measure, p_values)


@pytest.mark.long
def test_the_delays_effect_is_found_with_its_sign_in_every_seed() -> None:
    """Issue 37: a delay that raises RMS and lowers phase locking is found, right sign."""
    effects = {"rms": 0.03, "phase_locking": -0.05}
    for seed in range(20):
        rows = persons(make_study_rows(100 + seed, effects=effects))
        for measure, effect in effects.items():
            model = fit_contrasts(rows, measure, CONDITIONS, NO_DELAY)
            assert model is not None
            (contrast,) = model.contrasts
            assert contrast.p < 0.05, (seed, measure, contrast)
            assert np.sign(contrast.difference) == np.sign(effect)
            assert np.sign(contrast.d_z) == np.sign(effect)


NOISELESS = "no variation beyond what participant, condition and position explain exactly"
"""The note of a measure the mixed model's fixed effects and participants explain exactly."""


def test_a_constant_or_noiseless_measure_is_said_untested() -> None:
    """Found before any fit, so the words do not depend on what statsmodels and the machine's
    BLAS make of a singular model (an error on one machine, a fit not converging on another)."""
    rows = persons(make_study_rows(0))
    constant = fit_contrasts(rows.assign(rms=0.1), "rms", CONDITIONS, NO_DELAY)
    noiseless = rows.assign(rms=np.where(rows["condition"] == DELAY, 0.2, 0.1))
    exact = fit_contrasts(noiseless, "rms", CONDITIONS, NO_DELAY)
    assert constant is not None and exact is not None
    assert constant.notes == ["the same value in every trial"]
    assert exact.notes == [f"{NOISELESS}, so no mixed model was fitted"]
    (contrast,) = exact.contrasts
    assert np.isnan(contrast.p) and np.isnan(contrast.difference)
    assert contrast.condition_mean == pytest.approx(0.2)


def test_a_measure_of_participants_and_conditions_without_noise_is_said_untested() -> None:
    rows = persons(make_study_rows(1))
    offsets = rows["participant"].astype("category").cat.codes * 0.01
    exact = rows.assign(rms=0.1 + offsets + 0.05 * (rows["condition"] == DELAY))
    model = fit_contrasts(exact, "rms", CONDITIONS, NO_DELAY)
    assert model is not None and model.notes == [f"{NOISELESS}, so no mixed model was fitted"]
    (contrast,) = model.contrasts
    assert np.isnan(contrast.p)
    assert contrast.condition_mean == pytest.approx(contrast.reference_mean + 0.05)


def test_a_measure_with_noise_below_its_scale_is_still_fitted() -> None:
    """Noise of a 50th of the effect is not rounding: the model is fitted and finds the effect."""
    rows = persons(make_study_rows(2))
    noise = np.random.default_rng(3).normal(scale=1e-3, size=len(rows))
    nearly = rows.assign(rms=0.1 + 0.05 * (rows["condition"] == DELAY) + noise)
    model = fit_contrasts(nearly, "rms", CONDITIONS, NO_DELAY)
    assert model is not None
    (contrast,) = model.contrasts
    assert contrast.difference == pytest.approx(0.05, rel=0.02) and contrast.p < 1e-6


def test_trial_labels_name_each_trials_partners_once_in_trial_values_order() -> None:
    """A pair's two persons name each other: the trial's partners are both, once."""
    rows = pd.DataFrame({
        "participant": ["a", "a", "a", "a", "b"], "condition": "x", "position": 1,
        "trial": [1, 1, 2, 2, 1], "partners": ["P2", "P1", "P2", "P1", "A3"],
        "rms": [0.1, 0.1, 0.2, 0.2, 0.3],
    })  # fmt: skip
    partners = trial_labels(rows, "partners")
    assert partners is not None
    assert list(partners) == ["P1+P2", "P1+P2", "A3"]
    assert list(partners.index) == list(trial_values(rows, "rms").index)
    assert trial_labels(rows.drop(columns="partners"), "partners") is None
