"""A study's results in words: a line per comparison, the identification, a methods paragraph.

Numbers keep three significant digits; p-values three decimals ("p < 0.001" below that).
A comparison is called a change when its p-value (Holm-corrected when a measure has several
contrasts) is below `ALPHA`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from mirror_avatar.analysis.identification import CHANCE, Identification
from mirror_avatar.analysis.statistics import Contrast

ALPHA = 0.05
"""The significance level the sentences use (**choice**: the field's convention)."""

NO_UNITS = ("", "1", "n/a", "dimensionless")
"""Units not written after a number (BIDS writes "1" for a ratio)."""


def format_p(p: float) -> str:
    """``p = 0.003``, ``p < 0.001``, or ``p = n/a`` for NaN."""
    if math.isnan(p):
        return "p = n/a"
    return "p < 0.001" if p < 0.001 else f"p = {p:.3f}"


def number(value: float) -> str:
    """Format a number with three significant digits ("n/a" for NaN)."""
    return "n/a" if math.isnan(value) else f"{value:.3g}"


def is_change(contrast: Contrast) -> bool:
    """Whether the contrast's (Holm-corrected) p-value is below `ALPHA`."""
    return contrast.p_holm < ALPHA


def comparison_sentence(contrast: Contrast, units: str, several: bool) -> str:
    """One plain-language line: did the condition change the measure, by how much, how surely.

    ``several``: the measure has more than one contrast, so the p-value is Holm-corrected.
    """
    c = contrast
    unit = "" if units in NO_UNITS else f" {units}"
    p = format_p(c.p_holm) + (" Holm-corrected" if several else "")
    evidence = f"({p}, d_z = {number(c.d_z)}, n = {c.participants})"
    if math.isnan(c.p_holm):
        return _capitalised(
            f"{c.condition} against {c.reference}: {c.measure} {number(c.reference_mean)} and "
            f"{number(c.condition_mean)}{unit}, not tested (see the notes below)."
        )
    if is_change(c):
        verb = "raised" if c.difference > 0 else "lowered"
        return _capitalised(
            f"{c.condition} {verb} {c.measure} from {number(c.reference_mean)} "
            f"({c.reference}) to {number(c.condition_mean)}{unit} {evidence}."
        )
    return _capitalised(
        f"{c.condition} did not change {c.measure} detectably from {c.reference}: "
        f"{number(c.reference_mean)} and {number(c.condition_mean)}{unit} {evidence}."
    )


def identification_sentence(found: Identification) -> str:
    """Say the identification result in one paragraph: rate against chance, d', c, confidence."""
    d = found.detection
    said = _against_chance(found)
    told = (f"told persons from avatars {said}" if said != "at chance"
            else "did not tell persons from avatars apart better than chance")  # fmt: skip
    text = (
        f"Participants {told}: {found.correct} of {found.answers} answers right "
        f"({found.rate:.0%}, 95 % CI {found.rate_ci_low:.0%}-{found.rate_ci_high:.0%}; exact "
        f"binomial {format_p(found.binomial_p)} against {CHANCE:.0%}); d' = {number(d.d_prime)}, "
        f"criterion c = {number(d.criterion)}{_bias(d.criterion)}"
    )
    if d.corrected:
        text += ", log-linear corrected for a rate of 0 or 1"
    text += "."
    if found.confidence_right_n and found.confidence_wrong_n:
        text += (f" Confidence was {number(found.confidence_right)} in right answers and "
                 f"{number(found.confidence_wrong)} in wrong ones (Mann-Whitney "
                 f"{format_p(found.confidence_p)}).")  # fmt: skip
    if found.left_out:
        text += f" {found.left_out} answers about mixed partners were not scored."
    return text


def verdict(contrasts: list[Contrast], identification: Identification | None) -> str:
    """Write the report's first line: which comparisons changed a measure, the identification."""
    changed = [f"{c.condition} on {c.measure}" for c in contrasts if is_change(c)]
    if not contrasts:
        line = "No conditions to compare."
    elif changed:
        line = (f"{len(changed)} of {len(contrasts)} comparisons changed a measure "
                f"(p < {ALPHA}): {', '.join(changed)}.")  # fmt: skip
    else:
        line = f"None of {len(contrasts)} comparisons changed a measure (p < {ALPHA} in none)."
    if identification is not None:
        said = _against_chance(identification)
        line += (f" Partners identified {said}: {identification.rate:.0%} right "
                 f"({format_p(identification.binomial_p)}).")  # fmt: skip
    return line


def methods_paragraph(parameters: Mapping[str, Any]) -> str:
    """Write the paragraph to cite in a paper's methods: software, every parameter, the seed."""
    v = parameters["versions"]
    return (
        f"Statistics were computed with mirror-avatar {v['mirror-avatar']} (Python "
        f"{v['python']}, NumPy {v['numpy']}, pandas {v['pandas']}, SciPy {v['scipy']}, "
        f"statsmodels {v['statsmodels']}) from {parameters['participants']} participants' "
        f"{_trials(parameters)}. Each participant's measures were first averaged over their "
        "trials in each condition. Each condition's mean over participants is given with a "
        f"{parameters['confidence']:.0%} bias-corrected and accelerated (BCa) bootstrap "
        f"confidence interval ({parameters['bootstrap_resamples']} resamples of the "
        f"participants' means, scipy.stats.bootstrap, random seed {parameters['seed']}; Efron "
        "& Tibshirani 1993). Conditions were compared within participants by a linear mixed "
        "model per measure, measure ~ condition + position with a random intercept per "
        "participant (statsmodels MixedLM, REML), condition in treatment coding against "
        f"{parameters['reference']!r} and position the condition's place in the participant's "
        "order (1, 2, ...), a covariate that checks order effects; fixed effects were tested "
        "by Wald z tests, Holm-corrected over a measure's contrasts when it has several "
        "(Holm 1979). Effect sizes: Cohen's d_z of the participants' paired means, and the "
        "model's coefficient over its total standard deviation (participant and residual "
        "variances summed; Westfall, Kenny & Judd 2014); paired t-tests and Wilcoxon "
        "signed-rank tests of the participants' means cross-check each contrast. Answers to "
        '"person or computer?" were scored against the partner\'s true kind: the rate of '
        f"right answers against chance ({CHANCE:g}) by an exact two-sided binomial test with "
        "a Clopper-Pearson interval; sensitivity d' = z(H) - z(F) and criterion "
        'c = -(z(H) + z(F))/2 with "person" as the signal (hit: "person" said of a '
        'person; false alarm: "person" said of an avatar; Macmillan & Creelman 2005), '
        "log-linear corrected (0.5 added to hits and false alarms, 1 to each kind's count; "
        "Hautus 1995) when a rate is 0 or 1; each person's own d' tested against 0 by a "
        "one-sample t-test; confidence in right and in wrong answers compared by a two-sided "
        f"Mann-Whitney U test. Significance level {ALPHA}."
    )


def _trials(parameters: Mapping[str, Any]) -> str:
    """Say which trials were analysed: the complete ones, and the incomplete ones left out."""
    rows, left = parameters["rows"], parameters["incomplete_rows"]
    if left is None:
        return (
            f"{rows} trials (the persons' rows of the study table; avatars' rows left out; the "
            "table does not say which trials ran to their end, so all were kept)"
        )
    if not left:
        return (
            f"{rows} complete trials (the persons' rows of the study table; avatars' rows left "
            "out; every trial ran to its end)"
        )
    return (
        f"{rows} complete trials (the persons' rows of the study table; avatars' rows and "
        f"{left} rows of incomplete trials, stopped before their end, left out)"
    )


def _capitalised(sentence: str) -> str:
    return sentence[:1].upper() + sentence[1:]


def _against_chance(found: Identification) -> str:
    """Say "above chance", "below chance" (both at `ALPHA`) or "at chance"."""
    if found.binomial_p >= ALPHA:
        return "at chance"
    return "above chance" if found.rate > CHANCE else "below chance"


def _bias(criterion: float) -> str:
    """Say which answer the criterion leans to, in brackets."""
    if math.isnan(criterion):
        return " (d' and c need answers about both kinds of partner)"
    if criterion == 0:
        return " (no bias)"
    return f' (a bias towards "{"person" if criterion < 0 else "avatar"}")'
