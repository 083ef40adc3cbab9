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

    The covariance is block-diagonal, a block per group of the model (statsmodels' groups, in
    its order). ``parts[j][i]`` is the derivative of group i's block (n_i x n_i) by parameter
    j; ``estimates[j]`` the parameter's REML estimate; ``free[j]`` whether it is a parameter of
    the df (not on the boundary).
    """

    parts: list[list[NDArray[np.float64]]]
    estimates: NDArray[np.float64]
    free: NDArray[np.bool_]

    def blocks(self) -> list[NDArray[np.float64]]:
        """Return each group's block of the covariance at the estimates (n_i x n_i)."""
        return [
            np.einsum("j,jmn->mn", self.estimates, np.asarray([part[i] for part in self.parts]))
            for i in range(len(self.parts[0]))
        ]


def satterthwaite_tests(result: MixedLMResults, contrasts: ArrayLike) -> list[SmallSampleTest]:
    """Test each row of ``contrasts`` (shape (m, p), p the fixed effects) on a REML fit.

    ``result`` is a statsmodels `MixedLM` fit by REML: random effects per group (``exog_re``),
    variance components (``exog_vc``) and a residual variance. Its variance parameters are taken
    as they are; beta and C = (X' V^-1 X)^-1 are those of generalised least squares at them (as
    lme4's, and statsmodels' estimates; statsmodels' standard errors come from the inverse of its
    observed Hessian instead, and differ slightly on an unbalanced design). Every quantity is
    summed over the groups' blocks of V (`_reml_pieces`), so memory grows with the largest
    group's trials squared, not with all the trials squared.

    Returns
    -------
    list of SmallSampleTest
        One per contrast, in order.
    """
    weights = np.atleast_2d(np.asarray(contrasts, dtype=np.float64))
    model = result.model
    covariance = _covariance(result)
    beta, fixed, jacobian, hessian = _reml_pieces(model.exog_li, model.endog_li, covariance)
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
            parts.append([_pair(model.exog_re_li[i], a, b) for i in groups])
            estimates.append(random[a, b])
            free.append(min(random[a, a], random[b, b]) > BOUNDARY * scale)
    for j, variance in enumerate(np.asarray(result.vcomp, dtype=np.float64)):
        mats = model.exog_vc.mats[j]
        parts.append([mats[i] @ mats[i].T for i in groups])
        estimates.append(variance)
        free.append(variance > BOUNDARY * scale)
    parts.append([np.eye(len(y)) for y in model.endog_li])
    estimates.append(scale)
    free.append(True)
    return _Covariance(parts, np.array(estimates), np.array(free))


def _pair(columns: NDArray[np.float64], a: int, b: int) -> NDArray[np.float64]:
    """Return the derivative of Z G Z' by G[a, b] and G[b, a] (one parameter), Z ``columns``."""
    outer = np.outer(columns[:, a], columns[:, b])
    return outer if a == b else outer + outer.T


def _reml_pieces(
    designs: list[NDArray[np.float64]],
    outcomes: list[NDArray[np.float64]],
    covariance: _Covariance,
) -> tuple[
    NDArray[np.float64], NDArray[np.float64], list[NDArray[np.float64]], NDArray[np.float64]
]:
    """Return beta, C, C's derivatives and the Hessian of the negative REML log-likelihood.

    With W = V^-1, A = W X, C = (X' W X)^-1 and P = W - A C A': dC/dtau_j = C M_j C with
    M_j = A' V_j A, and -d2l/dtau_j dtau_k = -tr(P V_j P V_k) / 2 + y' P V_j P V_k P y
    (V linear in tau). As W and each V_j are block-diagonal (``designs[i]``, ``outcomes[i]``
    and the blocks of group i), tr(P V_j P V_k) = tr(W V_j W V_k) - 2 tr(C A' V_j W V_k A)
    + tr(C M_j C M_k), and with r = P y = W (y - X beta), y' P V_j P V_k P y =
    r' V_j W V_k r - (A' V_j r)' C (A' V_k r): every term a sum over the groups.

    Returns
    -------
    tuple
        Beta (p), C (p x p), the derivatives (each p x p) and the Hessian (k x k), k the free
        parameters.
    """
    inverses = [np.asarray(np.linalg.inv(b), dtype=np.float64) for b in covariance.blocks()]
    weighted = [w @ x for w, x in zip(inverses, designs, strict=True)]
    fixed = np.asarray(np.linalg.inv(sum(x.T @ a for x, a in zip(designs, weighted, strict=True))),
                       dtype=np.float64)  # fmt: skip
    beta = fixed @ sum(a.T @ y for a, y in zip(weighted, outcomes, strict=True))
    parts = [p for p, free in zip(covariance.parts, covariance.free, strict=True) if free]
    sums = _GroupSums.of(len(parts), fixed.shape[0])
    for i, (w, x, y, a) in enumerate(zip(inverses, designs, outcomes, weighted, strict=True)):
        sums.add(w, a, w @ (y - x @ beta), np.asarray([part[i] for part in parts]))
    return beta, fixed, [fixed @ m @ fixed for m in sums.weighted], sums.hessian(fixed)


