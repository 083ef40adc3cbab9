"""The statistics of conditions compared within participants (docs/METHODS.md, section 15).

Per condition and measure, the mean over participants with a bootstrap confidence interval
(`condition_summaries`); per measure, each condition against the reference condition in a
linear mixed model with the condition's position in the participant's order as a covariate
and random effects per participant (slopes for condition and partner kind, and crossed
partners, where the data support them: `mirror_avatar.analysis.random_effects`), its fixed
effects tested by t tests
with Satterthwaite's degrees of freedom (`mirror_avatar.analysis.small_sample`), with effect
sizes and paired tests of the participants' means as a cross-check (`fit_contrasts`). Rows are
a participant's trials (one per trial and player); every participant's mean is taken over
their trials first.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray
from scipy import stats

from mirror_avatar.analysis.multiple_tests import holm
from mirror_avatar.analysis.partner_kind import (
    INTERACTION_TERM,
    KIND_TERM,
    KindTerms,
    kind_terms,
)
from mirror_avatar.analysis.random_effects import (
    CROSSED,
    INTERCEPT,
    SLOPES,
    fit_random_effects,
)
from mirror_avatar.analysis.small_sample import SmallSampleTest, satterthwaite_tests
from mirror_avatar.common.constraints import Interval

BOOTSTRAP_RESAMPLES = 9999
"""Bootstrap resamples of the participants' means (**choice**: scipy's default)."""

RESAMPLES = Interval(int, 100, 100_000)
"""The bootstrap resamples a report may ask for: scipy holds every resample's participants' means
in memory together (**choice**)."""

CONFIDENCE = 0.95
"""Confidence level of every interval."""

MIXED_MODEL = (
    f"measure ~ C(condition, reference) + position (+ partner kind + condition x partner kind "
    f"where the trials have partners of several kinds), {SLOPES} where the data support them, "
    f"else {INTERCEPT}; {CROSSED} where several partners are met by several participants; "
    "REML, t tests with Satterthwaite degrees of freedom, Holm over a measure's contrasts"
)
"""Each measure's model of the conditions, in words (`fit_contrasts`)."""

BootstrapMethod = Literal["BCa", "percentile"]

EXACT_RESIDUAL = 1e-9
"""Largest residual, in the measure's SDs, of a measure its model's terms explain exactly
(rounding leaves 1e-15 or so; any noise a measure of people carries is many orders above)."""

NOISELESS = (
    "no variation beyond what participant, condition and position explain exactly, "
    "so no mixed model was fitted"
)
"""The note of a measure its model's terms explain exactly (`fit_contrasts`)."""


def has_spread(values: NDArray[np.float64]) -> bool:
    """Whether ``values`` differ by more than rounding (relative 1e-12): a spread to scale by."""
    return bool(has_spreads(np.ravel(values)))


def has_spreads(values: NDArray[np.floating[Any]]) -> NDArray[np.bool_]:
    """Shape ``values.shape[:-1]``: `has_spread` of each row along the last axis."""
    if values.shape[-1] == 0:
        return np.zeros(values.shape[:-1], dtype=bool)
    scale = np.maximum(1.0, np.max(np.abs(values), axis=-1))
    return np.asarray(np.ptp(values, axis=-1) > 1e-12 * scale)


TRIAL_KEYS = ("participant", "condition", "position", "block", "trial")
"""The columns that name a trial of a participant (those the table has)."""


def trial_values(rows: pd.DataFrame, measure: str) -> pd.DataFrame:
    """One value of ``measure`` per trial: the mean over the trial's rows (its persons).

    A participant of a two-person protocol has a row per person and trial; a measure of the
    pair is the same in both, and counting it twice would halve the model's variance. Rows
    without ``block`` and ``trial`` columns are each a trial.

    Returns
    -------
    pandas.DataFrame
        Columns `TRIAL_KEYS` (those present) and ``measure``.
    """
    keys = [key for key in TRIAL_KEYS if key in rows]
    if "trial" not in keys:
        return rows[[*keys, measure]]
    grouped = rows.groupby(keys, sort=False, dropna=False)[measure].mean()
    return grouped.reset_index()


