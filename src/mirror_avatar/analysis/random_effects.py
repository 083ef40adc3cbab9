"""A measure's random effects: random slopes for condition where the data support them.

The maximal model of a within-participant design has a random slope per participant for each
condition (Barr, Levy, Scheepers & Tily 2013): without it a condition is tested against the
trials' noise, and a handful of participants with many trials each gives tiny p-values. A slope
that the data do not support costs power instead (Matuschek, Kliegl, Vasishth, Baayen & Bates
2017), so `fit_random_effects` keeps the slopes only when the data can estimate them and a
likelihood-ratio test against the random intercept alone supports them; otherwise it fits the
random intercept and says why. A study whose participants meet partners of several kinds
(`mirror_avatar.analysis.partner_kind`) gets random slopes for the kind on the same terms,
tested against the model chosen without them. When several partners (the table's
``partners``) are each met by several participants, partner identity is a second random factor,
crossed with the participants, kept on the same terms. docs/METHODS.md, section 15.4.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from scipy import stats
from statsmodels.regression.mixed_linear_model import MixedLM, MixedLMResults, VCSpec
from statsmodels.tools.sm_exceptions import ConvergenceWarning

from mirror_avatar.analysis.small_sample import BOUNDARY

SLOPE_OPTIMISERS = ("lbfgs", "powell")
"""The optimisers tried in turn for the fit with slopes, until one converges (**choice**:
statsmodels' default, BFGS, stops short of the REML optimum of such fits more often, and
slower)."""

SELECTION_ALPHA = 0.2
"""Level of the likelihood-ratio tests that keep the slopes or the partners (**choice**:
Matuschek et al. 2017's, which kept the type 1 error at its nominal level and most of the
power)."""

INTERCEPT = "random intercept per participant"
SLOPES = "random intercept and correlated random slopes for condition per participant"
KIND_SLOPES = "random intercept and correlated random slopes for partner kind per participant"
BOTH_SLOPES = (
    "random intercept and correlated random slopes for condition and partner kind per participant"
)
STRUCTURES = {
    (False, False): INTERCEPT, (True, False): SLOPES,
    (False, True): KIND_SLOPES, (True, True): BOTH_SLOPES,
}  # fmt: skip
"""The participants' structure by (slopes for condition, slopes for partner kind)."""

CROSSED = "a random intercept per partner, crossed with the participants"
"""The random-effects structures, in words (the slopes uncorrelated with the intercept when
crossed with partners)."""

DEGENERATE_SHARE = 0.01
"""Smallest share of the random effects' variance the last principal component of their
covariance may hold (**choice**: Bates, Kliegl, Vasishth & Baayen 2015's rePCA reads a
component with next to none as a model too rich for its data; a correlation of -0.997 between
intercept and slope holds 0.1 %)."""

CROSSED_PARTNERS = 3
"""Fewest partners, each met by two participants or more, for partner identity as a random
factor (**choice**: a variance from two partners has one degree of freedom)."""


@dataclass(frozen=True)
class RandomEffects:
    """The fit chosen for a measure.

    Parameters
    ----------
    result
        The REML fit (statsmodels `MixedLM`).
    slopes
        Whether it has random slopes for condition.
    notes
        What the fit said (boundary, convergence) and, without slopes, why, in plain words.
    partners
        Whether partner identity is a crossed random factor: then ``result`` is one group of
        variance components (participants, each slope, partners).
    kind_slopes
        The design's partner-kind columns that are random slopes too (none: no such slopes).
    """

    result: MixedLMResults
    slopes: bool
    notes: list[str]
    partners: bool = False
    kind_slopes: tuple[str, ...] = ()

    @property
    def structure(self) -> str:
        """Say the random effects in words (`INTERCEPT`, `SLOPES`, `KIND_SLOPES`, `BOTH_SLOPES`).

        With partners, `CROSSED` is added and the slopes are uncorrelated.
        """
        words = STRUCTURES[self.slopes, bool(self.kind_slopes)]
        if not self.partners:
            return words
        return f"{words.replace('correlated', 'uncorrelated')}, and {CROSSED}"

    @property
    def participant_variance(self) -> float:
        """The participants' intercept variance, in the fitted outcome's units squared."""
        if self.partners:
            return float(np.asarray(self.result.vcomp)[0])
        return float(np.asarray(self.result.cov_re)[0, 0])

    @property
    def partner_variance(self) -> float:
        """The partners' variance (NaN without them), in the fitted outcome's units squared."""
        return float(np.asarray(self.result.vcomp)[-1]) if self.partners else float("nan")


