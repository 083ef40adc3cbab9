"""A measure's random effects: random slopes for condition where the data support them.

The maximal model of a within-participant design has a random slope per participant for each
condition (Barr, Levy, Scheepers & Tily 2013): without it a condition is tested against the
trials' noise, and a handful of participants with many trials each gives tiny p-values. A slope
that the data do not support costs power instead (Matuschek, Kliegl, Vasishth, Baayen & Bates
2017), so `fit_random_effects` keeps the slopes only when the data can estimate them and a
likelihood-ratio test against the random intercept alone supports them; otherwise it fits the
random intercept and says why. docs/METHODS.md, section 15.4.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats
from statsmodels.regression.mixed_linear_model import MixedLM, MixedLMResults
from statsmodels.tools.sm_exceptions import ConvergenceWarning

from mirror_avatar.analysis.small_sample import BOUNDARY

SLOPE_OPTIMISERS = ("lbfgs", "powell")
"""The optimisers tried in turn for the fit with slopes, until one converges (**choice**:
statsmodels' default, BFGS, stops short of the REML optimum of such fits more often, and
slower)."""

SLOPE_ALPHA = 0.2
"""Level of the likelihood-ratio test that keeps the slopes (**choice**: Matuschek et al.
2017's, which kept the type 1 error at its nominal level and most of the power)."""

INTERCEPT = "random intercept per participant"
SLOPES = "random intercept and correlated random slopes for condition per participant"
"""The two random-effects structures, in words."""


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
    """

    result: MixedLMResults
    slopes: bool
    notes: list[str]

    @property
    def structure(self) -> str:
        """Say the random effects in words (`INTERCEPT` or `SLOPES`)."""
        return SLOPES if self.slopes else INTERCEPT


def fit_random_effects(
    values: pd.Series, design: pd.DataFrame, participants: pd.Series, conditions: pd.Series
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

    The slopes are the non-reference conditions' dummies as random effects with the intercept,
    their covariance unstructured. They are tried when every condition's values can vary by
    participant apart from the trials' noise (`unsupported`), and kept when their fit
    converged, their covariance is not singular (each pivot of its Cholesky factor above
    `BOUNDARY` of the residual variance, a random-effects variance not on 0) and the REML
    likelihood-ratio test against the intercept alone has p < `SLOPE_ALPHA` (chi-square on the
    added covariance parameters; both fits have the same fixed effects, so their REML
    likelihoods compare).

    Raises
    ------
    numpy.linalg.LinAlgError, ValueError
        The random intercept's fit failed (statsmodels' errors).
    """
    effects = [c for c in design.columns if c != "Intercept" and c in set(conditions)]
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


def unsupported(participants: pd.Series, conditions: pd.Series) -> str | None:
    """Say why the data cannot estimate slopes for condition, or None when they can.

    The slopes' covariance has c (c + 1) / 2 parameters (c conditions), estimated from each
    participant's c condition means; a covariance of c-vectors needs at least c + 1 of them, so
    c + 1 participants with values in every condition. A slope is told apart from the trials'
    noise only by repeated trials: more trials than participant-condition cells.
    """
    cells = pd.crosstab(participants, conditions)
    count = cells.shape[1]
    complete = int((cells > 0).all(axis=1).sum())
    if complete < count + 1:
        return (f"{complete} participants with every condition, fewer than the {count + 1} "
                f"that the slopes' covariance needs")  # fmt: skip
    if len(participants) <= int((cells > 0).sum().sum()):
        return "one trial per participant and condition, so a slope is not apart from the noise"
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


def _rejected(slopes: MixedLMResults, intercept: MixedLMResults) -> str | None:
    """Say why the fit with slopes is not kept, or None when it is."""
    if not slopes.converged:
        return "their fit did not converge"
    covariance = np.asarray(slopes.cov_re, dtype=np.float64) / float(slopes.scale)
    try:
        pivots = np.diag(np.linalg.cholesky(covariance)) ** 2
    except np.linalg.LinAlgError:
        pivots = np.zeros(1)
    if np.min(pivots) <= BOUNDARY:
        return "their covariance is singular (a variance on 0)"
    added = covariance.shape[0] * (covariance.shape[0] + 1) // 2 - 1
    ratio = max(0.0, 2.0 * (float(slopes.llf) - float(intercept.llf)))
    p = float(stats.chi2.sf(ratio, added))
    if p >= SLOPE_ALPHA:
        return (f"the data do not support them (REML likelihood-ratio test p = {p:.2f}, at least "
                f"{SLOPE_ALPHA:g})")  # fmt: skip
    return None