def trial_labels(rows: pd.DataFrame, column: str) -> pd.Series | None:
    """Each trial's labels in ``column``, in `trial_values`'s order and index; None without it.

    The labels of the trial's rows (its persons'), each once, sorted and joined by +: for
    ``partners``, a person playing with avatar A2 has A2 and the two persons of a pair P1+P2;
    for ``partner_kind``, a trial whose persons met partners of two kinds has both
    (avatar+person).
    """
    if column not in rows:
        return None
    keys = [key for key in TRIAL_KEYS if key in rows]
    if "trial" not in keys:
        return rows[column].astype(str)
    joined = rows.groupby(keys, sort=False, dropna=False)[column].agg(
        lambda labels: "+".join(sorted({str(label) for label in labels}))
    )
    return joined.reset_index(drop=True)


def participant_means(
    rows: pd.DataFrame,
    measure: str,
    conditions: Sequence[str],
    average: str | Callable[[pd.Series], float] = "mean",
) -> pd.DataFrame:
    """Each participant's mean of ``measure`` in each condition over their trials.

    ``average`` takes the mean: the arithmetic by default, any aggregation pandas accepts
    (`mirror_avatar.analysis.circular.circular_mean` for an angle).

    Returns
    -------
    pandas.DataFrame
        Index the participants (sorted), columns ``conditions`` in their order; NaN where a
        participant has no value in a condition.
    """
    valid = rows.dropna(subset=[measure])
    means = valid.groupby(["participant", "condition"])[measure].agg(average).unstack("condition")
    return means.reindex(columns=list(conditions)).sort_index()


def bootstrap_mean_ci(
    values: ArrayLike,
    seed: int,
    resamples: int = BOOTSTRAP_RESAMPLES,
    confidence: float = CONFIDENCE,
    method: BootstrapMethod = "BCa",
) -> tuple[float, float]:
    """Bootstrap confidence interval of the mean of ``values`` (one per participant).

    ``scipy.stats.bootstrap`` (Efron & Tibshirani 1993) with a generator seeded by ``seed``.
    Values all equal (see `has_spread`) give (value, value); fewer than two values give NaN.

    Returns
    -------
    tuple of float
        Lower and upper limits, in the values' units.
    """
    sample = np.asarray(values, dtype=np.float64)
    sample = sample[np.isfinite(sample)]
    if sample.size < 2:
        return (float("nan"), float("nan"))
    if not has_spread(sample):
        return (float(sample.mean()), float(sample.mean()))
    found = stats.bootstrap(
        (sample,),
        np.mean,
        n_resamples=resamples,
        confidence_level=confidence,
        method=method,
        rng=np.random.default_rng(seed),
    )
    return (float(found.confidence_interval.low), float(found.confidence_interval.high))


def condition_summaries(
    rows: pd.DataFrame,
    measures: Sequence[str],
    conditions: Sequence[str],
    seed: int,
    resamples: int = BOOTSTRAP_RESAMPLES,
    confidence: float = CONFIDENCE,
) -> pd.DataFrame:
    """Mean over participants, its bootstrap CI and the SD, per measure and condition.

    Each interval draws its resamples from a generator seeded by ``seed`` (BCa).

    Returns
    -------
    pandas.DataFrame
        Columns ``measure, condition, participants, mean, ci_low, ci_high, sd``, one row per
        measure and condition, in the given orders.
    """
    found = []
    for measure in measures:
        means = participant_means(rows, measure, conditions)
        for condition in conditions:
            values = means[condition].dropna().to_numpy()
            low, high = bootstrap_mean_ci(values, seed, resamples, confidence)
            found.append({
                "measure": measure, "condition": condition, "participants": values.size,
                "mean": _mean(values), "ci_low": low, "ci_high": high,
                "sd": float(np.std(values, ddof=1)) if values.size > 1 else float("nan"),
            })  # fmt: skip
    return pd.DataFrame(found)


