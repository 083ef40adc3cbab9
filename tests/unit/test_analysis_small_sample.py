"""Satterthwaite's degrees of freedom for a mixed model's t tests, against independent truth.

On balanced designs the t test of a within-participant condition is exact, and known: with one
value per participant and condition it is the paired t-test (n - 1 df); with several trials per
cell and a random slope for condition, the paired t-test of the cell means (n - 1 df); with a
random intercept only, the fixed-effects analysis with a dummy per participant (N - n - 1 df);
with the participants' variance at 0, ordinary least squares (N - p df). On an unbalanced design
the df are checked against lmerTest's computation written out slowly here: numerical derivatives
of the REML deviance and of C in lme4's parameters (the SDs), not the variances.

Tolerances: statsmodels' REML optimiser stops within about 1e-5 (relative) of the optimum, so t
agrees to 1e-4 relative, p to 1e-4 absolute and the df to 0.01; the slow reference's central
differences (step 1e-4) agree to 1e-3 relative.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest
import statsmodels.api as sm
from numpy.typing import NDArray
from scipy import stats
from statsmodels.regression.mixed_linear_model import MixedLM, MixedLMResults
from statsmodels.tools.sm_exceptions import ConvergenceWarning

from mirror_avatar.analysis.small_sample import satterthwaite_tests


def two_conditions(
    seed: int, participants: int = 8, trials: int = 1, slope_sd: float = 0.0
) -> pd.DataFrame:
    """A balanced study: a value per participant, condition (0, 1) and trial.

    Participants' levels of SD 1 (far above the noise, so their variance is not on the
    boundary), a condition effect of 0.3 varying by participant with ``slope_sd``, noise 0.5.
    """
    rng = np.random.default_rng(seed)
    level = rng.normal(0.0, 1.0, participants)
    slope = 0.3 + rng.normal(0.0, slope_sd, participants)
    rows = [
        (i, c, level[i] + slope[i] * c + rng.normal(0.0, 0.5))
        for i in range(participants) for c in (0, 1) for _ in range(trials)
    ]  # fmt: skip
    return pd.DataFrame(rows, columns=["participant", "condition", "y"])


def fit(data: pd.DataFrame, slopes: bool = False) -> MixedLMResults:
    design = np.column_stack([np.ones(len(data)), data["condition"]])
    with warnings.catch_warnings():  # boundary fits are the point of one test
        warnings.simplefilter("ignore", ConvergenceWarning)
        return MixedLM(data["y"].to_numpy(), design, groups=data["participant"],
                       exog_re=design if slopes else None).fit(reml=True)  # fmt: skip


def paired(data: pd.DataFrame) -> tuple[float, float]:
    """The paired t-test of the participants' cell means: t and p."""
    means = data.groupby(["participant", "condition"])["y"].mean().unstack()
    tested = stats.ttest_rel(means[1], means[0])
    return float(tested.statistic), float(tested.pvalue)


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize(("trials", "slopes"), [(1, False), (4, True)])
def test_balanced_two_conditions_are_the_paired_t_test(
    seed: int, trials: int, slopes: bool
) -> None:
    """One value per cell with a random intercept; or trials per cell with a random slope for
    condition, the balanced split-plot, condition tested against the participant x condition
    stratum: both the paired t-test of the cell means, on n - 1 = 7 df."""
    data = two_conditions(seed, trials=trials, slope_sd=0.5 if slopes else 0.0)
    (test,) = satterthwaite_tests(fit(data, slopes=slopes), [[0.0, 1.0]])
    t, p = paired(data)
    assert test.t == pytest.approx(t, rel=1e-4)
    assert test.df == pytest.approx(7.0, abs=0.01)
    assert test.p == pytest.approx(p, abs=1e-4)


