"""A study's declared hypothesis tested, and its other comparisons corrected for discovery.

The confirmatory test (`confirm`) is the one a protocol's ``[analysis]`` declares
(`mirror_avatar.lab.design.protocol.Analysis`): per primary measure, a paired t-test of the
participants' means in the tested condition against the reference, one-sided when the
hypothesis names a direction, its interval at the matching level, the primary measures
Holm-corrected together, and the estimate set against the smallest effect of interest. An angle
(`mirror_avatar.analysis.dictionary.is_angle`) is tested on the circle instead: the participants'
circular means, the sign-flip test of their differences of direction
(`mirror_avatar.analysis.circular.sign_flip_p`, one-sided as declared: "higher" is later in
the cycle), the estimate the differences' circular mean (rad) and no interval. Every
other comparison is exploratory: its p-values adjusted across measures by Benjamini and
Hochberg's step-up procedure
(`mirror_avatar.analysis.multiple_tests.benjamini_hochberg`). docs/METHODS.md, section 15.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from numpy.typing import NDArray
from scipy import stats

from mirror_avatar.analysis.circular import circular_mean, sign_flip_p, wrapped
from mirror_avatar.analysis.dictionary import is_angle
from mirror_avatar.analysis.multiple_tests import holm
from mirror_avatar.analysis.statistics import has_spread, participant_means
from mirror_avatar.lab.design.protocol import Analysis

ALTERNATIVES = {"lower": "less", "higher": "greater", "two-sided": "two-sided"}
"""Each direction of a hypothesis as scipy's ``alternative`` of condition minus reference."""

CONFIRMATORY_MODEL = (
    "paired t-test of the participants' means, condition minus reference, one-sided as "
    "declared, Holm over the primary measures"
)
"""The declared hypothesis's test in words, as the report and the registered plan name it
(`confirmatory_model`: with the words of `ANGLE_TEST` when a primary measure is an angle)."""

ANGLE_TEST = "sign-flip test of the participants' differences of circular means"
"""The declared test of an angle, in words."""

PAIRED_T = "paired t-test"
"""The declared test of any other measure, in words."""

EXPLORATORY_MODEL = "Benjamini-Hochberg q-values over every exploratory contrast"
"""How every other comparison is corrected, in words."""


@dataclass(frozen=True)
class ConfirmatoryTest:
    """The declared test of one primary measure.

    Parameters
    ----------
    measure, condition, reference, direction
        What the hypothesis declares (``direction``: lower, higher or two-sided).
    participants
        Participants with a mean in both conditions (the test's n).
    reference_mean, condition_mean
        The means of their means.
    estimate
        The mean of the paired differences, condition minus reference, in the measure's units.
    ci_low, ci_high, confidence
        Its t interval at ``confidence``: 1 - alpha two-sided, 1 - 2 alpha one-sided (its bound
        on the hypothesis's side excludes 0 exactly when the one-sided p is below alpha).
    t, p
        The paired t statistic and its p-value, one-sided as declared.
    p_holm
        ``p`` Holm-corrected over the primary measures (``p`` with one).
    smallest_effect, alpha
        As declared.
    test
        The test run, in words: `PAIRED_T`, or `ANGLE_TEST` for an angle (whose means and
        estimate are circular, in rad, and whose ``t`` and interval are NaN).
    """

    measure: str
    condition: str
    reference: str
    direction: str
    participants: int
    reference_mean: float
    condition_mean: float
    estimate: float
    ci_low: float
    ci_high: float
    confidence: float
    t: float
    p: float
    p_holm: float
    smallest_effect: float
    alpha: float
    test: str = PAIRED_T

    @property
    def tested(self) -> bool:
        """Whether the test could be run (two or more pairs with a spread)."""
        return not math.isnan(self.p)

    @property
    def significant(self) -> bool:
        """Whether the Holm-corrected p is below alpha."""
        return self.p_holm < self.alpha

    @property
    def exceeds_smallest(self) -> bool:
        """Whether the estimate, in the declared direction, is the smallest effect or more."""
        signed = {"lower": -self.estimate, "higher": self.estimate}
        return bool(signed.get(self.direction, abs(self.estimate)) >= self.smallest_effect)

    @property
    def supported(self) -> bool:
        """Whether the hypothesis holds: significant, and at least the smallest effect."""
        return self.significant and self.exceeds_smallest