@dataclass(frozen=True)
class Contrast:
    """One condition against the reference condition, for one measure.

    Parameters
    ----------
    measure, condition, reference
        What is compared.
    difference
        The mixed model's coefficient of the condition: its mean minus the reference's, in the
        measure's units, at equal position.
    ci_low, ci_high
        Its t confidence interval on ``df``.
    p
        Its t test's p-value on ``df``; ``p_holm`` the same, Holm-corrected over the measure's
        contrasts.
    standardised
        ``difference`` over the model's total SD (participant and residual variances summed).
    participants
        Participants with a mean in both conditions (the paired tests' n).
    reference_mean, condition_mean
        Means of those participants' means.
    d_z
        Cohen's d_z: mean of the paired differences over their SD.
    t, t_p
        Paired t-test of the participants' means; ``wilcoxon_p`` the Wilcoxon signed-rank test's.
    exploratory
        False for the declared hypothesis's contrast (`mirror_avatar.analysis.hypothesis`).
    q
        ``p`` adjusted by Benjamini-Hochberg across the study's exploratory contrasts; NaN for
        the confirmatory one and one not tested.
    df
        The t test's Satterthwaite degrees of freedom; NaN when not tested.
    """

    measure: str
    condition: str
    reference: str
    difference: float
    ci_low: float
    ci_high: float
    p: float
    p_holm: float
    standardised: float
    participants: int
    reference_mean: float
    condition_mean: float
    d_z: float
    t: float
    t_p: float
    wilcoxon_p: float
    exploratory: bool = True
    q: float = float("nan")
    df: float = float("nan")


@dataclass(frozen=True)
class FactorTest:
    """A coefficient of the partner's kind, or of condition x kind, in a measure's model.

    Parameters
    ----------
    measure, term
        The measure; the term (`mirror_avatar.analysis.partner_kind.KIND_TERM` or
        ``INTERACTION_TERM``).
    condition, kind, reference_kind
        What the coefficient compares: ``kind`` against ``reference_kind``, and for an
        interaction the non-reference ``condition``'s effect ("" for the kind's own term).
    estimate
        The coefficient, in the measure's units: a kind's mean minus the reference kind's,
        averaged over the conditions; an interaction, the condition's effect with the kind
        minus its effect with the reference kind.
    ci_low, ci_high, df, p
        Its t interval, Satterthwaite's degrees of freedom and two-sided p-value; ``p_holm``
        Holm-corrected over the term's coefficients in the measure.
    q
        ``p`` adjusted by Benjamini-Hochberg across the study's tests of kind and condition x
        kind (`mirror_avatar.analysis.study_report`); NaN until then.
    """

    measure: str
    term: str
    condition: str
    kind: str
    reference_kind: str
    estimate: float
    ci_low: float
    ci_high: float
    df: float
    p: float
    p_holm: float
    q: float = float("nan")


@dataclass(frozen=True)
class MeasureModel:
    """The mixed model of one measure and its contrasts.

    Parameters
    ----------
    measure
        The measure modelled.
    rows, participants
        Rows (trials) and participants it was fitted on.
    position_in_model
        Whether the position covariate was in the model (left out when it is constant or
        confounded with condition, which ``notes`` says).
    position_slope, position_p
        Change of the measure per step later in the order (measure units), its t test's p-value
        (Satterthwaite degrees of freedom).
    participant_variance, residual_variance
        The random intercept's variance (with slopes, the reference condition's participant
        variance) and the residual variance (units squared).
    contrasts
        Each condition against the reference.
    notes
        What the fit said (boundary, convergence) and what was left out, in plain words.
    random_effects
        The random effects fitted, in words (`mirror_avatar.analysis.random_effects`); empty
        when no model was fitted.
    partner_variance
        The variance of partner identity as a crossed random factor (units squared); NaN when
        it is not in the model.
    fixed_effects
        The fixed effects fitted, in words (`fixed_effects_words`); empty when no model was
        fitted.
    factors
        The tests of the partner's kind and of condition x kind, when they were in the model.
    converged
        Whether the fit converged (False also when no model was fitted); a verdict leaves out
        the contrasts of a fit that did not.
    """

    measure: str
    rows: int
    participants: int
    position_in_model: bool
    position_slope: float
    position_p: float
    participant_variance: float
    residual_variance: float
    contrasts: list[Contrast]
    notes: list[str] = field(default_factory=list)
    random_effects: str = ""
    partner_variance: float = float("nan")
    fixed_effects: str = ""
    factors: list[FactorTest] = field(default_factory=list)
    converged: bool = False