def fit_random_effects(
    values: pd.Series,
    design: pd.DataFrame,
    participants: pd.Series,
    conditions: pd.Series,
    partners: pd.Series | None = None,
    kinds: pd.Series | None = None,
    kind_columns: tuple[str, ...] = (),
) -> RandomEffects:
    """Fit ``values`` on ``design`` with slopes for condition if supported, else without.

    Parameters
    ----------
    values
        The outcome, one per trial (N).
    design
        The fixed effects (N x p): ``Intercept``, a dummy per non-reference condition, then
        any covariates.
    participants, conditions
        Each trial's participant and condition (N).
    partners
        Each trial's partner identity (N); None, or one partner, for none.
    kinds, kind_columns
        Each trial's partner kind (N), and the design's columns of the kinds (their centred
        indicators); slopes for the kind are tried with them (`fit_kind_slopes`).

    The slopes are the non-reference conditions' dummies as random effects with the intercept,
    their covariance unstructured. They are tried when every condition's values can vary by
    participant apart from the trials' noise (`unsupported`), and kept when their fit
    converged, their covariance is not singular (each pivot of its Cholesky factor above
    `BOUNDARY` of the residual variance, a random-effects variance not on 0) nor degenerate
    (its smallest principal component holds `DEGENERATE_SHARE` of the variance or more) and the
    REML likelihood-ratio test against the intercept alone has p < `SELECTION_ALPHA`
    (chi-square on the added covariance parameters; both fits have the same fixed effects, so
    their REML likelihoods compare). The kinds' slopes are then tried (`fit_kind_slopes`), then
    partners (`fit_partners`).

    Raises
    ------
    numpy.linalg.LinAlgError, ValueError
        The random intercept's fit failed (statsmodels' errors).
    """
    chosen = _participant_effects(values, design, participants, conditions)
    if kinds is not None and kind_columns:
        chosen = fit_kind_slopes(
            chosen, values, design, participants, conditions, kinds, kind_columns
        )
    if partners is None or partners.nunique() < 2:
        return chosen
    return fit_partners(chosen, values, design, participants, conditions, partners)


def _participant_effects(
    values: pd.Series, design: pd.DataFrame, participants: pd.Series, conditions: pd.Series
) -> RandomEffects:
    """Fit the participants' random effects: slopes if supported, else the intercept."""
    effects = _effects(design, conditions)
    intercept, caught = _fit(values, design, participants, None)
    why = unsupported(participants, conditions)
    if why is None:
        try:
            slopes, slope_caught = _fit(
                values, design, participants, design[["Intercept", *effects]]
            )
        except (np.linalg.LinAlgError, ValueError) as error:
            why = f"their fit failed ({' '.join(str(error).split())})"
        else:
            why = _rejected(slopes, intercept)
            if why is None:
                return RandomEffects(slopes, True, fit_notes(slope_caught, slopes))
    fallback = f"no random slopes for condition: {why}; a random intercept only"
    return RandomEffects(intercept, False, [*fit_notes(caught, intercept), fallback])