def confirmatory_model(primary: tuple[str, ...]) -> str:
    """Return the declared test in words, naming the angles' test when ``primary`` has one."""
    angles = [measure for measure in primary if is_angle(measure)]
    if not angles:
        return CONFIRMATORY_MODEL
    return f"{CONFIRMATORY_MODEL}; for {', '.join(angles)}, an angle, the {ANGLE_TEST}"


def confirm(rows: pd.DataFrame, analysis: Analysis) -> list[ConfirmatoryTest]:
    """Run the declared test of each primary measure on the participants' rows.

    ``rows``: one per trial and person (`mirror_avatar.analysis.study_report.analyse_study`'s),
    with a column per primary measure.
    """
    pairs = [_pairs(rows, measure, analysis) for measure in analysis.primary]
    tests = [
        _paired_test(pair, analysis, is_angle(measure))
        for measure, pair in zip(analysis.primary, pairs, strict=True)
    ]
    adjusted = holm([test[1] for test in tests])
    return [
        _result(measure, pair, test, float(p_holm), analysis)
        for measure, pair, test, p_holm in zip(
            analysis.primary, pairs, tests, adjusted, strict=True
        )
    ]


def _pairs(rows: pd.DataFrame, measure: str, analysis: Analysis) -> pd.DataFrame:
    """Each participant's means in the reference and the tested condition, both present."""
    average = circular_mean if is_angle(measure) else "mean"
    conditions = [analysis.reference, analysis.condition]
    return participant_means(rows, measure, conditions, average).dropna()


def _paired_test(
    pairs: pd.DataFrame, analysis: Analysis, angle: bool
) -> tuple[float, float, tuple[float, float], float]:
    """Return the paired test's statistic, p (as declared), interval and its level.

    An angle's statistic and interval are NaN: its p is the sign-flip test's.
    """
    one_sided = analysis.direction != "two-sided"
    confidence = 1.0 - analysis.alpha * (2.0 if one_sided else 1.0)
    after = pairs[analysis.condition].to_numpy(np.float64)
    before = pairs[analysis.reference].to_numpy(np.float64)
    nan = float("nan")
    differences = wrapped(after - before) if angle else after - before
    if after.size < 2 or not has_spread(differences):
        return nan, nan, (nan, nan), confidence
    if angle:
        alternative = ALTERNATIVES[analysis.direction]
        p = sign_flip_p(np.sin(differences), alternative, np.random.default_rng(0))
        return nan, float(p), (nan, nan), confidence
    t, p = declared_test(differences, analysis.direction)
    interval = stats.ttest_rel(after, before).confidence_interval(confidence)
    limits = (float(interval.low), float(interval.high))
    return float(t), float(p), limits, confidence


def declared_test(
    differences: NDArray[np.float64], direction: str
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return the paired t statistic and its p-value, one-sided as declared, of each study.

    Parameters
    ----------
    differences
        Shape (..., n): each study's n paired differences, condition minus reference.
    direction
        The hypothesis's direction (`ALTERNATIVES`).

    Returns
    -------
    t, p
        Shape (...): the one-sample t-test of the differences against 0, which is the paired
        t-test of the two conditions (`scipy.stats.ttest_rel`).
    """
    found = stats.ttest_1samp(differences, 0.0, axis=-1, alternative=ALTERNATIVES[direction])
    return np.asarray(found.statistic, np.float64), np.asarray(found.pvalue, np.float64)


def _result(
    measure: str,
    pairs: pd.DataFrame,
    test: tuple[float, float, tuple[float, float], float],
    p_holm: float,
    analysis: Analysis,
) -> ConfirmatoryTest:
    t, p, (low, high), confidence = test
    before, after = pairs[analysis.reference], pairs[analysis.condition]
    angle = is_angle(measure)
    average = circular_mean if angle else np.mean
    difference = wrapped(after - before) if angle else after - before
    return ConfirmatoryTest(
        measure=measure, condition=analysis.condition, reference=analysis.reference,
        direction=analysis.direction, participants=len(pairs),
        reference_mean=float(average(before)), condition_mean=float(average(after)),
        estimate=float(average(difference)),
        ci_low=low, ci_high=high, confidence=confidence, t=t, p=p, p_holm=p_holm,
        smallest_effect=analysis.smallest_effect, alpha=analysis.alpha,
        test=ANGLE_TEST if angle else PAIRED_T,
    )  # fmt: skip