class Estimate(NamedTuple):
    """A contrast's estimate in the measure's units: value, t interval, p-value and its df."""

    value: float
    low: float
    high: float
    p: float
    df: float


def fit_contrasts(
    rows: pd.DataFrame,
    measure: str,
    conditions: Sequence[str],
    reference: str,
    confidence: float = CONFIDENCE,
) -> MeasureModel | None:
    """Fit ``measure ~ C(condition) + position`` with random effects per participant.

    The observations are the participant's trials (`trial_values`). When the trials have
    partners of several kinds (``partner_kind``), the kind and condition x kind are fixed
    effects too (`mirror_avatar.analysis.partner_kind.kind_terms`, docs/METHODS.md, section
    15.5), each coefficient tested as the conditions are.

    statsmodels' `MixedLM` fitted by REML; the reference condition is the treatment coding's
    baseline. The random effects are a random intercept, with random slopes for condition
    and for the partner's kind where the data support them (`fit_random_effects`;
    docs/METHODS.md, section 15.4). The
    fixed effects are tested by t tests with Satterthwaite's degrees of freedom, with t
    intervals (`satterthwaite_tests`; section 15.3). The model is fitted to the measure
    centred and divided by its SD, and its estimates scaled back (REML is equivariant, so
    nothing changes but the fit's boundary check: statsmodels flags a random-intercept
    variance under 0.01 in the outcome's units squared, here under 1 % of the measure's
    variance). Each
    contrast is cross-checked by a paired t-test and a Wilcoxon signed-rank test of the
    participants' means in the two conditions. A measure with the same value in every trial, or
    one that participant, condition and position explain exactly (no residual variance: a
    singular model), is not fitted, and a note says which: its contrasts have NaN estimates and
    keep their paired tests.

    Returns
    -------
    MeasureModel or None
        None when fewer than two conditions or two participants have values of ``measure``.
    """
    valid = rows.dropna(subset=[measure, "position"])
    data = trial_values(valid, measure)
    partners = trial_labels(valid, "partners")
    kinds = trial_labels(valid, "partner_kind")
    data = data[data["condition"].isin(conditions)]
    present = [c for c in conditions if c in set(data["condition"])]
    if reference not in present or len(present) < 2 or data["participant"].nunique() < 2:
        return None
    others = [c for c in present if c != reference]
    design, notes = _design(data, others)
    terms = kind_terms(
        design, pd.Series("", index=data.index) if kinds is None else kinds.loc[data.index],
        data["condition"], others,
    )  # fmt: skip
    design, notes = terms.design, notes + terms.notes
    values = data[measure].to_numpy(np.float64)
    means = participant_means(data, measure, present)
    if not has_spread(values):
        return _unfitted(data, measure, means, reference, notes + ["the same value in every trial"])
    sd = float(np.std(values))
    scaled = (values - values.mean()) / sd
    if _explained_exactly(scaled, design, data["participant"]):
        return _unfitted(data, measure, means, reference, notes + [NOISELESS])
    try:
        fitted = fit_random_effects(
            pd.Series(scaled, index=data.index), design, data["participant"], data["condition"],
            None if partners is None else partners.loc[data.index],
            None if kinds is None else kinds.loc[data.index],
            tuple(c for c, (term, _, _) in terms.columns.items() if term == KIND_TERM),
        )  # fmt: skip
    except (np.linalg.LinAlgError, ValueError) as error:
        failed = f"the mixed model could not be fitted ({' '.join(str(error).split())})"
        return _unfitted(data, measure, means, reference, notes + [failed])
    result = fitted.result
    notes += fitted.notes
    tests = dict(zip(design.columns[1:], satterthwaite_tests(result, np.eye(design.shape[1])[1:]),
                     strict=True))  # fmt: skip
    participant_variance = fitted.participant_variance * sd**2
    residual_variance = float(result.scale) * sd**2
    total_sd = float(np.sqrt(participant_variance + residual_variance))
    adjusted = holm([tests[c].p for c in others])
    contrasts = [
        _contrast(measure, condition, reference, means, _scaled(tests[condition], sd, confidence),
                  total_sd, float(p_holm))
        for condition, p_holm in zip(others, adjusted, strict=True)
    ]  # fmt: skip
    position = tests.get("position")
    factors = _factor_tests(measure, terms, tests, sd, confidence)
    return MeasureModel(
        measure=measure,
        rows=len(data),
        participants=int(data["participant"].nunique()),
        position_in_model=position is not None,
        position_slope=float("nan") if position is None else position.estimate * sd,
        position_p=float("nan") if position is None else position.p,
        participant_variance=participant_variance,
        residual_variance=residual_variance,
        contrasts=contrasts,
        notes=notes,
        random_effects=fitted.structure,
        partner_variance=fitted.partner_variance * sd**2,
        fixed_effects=fixed_effects_words(position is not None, terms),
        factors=factors,
        converged=bool(result.converged),
    )


