"""A study's results in words: the hypothesis, a line per comparison, the identification, methods.

Numbers keep three significant digits; p-values three decimals ("p < 0.001" below that).
Measures are named by their labels and units (`mirror_avatar.metrics.registry`, through the
study table's data dictionary). The declared hypothesis is said supported when its test's
p-value is below its alpha and the estimate reaches the smallest effect of interest
(`mirror_avatar.analysis.hypothesis.ConfirmatoryTest`); an exploratory comparison is called a
change when its q-value (p adjusted by Benjamini-Hochberg across the exploratory comparisons)
is below `ALPHA`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from mirror_avatar.analysis.hypothesis import ConfirmatoryTest
from mirror_avatar.analysis.identification import CHANCE, Identification
from mirror_avatar.analysis.partner_kind import KIND_TERM
from mirror_avatar.analysis.random_effects import CROSSED_PARTNERS, SELECTION_ALPHA
from mirror_avatar.analysis.statistics import Contrast, FactorTest

ALPHA = 0.05
"""The significance level, and the false discovery rate, of the exploratory sentences
(**choice**: the field's convention)."""

NO_UNITS = ("", "1", "n/a", "dimensionless")
"""Units not written after a number (BIDS writes "1" for a ratio)."""


def format_p(p: float, name: str = "p") -> str:
    """``p = 0.003``, ``p < 0.001``, or ``p = n/a`` for NaN (``name``: ``q`` for a q-value)."""
    if math.isnan(p):
        return f"{name} = n/a"
    return f"{name} < 0.001" if p < 0.001 else f"{name} = {p:.3f}"


def number(value: float) -> str:
    """Format a number with three significant digits ("n/a" for NaN)."""
    return "n/a" if math.isnan(value) else f"{value:.3g}"


def is_change(contrast: Contrast) -> bool:
    """Whether the contrast's q-value (Benjamini-Hochberg) is below `ALPHA`."""
    return contrast.q < ALPHA


def with_unit(value: float, units: str) -> str:
    """Write a number with its unit (none for `NO_UNITS`)."""
    return number(value) + ("" if units in NO_UNITS else f" {units}")


def comparison_sentence(contrast: Contrast, label: str, units: str) -> str:
    """One plain-language line: did the condition change the measure, by how much, how surely.

    ``label`` and ``units`` name the measure; the evidence is the q-value (Benjamini-Hochberg
    across the exploratory comparisons), the model's p, d_z and n.
    """
    c = contrast
    evidence = (f"(exploratory: {format_p(c.q, 'q')}, {format_p(c.p)}, d_z = {number(c.d_z)}, "
                f"n = {c.participants})")  # fmt: skip
    if math.isnan(c.q):
        return _capitalised(
            f"{c.condition} against {c.reference}: {label} {number(c.reference_mean)} and "
            f"{with_unit(c.condition_mean, units)}, not tested (see the notes below)."
        )
    if is_change(c):
        verb = "raised" if c.difference > 0 else "lowered"
        return _capitalised(
            f"{c.condition} {verb} {label} from {number(c.reference_mean)} "
            f"({c.reference}) to {with_unit(c.condition_mean, units)} {evidence}."
        )
    return _capitalised(
        f"{c.condition} did not change {label} detectably from {c.reference}: "
        f"{number(c.reference_mean)} and {with_unit(c.condition_mean, units)} {evidence}."
    )


def factor_sentence(test: FactorTest, label: str, units: str) -> str:
    """Say one test of the partner's kind, or of condition x kind, in a line.

    ``label`` and ``units`` name the measure; the evidence is the q-value (Benjamini-Hochberg
    across the study's tests of kind), the model's p and interval.
    """
    t = test
    evidence = (f"(exploratory: {format_p(t.q, 'q')}, {format_p(t.p)}, 95 % CI "
                f"{number(t.ci_low)} to {number(t.ci_high)}, {number(t.df)} df)")  # fmt: skip
    if t.term == KIND_TERM:
        said = (f"{label} was {with_unit(abs(t.estimate), units)} "
                f"{'higher' if t.estimate > 0 else 'lower'} with {t.kind} partners than with "
                f"{t.reference_kind} partners, over the conditions")  # fmt: skip
        return f"Partner kind: {said} {evidence}."
    said = (f"{t.condition} changed {label} by {with_unit(abs(t.estimate), units)} "
            f"{'more' if t.estimate > 0 else 'less'} with {t.kind} partners than with "
            f"{t.reference_kind} partners")  # fmt: skip
    return f"Condition x partner kind: {said} {evidence}."


def confirmatory_sentence(test: ConfirmatoryTest, label: str, units: str) -> str:
    """Say the declared test's result: the estimate, its interval, p, the smallest effect."""
    t = test
    sided = "two-sided" if t.direction == "two-sided" else "one-sided"
    claim = f"{label} {_direction_words(t.direction)} in {t.condition} than in {t.reference}"
    if not t.tested:
        return _capitalised(
            f"Hypothesis ({claim}): not tested (n = {t.participants} with a mean in both "
            "conditions; two or more whose differences differ are needed)."
        )
    p = format_p(t.p) if t.p == t.p_holm else f"{format_p(t.p_holm)} Holm-corrected"
    interval = (
        ""
        if math.isnan(t.ci_low)
        else f"{t.confidence:.0%} CI {number(t.ci_low)} to {number(t.ci_high)}; "
    )
    found = (
        f"{label} {number(t.reference_mean)} ({t.reference}) and "
        f"{with_unit(t.condition_mean, units)} ({t.condition}), a difference of "
        f"{with_unit(t.estimate, units)} ({interval}{sided} {t.test} {p}, n = {t.participants})"
    )
    smallest = f"the smallest effect of interest, {with_unit(t.smallest_effect, units)}"
    if t.supported:
        outcome = f"at least {smallest}: the hypothesis is supported"
    elif t.significant:
        outcome = f"significant at alpha = {t.alpha:g} but under {smallest}: not supported"
    else:
        outcome = f"not significant at alpha = {t.alpha:g}: the hypothesis is not supported"
    return f"Hypothesis ({claim}): {found}, {outcome}."


def _direction_words(direction: str) -> str:
    return {"lower": "lower", "higher": "higher"}.get(direction, "other")


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
    if found.over_persons:
        text += (f" Over the {found.persons} persons, a mean rate of {found.person_rate_mean:.0%} "
                 f"right (one-sample t-test against {CHANCE:.0%}, "
                 f"{format_p(found.person_rate_p)}; each person's rate a unit, as the binomial "
                 "test above takes every answer as independent).")  # fmt: skip
    if found.confidence_right_n and found.confidence_wrong_n:
        text += (f" Confidence was {number(found.confidence_right)} in right answers and "
                 f"{number(found.confidence_wrong)} in wrong ones (Mann-Whitney "
                 f"{format_p(found.confidence_p)}).")  # fmt: skip
    if found.left_out:
        text += f" {found.left_out} answers about mixed partners were not scored."
    return text


def verdict(
    contrasts: list[Contrast],
    identification: Identification | None,
    confirmatory: list[ConfirmatoryTest] | None = None,
    labels: Mapping[str, str] | None = None,
    unconverged: Sequence[str] = (),
) -> str:
    """Write the report's first line: the hypothesis, the exploratory changes, the identification.

    ``confirmatory`` None: no hypothesis was declared, and every comparison is exploratory.
    ``labels`` names the measures in words (their keys otherwise). ``unconverged``: the
    measures whose mixed model did not converge; their contrasts are left out of the count and
    named. The identification is said by `Identification.chance_test`: over persons when it can.
    """
    named = dict(labels or {})
    contrasts = [c for c in contrasts if c.measure not in unconverged]
    line = _hypothesis_line(confirmatory, named)
    changed = [f"{c.condition} on {named.get(c.measure, c.measure)}"
               for c in contrasts if is_change(c)]  # fmt: skip
    if not contrasts:
        line += "No exploratory comparison." if confirmatory else "No conditions to compare."
    elif changed:
        line += (f"Exploratory: {len(changed)} of {len(contrasts)} comparisons changed a measure "
                 f"(q < {ALPHA}, Benjamini-Hochberg): {'; '.join(changed)}.")  # fmt: skip
    else:
        line += (f"Exploratory: none of {len(contrasts)} comparisons changed a measure "
                 f"(q < {ALPHA} in none).")  # fmt: skip
    if unconverged:
        line += (f" Not counted, their fit did not converge: "
                 f"{', '.join(named.get(m, m) for m in unconverged)}.")  # fmt: skip
    if identification is not None:
        said = _against_chance(identification)
        rate, p = identification.chance_test
        test = (f"t-test over {identification.persons} persons" if identification.over_persons
                else f"exact binomial over {identification.answers} answers")  # fmt: skip
        line += f" Partners identified {said}: {rate:.0%} right ({test}, {format_p(p)})."
    return line


def _hypothesis_line(confirmatory: list[ConfirmatoryTest] | None, labels: dict[str, str]) -> str:
    """Open the verdict: the hypothesis supported or not, or none declared."""
    if confirmatory is None:
        return "No hypothesis declared: every comparison is exploratory. "
    said = "; ".join(
        f"{labels.get(t.measure, t.measure)} {'supported' if t.supported else 'not supported'}"
        for t in confirmatory
    )
    first = confirmatory[0]
    return f"Hypothesis ({first.condition} against {first.reference}): {said}. "


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
        "model per measure, measure ~ condition + position, and + partner kind + condition x "
        "partner kind where the trials had partners of several kinds (weighted-effects "
        "coding: each kind's indicator and the conditions' centred, so that a condition's "
        "effect is averaged over the kinds)"
        f"{_fitted_models(parameters.get('fixed_effects', {}))}, with random effects per "
        "participant (statsmodels MixedLM, REML): a random intercept and correlated random "
        "slopes for condition (Barr, Levy, Scheepers & Tily 2013) where the data supported "
        "them (participants with every condition outnumbering the conditions, repeated trials, "
        "a fit that converged with a non-singular covariance, and a REML likelihood-ratio test "
        f"against the random intercept alone at p < {SELECTION_ALPHA:g}; Matuschek, Kliegl, "
        "Vasishth, Baayen & Bates 2017), else a random intercept alone; with partners of "
        "several kinds, correlated random slopes for the kind added on the same terms (tested "
        "against the model without them); with at least "
        f"{CROSSED_PARTNERS} partners each met by two participants or more, a random intercept "
        "per partner crossed with the participants, kept on the same terms (variance "
        "components of one group, the slopes then uncorrelated with the intercept)"
        f"{_fitted_models(parameters.get('random_effects', {}))}; condition in treatment "
        f"coding against {parameters['reference']!r} and position the condition's place in "
        "the participant's order (1, 2, ...), a covariate that checks order effects; fixed "
        "effects were tested "
        "by t tests with Satterthwaite's degrees of freedom, computed from the REML fit's "
        "variance parameters (Satterthwaite 1946; the method of lmerTest, Kuznetsova, "
        "Brockhoff & Christensen 2017), with t confidence intervals on the same degrees of "
        "freedom, and every comparison but the declared hypothesis's is exploratory: "
        "its p-value adjusted for the false discovery rate across measures and conditions "
        "(Benjamini & Hochberg 1995; q-values). Effect sizes: Cohen's d_z of the "
        "participants' paired means, and the "
        "model's coefficient over its total standard deviation (participant and residual "
        "variances summed; Westfall, Kenny & Judd 2014); paired t-tests and Wilcoxon "
        "signed-rank tests of the participants' means cross-check each contrast. Answers to "
        '"person or computer?" were scored against the partner\'s true kind: the rate of '
        f"right answers against chance ({CHANCE:g}) by an exact two-sided binomial test with "
        "a Clopper-Pearson interval; sensitivity d' = z(H) - z(F) and criterion "
        'c = -(z(H) + z(F))/2 with "person" as the signal (hit: "person" said of a '
        'person; false alarm: "person" said of an avatar; Macmillan & Creelman 2005), '
        "log-linear corrected (0.5 added to hits and false alarms, 1 to each kind's count; "
        "Hautus 1995) when a rate is 0 or 1; each person's own d' tested against 0, and each "
        f"person's rate of right answers against {CHANCE:g}, by one-sample t-tests over the "
        "persons (the persons the unit, a person's answers not being independent; the "
        "verdict's test, the pooled binomial when fewer than two persons' rates differ); "
        "confidence in right and in wrong answers compared by a two-sided "
        f"Mann-Whitney U test. Significance level and false discovery rate {ALPHA}."
        + _angles_methods(parameters.get("angles", []))
        + _hypothesis_methods(parameters.get("hypothesis"), parameters.get("protocol"))
    )


