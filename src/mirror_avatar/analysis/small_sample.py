"""Small-sample t tests of a linear mixed model's fixed effects: Satterthwaite's degrees of freedom.

A contrast L'beta of a REML fit is tested by t = L'beta / sqrt(L' C L), C the covariance of the
fixed effects, against a t distribution whose degrees of freedom match the variance of
L' C L to a scaled chi-square's (Satterthwaite 1946; lmerTest's method, Kuznetsova, Brockhoff &
Christensen 2017): df = 2 f^2 / (g' A g), f = L' C L, g its gradient with respect to the
variance parameters and A their asymptotic covariance, the inverse of the Hessian of the negative
REML log-likelihood. docs/METHODS.md, section 15.3.

lmerTest differentiates numerically in lme4's parameters (relative Cholesky factors and the
residual SD); here the parameters are the variances and covariances themselves, in which the
covariance of the observations is linear, so that the gradient and the Hessian are exact
formulas. At an interior REML optimum the two give the same df (the delta method's variance is
invariant under a change of parameters there). A variance on the boundary (at most
`BOUNDARY` of the residual variance) is held at its estimate and is no parameter of the df, as
its direction adds nothing to lmerTest's sum where the Cholesky factor is 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats
from scipy.linalg import block_diag
from statsmodels.regression.mixed_linear_model import MixedLMResults

BOUNDARY = 1e-4
"""A random effect's variance at most this share of the residual variance is on the boundary
(**choice**: statsmodels' REML optimiser stops a little above 0, not at 0, when the optimum is
there; this is two orders of magnitude above where it stops)."""

EIGENVALUE_TOLERANCE = 1e-8
"""Eigenvalues of the Hessian at most this share of its largest are left out of its inverse
(a Moore-Penrose inverse over the positive ones, as lmerTest's)."""


@dataclass(frozen=True)
class SmallSampleTest:
    """The t test of one contrast of the fixed effects.

    Parameters
    ----------
    estimate
        L'beta, in the outcome's units.
    se
        Its standard error, sqrt(L' C L).
    t
        estimate / se.
    df
        Satterthwaite's degrees of freedom.
    p
        Two-sided p-value of t on df degrees of freedom.
    """

    estimate: float
    se: float
    t: float
    df: float
    p: float

    def interval(self, confidence: float) -> tuple[float, float]:
        """Return the t interval of the estimate at ``confidence`` (on ``df``)."""
        half = float(stats.t.ppf(0.5 + confidence / 2.0, self.df)) * self.se
        return (self.estimate - half, self.estimate + half)


@dataclass(frozen=True)
class _Covariance:
    """The covariance of the observations as a linear function of the variance parameters.

    ``parts[j]`` is the derivative of the covariance (N x N, rows in the model's group order) by
    parameter j; ``estimates[j]`` the parameter's REML estimate; ``free[j]`` whether it is a
    parameter of the df (not on the boundary).
    """

    parts: list[NDArray[np.float64]]
    estimates: NDArray[np.float64]
    free: NDArray[np.bool_]

    def matrix(self) -> NDArray[np.float64]:
        """Return the covariance at the estimates (N x N)."""
        return np.einsum("j,jmn->mn", self.estimates, np.asarray(self.parts))


def satterthwaite_tests(result: MixedLMResults, contrasts: ArrayLike) -> list[SmallSampleTest]:
    """Test each row of ``contrasts`` (shape (m, p), p the fixed effects) on a REML fit.

    ``result`` is a statsmodels `MixedLM` fit by REML: random effects per group (``exog_re``),
    variance components (``exog_vc``) and a residual variance. Its variance parameters are taken
    as they are; beta and C = (X' V^-1 X)^-1 are those of generalised least squares at them (as
    lme4's, and statsmodels' estimates; statsmodels' standard errors come from the inverse of its
    observed Hessian instead, and differ slightly on an unbalanced design).

    Returns
    -------
    list of SmallSampleTest
        One per contrast, in order.
    """
    weights = np.atleast_2d(np.asarray(contrasts, dtype=np.float64))
    model = result.model
    design = np.vstack(model.exog_li)
    outcome = np.concatenate(model.endog_li)
    covariance = _covariance(result)
    beta, fixed, jacobian, hessian = _reml_pieces(design, outcome, covariance)
    spread = _inverse_positive(hessian)
    tests = []
    for row in weights:
        variance = float(row @ fixed @ row)
        gradient = np.array([row @ part @ row for part in jacobian])
        df = 2.0 * variance**2 / float(gradient @ spread @ gradient)
        estimate = float(row @ beta)
        se = float(np.sqrt(variance))
        t = estimate / se
        tests.append(SmallSampleTest(estimate, se, t, df, float(2.0 * stats.t.sf(abs(t), df))))
    return tests


def _covariance(result: MixedLMResults) -> _Covariance:
    """Write the observations' covariance as a sum of parameters times their derivatives.

    Parameters: the random effects' covariance matrix (each variance and covariance, lower
    triangle), then each variance component, then the residual variance.
    """
    model = result.model
    groups = range(model.n_groups)
    random = np.atleast_2d(np.asarray(result.cov_re, dtype=np.float64))
    scale = float(result.scale)
    parts, estimates, free = [], [], []
    for a in range(random.shape[0]):
        for b in range(a + 1):
            blocks = [_pair(model.exog_re_li[i], a, b) for i in groups]
            parts.append(block_diag(*blocks))
            estimates.append(random[a, b])
            free.append(min(random[a, a], random[b, b]) > BOUNDARY * scale)
    for j, variance in enumerate(np.asarray(result.vcomp, dtype=np.float64)):
        mats = model.exog_vc.mats[j]
        parts.append(block_diag(*[mats[i] @ mats[i].T for i in groups]))
        estimates.append(variance)
        free.append(variance > BOUNDARY * scale)
    parts.append(np.eye(sum(len(y) for y in model.endog_li)))
    estimates.append(scale)
    free.append(True)
    return _Covariance(parts, np.array(estimates), np.array(free))


def _pair(columns: NDArray[np.float64], a: int, b: int) -> NDArray[np.float64]:
    """Return the derivative of Z G Z' by G[a, b] and G[b, a] (one parameter), Z ``columns``."""
    outer = np.outer(columns[:, a], columns[:, b])
    return outer if a == b else outer + outer.T


def _reml_pieces(
    design: NDArray[np.float64], outcome: NDArray[np.float64], covariance: _Covariance
) -> tuple[
    NDArray[np.float64], NDArray[np.float64], list[NDArray[np.float64]], NDArray[np.float64]
]:
    """Return beta, C, C's derivatives and the Hessian of the negative REML log-likelihood.

    With W = V^-1, C = (X' W X)^-1 and P = W - W X C X' W: dC/dtau_j = C X' W V_j W X C, and
    -d2l/dtau_j dtau_k = -tr(P V_j P V_k) / 2 + y' P V_j P V_k P y (V linear in tau).

    Returns
    -------
    tuple
        Beta (p), C (p x p), the derivatives (each p x p) and the Hessian (k x k), k the free
        parameters.
    """
    inverse = np.linalg.inv(covariance.matrix())
    weighted = inverse @ design
    fixed = np.asarray(np.linalg.inv(design.T @ weighted), dtype=np.float64)
    projection = inverse - weighted @ fixed @ weighted.T
    parts = [p for p, free in zip(covariance.parts, covariance.free, strict=True) if free]
    jacobian: list[NDArray[np.float64]] = [fixed @ weighted.T @ p @ weighted @ fixed for p in parts]
    projected = [projection @ part for part in parts]
    residual = projection @ outcome
    moved = [part @ residual for part in parts]
    pairs = list(zip(projected, moved, strict=True))
    hessian = np.array([
        [-0.5 * np.sum(pj * pk.T) + float(mj @ projection @ mk) for pk, mk in pairs]
        for pj, mj in pairs
    ], dtype=np.float64)  # fmt: skip
    return fixed @ weighted.T @ outcome, fixed, jacobian, hessian


def _inverse_positive(hessian: NDArray[np.float64]) -> NDArray[np.float64]:
    """Invert a symmetric matrix over its positive eigenvalues (a Moore-Penrose inverse)."""
    values, vectors = np.linalg.eigh(hessian)
    keep = values > EIGENVALUE_TOLERANCE * np.max(np.abs(values))
    kept = vectors[:, keep]
    return kept @ np.diag(1.0 / values[keep]) @ kept.T