def fixed_effects_words(position: bool, terms: KindTerms) -> str:
    """Say a measure's fixed effects as a formula in words.

    ``position``: whether the order covariate is in the model; ``terms`` the kind's
    (`kind_terms`).
    """
    said = {term for term, _, _ in terms.columns.values()}
    words = ["condition"] + ["position"] * position
    words += [t for t in (KIND_TERM, INTERACTION_TERM) if t in said]
    return "measure ~ " + " + ".join(words)


def _factor_tests(
    measure: str,
    terms: KindTerms,
    tests: dict[str, SmallSampleTest],
    sd: float,
    confidence: float,
) -> list[FactorTest]:
    """Test each kind and condition x kind coefficient, Holm-corrected within its term."""
    found = []
    for term in (KIND_TERM, INTERACTION_TERM):
        columns = [c for c, (t, _, _) in terms.columns.items() if t == term]
        adjusted = holm([tests[c].p for c in columns])
        for column, p_holm in zip(columns, adjusted, strict=True):
            estimate = _scaled(tests[column], sd, confidence)
            _, condition, kind = terms.columns[column]
            found.append(FactorTest(
                measure=measure, term=term, condition=condition, kind=kind,
                reference_kind=terms.reference,
                estimate=estimate.value, ci_low=estimate.low, ci_high=estimate.high,
                df=estimate.df, p=estimate.p, p_holm=float(p_holm),
            ))  # fmt: skip
    return found


def paired_effect(
    reference: NDArray[np.float64], condition: NDArray[np.float64]
) -> dict[str, float]:
    """Cohen's d_z, paired t-test and Wilcoxon signed-rank test of paired participant means.

    Returns
    -------
    dict
        ``d_z``, ``t``, ``t_p``, ``wilcoxon_p`` (two-sided); NaN when fewer than two pairs or
        when every difference is the same (no spread to scale by).
    """
    differences = np.asarray(condition, dtype=np.float64) - np.asarray(reference, dtype=np.float64)
    nan = float("nan")
    if differences.size < 2 or not has_spread(differences):
        return {"d_z": nan, "t": nan, "t_p": nan, "wilcoxon_p": nan}
    tested = stats.ttest_rel(condition, reference)
    signed_rank = stats.wilcoxon(differences) if np.any(differences != 0.0) else None
    return {
        "d_z": float(np.mean(differences) / np.std(differences, ddof=1)),
        "t": float(tested.statistic),
        "t_p": float(tested.pvalue),
        "wilcoxon_p": nan if signed_rank is None else float(signed_rank.pvalue),
    }