@pytest.mark.parametrize("seed", range(3))
def test_trials_with_a_random_intercept_are_the_fixed_effects_analysis(seed: int) -> None:
    """Balanced: the condition within participants is tested against the residual."""
    data = two_conditions(seed, trials=4)
    (test,) = satterthwaite_tests(fit(data), [[0.0, 1.0]])
    dummies = pd.get_dummies(data["participant"], dtype=float).to_numpy()
    ols = sm.OLS(data["y"].to_numpy(), np.column_stack([dummies, data["condition"]])).fit()
    assert test.t == pytest.approx(ols.tvalues[-1], rel=1e-4)
    assert test.df == pytest.approx(ols.df_resid, abs=0.01)  # 64 - 8 - 1 = 55
    assert test.p == pytest.approx(ols.pvalues[-1], abs=1e-4)


def test_participants_variance_on_the_boundary_gives_least_squares() -> None:
    """Each participant's mean taken out: REML puts their variance at 0, and the test is OLS's."""
    data = two_conditions(3, trials=3)
    data["y"] -= data.groupby("participant")["y"].transform("mean")
    result = fit(data)
    assert np.asarray(result.cov_re)[0, 0] < 1e-4 * result.scale
    (test,) = satterthwaite_tests(result, [[0.0, 1.0]])
    ols = sm.OLS(data["y"].to_numpy(), sm.add_constant(data["condition"].to_numpy())).fit()
    assert test.t == pytest.approx(ols.tvalues[1], rel=1e-4)
    assert test.df == pytest.approx(ols.df_resid, abs=0.01)


def test_an_unbalanced_design_has_lmertests_df() -> None:
    data = two_conditions(11, participants=10, trials=3, slope_sd=0.0)
    data = data.drop(index=np.random.default_rng(0).choice(len(data), 17, replace=False))
    result = fit(data)
    (test,) = satterthwaite_tests(result, [[0.0, 1.0]])
    t, df = lmertest(result, np.array([0.0, 1.0]))
    assert 8.0 < test.df < len(data) - 2
    assert test.df == pytest.approx(df, rel=1e-3)
    assert test.t == pytest.approx(t, rel=1e-9)


def test_interval_is_the_t_interval() -> None:
    data = two_conditions(2)
    (test,) = satterthwaite_tests(fit(data), [[0.0, 1.0]])
    means = data.groupby(["participant", "condition"])["y"].mean().unstack()
    differences = (means[1] - means[0]).to_numpy()
    low, high = stats.t.interval(0.95, 7, differences.mean(), stats.sem(differences))
    assert test.interval(0.95) == pytest.approx((low, high), rel=1e-3)


def lmertest(result: MixedLMResults, contrast: NDArray[np.float64]) -> tuple[float, float]:
    """lmerTest's t and Satterthwaite df, slowly: numerical derivatives in lme4's parameters.

    The parameters are the participants' SD and the residual SD; t = L' beta / sqrt(L' C L) with
    beta and C = (X' V^-1 X)^-1 of generalised least squares at the fit's variances (lme4's
    vcov: statsmodels' own standard errors come from the inverse of its observed Hessian and
    differ at the fourth digit on an unbalanced design).
    A = 2 H^-1, H the Hessian of the REML deviance; g the gradient of L' C L (Kuznetsova et al.
    2017; Christensen's note on Satterthwaite's method for LMMs).
    """
    model = result.model
    design = np.vstack(model.exog_li)
    outcome = np.concatenate(model.endog_li)
    sizes = [len(y) for y in model.endog_li]
    members = np.repeat(np.arange(len(sizes)), sizes)
    same = (members[:, None] == members[None, :]).astype(float)

    def covariance(sds: NDArray[np.float64]) -> NDArray[np.float64]:
        return sds[0] ** 2 * same + sds[1] ** 2 * np.eye(len(outcome))

    def deviance(sds: NDArray[np.float64]) -> float:
        inverse = np.linalg.inv(covariance(sds))
        information = design.T @ inverse @ design
        beta = np.linalg.solve(information, design.T @ inverse @ outcome)
        residual = outcome - design @ beta
        return float(np.linalg.slogdet(covariance(sds))[1] + np.linalg.slogdet(information)[1]
                     + residual @ inverse @ residual)  # fmt: skip

    def contrast_variance(sds: NDArray[np.float64]) -> float:
        fixed = np.linalg.inv(design.T @ np.linalg.inv(covariance(sds)) @ design)
        return float(contrast @ fixed @ contrast)

    sds = np.sqrt([float(np.asarray(result.cov_re)[0, 0]), float(result.scale)])
    step = 1e-4
    basis = np.eye(2) * step
    hessian = np.array([[
        (deviance(sds + a + b) - deviance(sds + a - b) - deviance(sds - a + b)
         + deviance(sds - a - b)) / (4 * step**2)
        for b in basis] for a in basis])  # fmt: skip
    gradient = np.array(
        [(contrast_variance(sds + a) - contrast_variance(sds - a)) / (2 * step) for a in basis]
    )
    spread = 2.0 * np.linalg.inv(hessian)
    inverse = np.linalg.inv(covariance(sds))
    beta = np.linalg.solve(design.T @ inverse @ design, design.T @ inverse @ outcome)
    variance = contrast_variance(sds)
    return (float(contrast @ beta) / np.sqrt(variance),
            2.0 * variance**2 / float(gradient @ spread @ gradient))  # fmt: skip