def _angles_methods(angles: list[str]) -> str:
    """Say how angle measures (their labels) were averaged and compared; "" without any."""
    if not angles:
        return ""
    return (
        f" {_capitalised(_listed(angles))}, angles, were averaged as unit vectors (each "
        "participant's circular mean per condition, the conditions' circular means of the "
        "participants', with the mean resultant length, the circular SD and Rayleigh's test; "
        "Fisher 1993; Zar 1999) and compared by a sign-flip randomisation test of each "
        "participant's difference of directions, not by the mixed model."
    )


def _fitted_models(fitted: Mapping[str, str]) -> str:
    """Say which measures (by label) got which random effects: ``fitted`` maps label to words."""
    if not fitted:
        return ""
    kinds = {kind: [label for label, k in fitted.items() if k == kind]
             for kind in dict.fromkeys(fitted.values())}  # fmt: skip
    said = "; ".join(f"{kind} for {_listed(labels)}" for kind, labels in kinds.items())
    return f" (fitted: {said})"


def _listed(labels: list[str]) -> str:
    """Join labels as prose: ``a``, ``a and b``, ``a, b and c``."""
    return labels[0] if len(labels) == 1 else f"{', '.join(labels[:-1])} and {labels[-1]}"


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


def _hypothesis_methods(hypothesis: Mapping[str, Any] | None, protocol: str | None) -> str:
    """Say the declared hypothesis and its test, for the methods paragraph."""
    if hypothesis is None:
        return " No hypothesis was declared: every comparison is exploratory."
    h = hypothesis
    sided = "two-sided" if h["direction"] == "two-sided" else f"one-sided ({h['direction']})"
    several = len(h["primary"]) > 1
    return (
        f" The hypothesis declared in the protocol's analysis section ({protocol}) was "
        f"tested first: {' and '.join(h['primary'])} in {h['condition']!r} against "
        f"{h['reference']!r}, by a {sided} paired t-test of the participants' means at alpha "
        f"{h['alpha']:g}{', Holm-corrected over the primary measures' if several else ''}, "
        f"with a {_level(h)} t interval of the mean difference, the smallest effect of "
        f"interest {h['smallest_effect']:g} in the measure's units."
    )


def _level(hypothesis: Mapping[str, Any]) -> str:
    """Write the confidence level matching the declared test (1 - 2 alpha when one-sided)."""
    sides = 1.0 if hypothesis["direction"] == "two-sided" else 2.0
    return f"{1.0 - sides * hypothesis['alpha']:.0%}"


def _capitalised(sentence: str) -> str:
    return sentence[:1].upper() + sentence[1:]


def _against_chance(found: Identification) -> str:
    """Say "above chance", "below chance" (both at `ALPHA`) or "at chance", by `chance_test`."""
    rate, p = found.chance_test
    if p >= ALPHA:
        return "at chance"
    return "above chance" if rate > CHANCE else "below chance"


def _bias(criterion: float) -> str:
    """Say which answer the criterion leans to, in brackets."""
    if math.isnan(criterion):
        return " (d' and c need answers about both kinds of partner)"
    if criterion == 0:
        return " (no bias)"
    return f' (a bias towards "{"person" if criterion < 0 else "avatar"}")'