@dataclass
class _GroupSums:
    """The sums over groups that `_reml_pieces`'s Hessian and derivatives are made of.

    With k free parameters and p fixed effects: ``traces[j, l]`` = tr(W V_j W V_l) (k x k);
    ``crossed[j, l]`` = A' V_j W V_l A (k x k x p x p); ``weighted[j]`` = M_j = A' V_j A
    (k x p x p); ``moved[j, l]`` = r' V_j W V_l r (k x k); ``residual[j]`` = A' V_j r (k x p).
    """

    traces: NDArray[np.float64]
    crossed: NDArray[np.float64]
    weighted: NDArray[np.float64]
    moved: NDArray[np.float64]
    residual: NDArray[np.float64]

    @classmethod
    def of(cls, parameters: int, effects: int) -> _GroupSums:
        """Return the sums over no group: zeros for ``parameters`` k and ``effects`` p."""
        k, p = parameters, effects
        return cls(np.zeros((k, k)), np.zeros((k, k, p, p)), np.zeros((k, p, p)),
                   np.zeros((k, k)), np.zeros((k, p)))  # fmt: skip

    def add(
        self,
        inverse: NDArray[np.float64],
        weighted: NDArray[np.float64],
        residual: NDArray[np.float64],
        parts: NDArray[np.float64],
    ) -> None:
        """Add one group: its W (n x n), A (n x p), r (n) and each free V_j's block (k x n x n)."""
        scaled = inverse @ parts  # W V_j, k x n x n
        applied = parts @ weighted  # V_j A, k x n x p
        moved = parts @ residual  # V_j r, k x n
        self.traces += np.einsum("jab,lba->jl", scaled, scaled)
        self.crossed += np.einsum("jai,lap->jlip", applied, inverse @ applied)
        self.weighted += np.einsum("ai,jap->jip", weighted, applied)
        self.moved += moved @ inverse @ moved.T
        self.residual += moved @ weighted

    def hessian(self, fixed: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the Hessian of the negative REML log-likelihood (k x k), C ``fixed``."""
        products = np.einsum("pq,jqr->jpr", fixed, self.weighted)  # C M_j
        traces = (self.traces - 2.0 * np.einsum("pq,jlqp->jl", fixed, self.crossed)
                  + np.einsum("jpq,lqp->jl", products, products))  # fmt: skip
        quadratic = self.moved - self.residual @ fixed @ self.residual.T
        return np.asarray(-0.5 * traces + quadratic, dtype=np.float64)


def _inverse_positive(hessian: NDArray[np.float64]) -> NDArray[np.float64]:
    """Invert a symmetric matrix over its positive eigenvalues (a Moore-Penrose inverse)."""
    values, vectors = np.linalg.eigh(hessian)
    keep = values > EIGENVALUE_TOLERANCE * np.max(np.abs(values))
    kept = vectors[:, keep]
    return kept @ np.diag(1.0 / values[keep]) @ kept.T