def fit_kind_slopes(
    chosen: RandomEffects,
    values: pd.Series,
    design: pd.DataFrame,
    participants: pd.Series,
    conditions: pd.Series,
    kinds: pd.Series,
    kind_columns: tuple[str, ...],
) -> RandomEffects:
    """Add random slopes for the partner's kind to ``chosen``'s, if supported.

    The slopes are the kind's columns of the design, correlated with the intercept and with
    ``chosen``'s slopes for condition if it has them. They are tried when the data can
    estimate them (`unsupported` on the kinds, the covariance's size counting every slope) and
    kept on `_rejected`'s terms, the likelihood-ratio test against ``chosen``'s fit.
    Otherwise ``chosen`` is returned with a note why.
    """
    slopes = [*(_effects(design, conditions) if chosen.slopes else []), *kind_columns]
    why = unsupported(participants, kinds, len(slopes) + 1, "partner kind")
    if why is None:
        try:
            fitted, caught = _fit(values, design, participants, design[["Intercept", *slopes]])
        except (np.linalg.LinAlgError, ValueError) as error:
            why = f"their fit failed ({' '.join(str(error).split())})"
        else:
            why = _rejected(fitted, chosen.result)
            if why is None:
                notes = fit_notes(caught, fitted)
                return RandomEffects(fitted, chosen.slopes, notes, kind_slopes=kind_columns)
    note = f"no random slopes for partner kind: {why}"
    return replace(chosen, notes=[*chosen.notes, note])


def fit_partners(
    chosen: RandomEffects,
    values: pd.Series,
    design: pd.DataFrame,
    participants: pd.Series,
    conditions: pd.Series,
    partners: pd.Series,
) -> RandomEffects:
    """Add partner identity as a random factor crossed with the participants, if supported.

    statsmodels fits crossed factors as variance components of a single group: each
    participant's intercept, each participant's slope per non-reference condition (when
    ``chosen`` has slopes; uncorrelated here), and each partner's intercept. The partners are
    tried when at least `CROSSED_PARTNERS` partners are each met by two participants or more,
    and kept when the fit converged, the partners' variance is above `BOUNDARY` of the residual
    variance and the REML likelihood-ratio test against the same model without partners has
    p < `SELECTION_ALPHA` (chi-square on 1). Otherwise ``chosen`` is returned with a note why.
    """
    met = participants.groupby(partners).nunique()
    crossed = int((met >= 2).sum())
    why: str | None
    if crossed < CROSSED_PARTNERS:
        why = (f"{crossed} partners met by two participants or more, fewer than "
               f"{CROSSED_PARTNERS}")  # fmt: skip
    else:
        slopes = [*(_effects(design, conditions) if chosen.slopes else []), *chosen.kind_slopes]
        try:
            with_partners, caught = _fit_crossed(values, design, participants, slopes, partners)
            without, _ = _fit_crossed(values, design, participants, slopes, None)
        except (np.linalg.LinAlgError, ValueError) as error:
            why = f"its fit failed ({' '.join(str(error).split())})"
        else:
            why = _partners_rejected(with_partners, without)
            if why is None:
                notes = fit_notes(caught, with_partners)
                return replace(chosen, result=with_partners, notes=notes, partners=True)
    return replace(chosen, notes=[*chosen.notes, f"no random effect of partner identity: {why}"])


def unsupported(
    participants: pd.Series, levels: pd.Series, size: int | None = None, factor: str = "condition"
) -> str | None:
    """Say why the data cannot estimate slopes for a factor, or None when they can.

    ``levels``: each trial's level of ``factor`` (a condition or a partner kind). The slopes'
    covariance has
    q (q + 1) / 2 parameters (q = ``size``, by default the c levels: the intercept and c - 1
    slopes), estimated from each participant's means; a covariance of q-vectors needs at least
    q + 1 of them, so q + 1 participants with values at every level. A slope is told apart
    from the trials' noise only by repeated trials: more trials than participant-level cells.
    """
    cells = pd.crosstab(participants, levels)
    count = cells.shape[1] if size is None else size
    complete = int((cells > 0).all(axis=1).sum())
    if complete < count + 1:
        return (f"{complete} participants with every {factor}, fewer than the {count + 1} "
                f"that the slopes' covariance needs")  # fmt: skip
    if len(participants) <= int((cells > 0).sum().sum()):
        return f"one trial per participant and {factor}, so a slope is not apart from the noise"
    return None


def fit_notes(caught: list[warnings.WarningMessage], result: MixedLMResults) -> list[str]:
    """Say what a fit's warnings mean: a boundary fit, a fit that did not converge."""
    texts = [str(w.message) for w in caught if issubclass(w.category, ConvergenceWarning)]
    notes = []
    if any("boundary" in text for text in texts):
        notes.append("mixed model: the participants' variance is near 0 (a boundary fit)")
    if not result.converged:
        notes.append("mixed model: the fit did not converge, so its p-values are not reliable")
    return notes