@pytest.mark.parametrize("slopes", [False, True])
def test_summed_over_participants_it_is_the_dense_computation(slopes: bool) -> None:
    """The groups' sums give the df of the formulas on the whole N x N covariance, to rounding.

    The reference builds V and its derivatives densely from the rows (same participant: Z G Z';
    every row: the residual variance) and takes the Hessian and C's derivatives as written in
    docs/METHODS.md, section 15.3.
    """
    data = two_conditions(5, participants=9, trials=4, slope_sd=0.5 if slopes else 0.0)
    data = data.drop(index=np.random.default_rng(1).choice(len(data), 11, replace=False))
    result = fit(data, slopes=slopes)
    (test,) = satterthwaite_tests(result, [[0.0, 1.0]])
    t, df = dense_satterthwaite(result, np.array([0.0, 1.0]))
    assert test.t == pytest.approx(t, rel=1e-10)
    assert test.df == pytest.approx(df, rel=1e-10)


def dense_satterthwaite(
    result: MixedLMResults, contrast: NDArray[np.float64]
) -> tuple[float, float]:
    """t and Satterthwaite's df of ``contrast`` from N x N matrices, in the variances."""
    model = result.model
    design = np.vstack(model.exog_li)
    outcome = np.concatenate(model.endog_li)
    effects = np.vstack(model.exog_re_li)
    members = np.repeat(np.arange(model.n_groups), [len(y) for y in model.endog_li])
    same = members[:, None] == members[None, :]
    random = np.atleast_2d(np.asarray(result.cov_re))
    parts, estimates = [], []
    for a in range(random.shape[0]):
        for b in range(a + 1):
            outer = np.outer(effects[:, a], effects[:, b])
            parts.append(same * (outer if a == b else outer + outer.T))
            estimates.append(random[a, b])
    parts.append(np.eye(len(outcome)))
    estimates.append(float(result.scale))
    inverse = np.linalg.inv(sum(e * p for e, p in zip(estimates, parts, strict=True)))
    fixed = np.linalg.inv(design.T @ inverse @ design)
    projection = inverse - inverse @ design @ fixed @ design.T @ inverse
    hessian = np.array([[
        -0.5 * np.trace(projection @ pj @ projection @ pk)
        + outcome @ projection @ pj @ projection @ pk @ projection @ outcome
        for pk in parts] for pj in parts])  # fmt: skip
    gradient = np.array([contrast @ fixed @ design.T @ inverse @ p @ inverse @ design @ fixed
                         @ contrast for p in parts])  # fmt: skip
    variance = float(contrast @ fixed @ contrast)
    beta = fixed @ design.T @ inverse @ outcome
    df = 2.0 * variance**2 / float(gradient @ np.linalg.pinv(hessian) @ gradient)
    return float(contrast @ beta) / np.sqrt(variance), df