def _design(data: pd.DataFrame, others: list[str]) -> tuple[pd.DataFrame, list[str]]:
    """Fixed-effects design: intercept, a dummy per non-reference condition, then position."""
    design = pd.DataFrame({"Intercept": 1.0}, index=data.index)
    for condition in others:
        design[condition] = (data["condition"] == condition).astype(np.float64)
    with_position = design.assign(position=data["position"].astype(np.float64))
    if np.linalg.matrix_rank(with_position.to_numpy()) == with_position.shape[1]:
        return with_position, []
    if data["position"].nunique() == 1:
        why = "it is the same in every row"
    else:
        why = "it is confounded with condition (every participant met the conditions in one order)"
    return design, [f"order not checked: position left out of the model, {why}"]


def _explained_exactly(
    scaled: NDArray[np.float64], design: pd.DataFrame, participants: pd.Series
) -> bool:
    """Whether the fixed effects and a mean per participant explain ``scaled`` to rounding.

    Least squares of the values (centred, in SDs) on the fixed effects' ``design`` and a dummy
    per participant. With rows to spare (rank under the row count) and every residual within
    `EXACT_RESIDUAL` SDs, the mixed model has no residual variance to estimate: its likelihood
    is singular, and what statsmodels makes of it (an error, or a fit that does not converge)
    depends on the machine's BLAS.
    """
    dummies = pd.get_dummies(participants, dtype=np.float64).to_numpy()
    terms = np.column_stack([design.to_numpy(np.float64), dummies])
    solution, _, rank, _ = np.linalg.lstsq(terms, scaled, rcond=None)
    residuals = scaled - terms @ solution
    return bool(rank < scaled.size and np.max(np.abs(residuals)) <= EXACT_RESIDUAL)


def _scaled(test: SmallSampleTest, sd: float, confidence: float) -> Estimate:
    """Put a test of the model fitted in SDs back in the measure's units (estimate, interval)."""
    low, high = test.interval(confidence)
    return Estimate(test.estimate * sd, low * sd, high * sd, test.p, test.df)


def _unfitted(
    data: pd.DataFrame, measure: str, means: pd.DataFrame, reference: str, notes: list[str]
) -> MeasureModel:
    """Make the model of a measure that could not be fitted: NaN estimates, the paired tests."""
    nan = float("nan")
    estimate = Estimate(nan, nan, nan, nan, nan)
    others = [c for c in means.columns if c != reference]
    return MeasureModel(
        measure=measure, rows=len(data), participants=int(data["participant"].nunique()),
        position_in_model=False, position_slope=nan, position_p=nan, participant_variance=nan,
        residual_variance=nan,
        contrasts=[_contrast(measure, c, reference, means, estimate, nan, nan) for c in others],
        notes=notes,
    )  # fmt: skip


def _contrast(
    measure: str,
    condition: str,
    reference: str,
    means: pd.DataFrame,
    estimate: Estimate,
    total_sd: float,
    p_holm: float,
) -> Contrast:
    """Build a contrast from the model's ``estimate`` and its Holm-corrected p."""
    difference = estimate.value
    paired = means[[reference, condition]].dropna()
    before, after = paired[reference].to_numpy(), paired[condition].to_numpy()
    effect = paired_effect(before, after)
    return Contrast(
        measure=measure, condition=condition, reference=reference, difference=float(difference),
        ci_low=estimate.low, ci_high=estimate.high, p=estimate.p, p_holm=p_holm, df=estimate.df,
        standardised=float(difference) / total_sd if total_sd > 0 else float("nan"),
        participants=len(paired), reference_mean=_mean(before), condition_mean=_mean(after),
        d_z=effect["d_z"], t=effect["t"], t_p=effect["t_p"], wilcoxon_p=effect["wilcoxon_p"],
    )  # fmt: skip


def _mean(values: NDArray[np.float64]) -> float:
    return float(np.mean(values)) if values.size else float("nan")