def _fit(
    values: pd.Series,
    design: pd.DataFrame,
    participants: pd.Series,
    random: pd.DataFrame | None,
) -> tuple[MixedLMResults, list[warnings.WarningMessage]]:
    """Fit by REML, recording the fit's warnings."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = MixedLM(values, design, groups=participants, exog_re=random)
        result = (
            model.fit(reml=True)
            if random is None
            else model.fit(reml=True, method=list(SLOPE_OPTIMISERS))
        )
    return result, caught


def _effects(design: pd.DataFrame, conditions: pd.Series) -> list[str]:
    """List the design's columns of the non-reference conditions."""
    return [c for c in design.columns if c != "Intercept" and c in set(conditions)]


def _fit_crossed(
    values: pd.Series,
    design: pd.DataFrame,
    participants: pd.Series,
    slopes: list[str],
    partners: pd.Series | None,
) -> tuple[MixedLMResults, list[warnings.WarningMessage]]:
    """Fit one group of variance components by REML: participants, their slopes, partners."""
    dummies = pd.get_dummies(participants, dtype=np.float64)
    components = {"participant": dummies.to_numpy()}
    for effect in slopes:
        components[f"participant:{effect}"] = dummies.to_numpy() * design[[effect]].to_numpy()
    if partners is not None:
        components["partner"] = pd.get_dummies(partners, dtype=np.float64).to_numpy()
    names = list(components)
    spec = VCSpec(names, [[f"{n}{j}" for j in range(m.shape[1])] for n, m in components.items()],
                  [[m] for m in components.values()])  # fmt: skip
    rows = len(values)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = MixedLM(values, design, groups=np.zeros(rows), exog_re=np.zeros((rows, 0)),
                        exog_vc=spec)  # fmt: skip
        result = model.fit(reml=True, method=list(SLOPE_OPTIMISERS))
    return result, caught


def _partners_rejected(with_partners: MixedLMResults, without: MixedLMResults) -> str | None:
    """Say why the fit with partners is not kept, or None when it is."""
    if not with_partners.converged:
        return "its fit did not converge"
    if float(np.asarray(with_partners.vcomp)[-1]) <= BOUNDARY * float(with_partners.scale):
        return "the partners' variance is on 0"
    return _not_supported(with_partners, without, 1)


def _not_supported(larger: MixedLMResults, smaller: MixedLMResults, added: int) -> str | None:
    """Say why the REML likelihood-ratio test does not support ``larger``, or None."""
    ratio = max(0.0, 2.0 * (float(larger.llf) - float(smaller.llf)))
    p = float(stats.chi2.sf(ratio, added))
    if p >= SELECTION_ALPHA:
        return (f"not supported by the data (REML likelihood-ratio test p = {p:.2f}, at "
                f"least {SELECTION_ALPHA:g})")  # fmt: skip
    return None


def _rejected(slopes: MixedLMResults, intercept: MixedLMResults) -> str | None:
    """Say why the fit with slopes is not kept, or None when it is.

    ``intercept`` is the fit with fewer random effects, nested in ``slopes``'s.
    """
    if not slopes.converged:
        return "their fit did not converge"
    covariance = np.asarray(slopes.cov_re, dtype=np.float64) / float(slopes.scale)
    try:
        pivots = np.diag(np.linalg.cholesky(covariance)) ** 2
    except np.linalg.LinAlgError:
        pivots = np.zeros(1)
    if np.min(pivots) <= BOUNDARY:
        return "their covariance is singular (a variance on 0)"
    shares = np.linalg.eigvalsh(covariance) / np.trace(covariance)
    if shares[0] < DEGENERATE_SHARE:
        return (f"their covariance is degenerate (its smallest principal component holds "
                f"{shares[0]:.1%} of the random effects' variance)")  # fmt: skip
    size, before = covariance.shape[0], np.asarray(intercept.cov_re).shape[0]
    added = size * (size + 1) // 2 - before * (before + 1) // 2
    return _not_supported(slopes, intercept, added)
