"""Permutation tests of two labelled sets of units (trials, people), and distances between them.

Units carry labels (True for one side); a statistic of a labelling is compared with its values over
relabellings of the units: every distinct relabelling when there are few (an exact test), else
random ones. Used by the human-likeness battery (labels permuted by trial) and by the comparison
of groups of people (labels permuted by person). `p_text` writes a p-value drawn against random
relabellings or surrogates as prose says it.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mirror_avatar.common.errors import InputError

Array = NDArray[np.float64]

N_PERMUTATIONS = 200
"""Relabellings drawn for each permutation test; all of them are tried when there are fewer
(**choice**: p-values resolve 0.005)."""


@dataclass(frozen=True)
class PermutationTest:
    """A statistic, its values over relabellings, and the p-value (larger is more extreme).

    Attributes
    ----------
    statistic
        The value with the true labels.
    null
        Its values with the labels permuted, shape (m,).
    p_value
        ``(1 + b) / (1 + m)`` over ``m`` random relabellings, ``b`` of them at least as large as
        the statistic (Phipson & Smyth 2010); with ``exact``, the share of all distinct
        relabellings (the true one included) at least as large.
    exact
        Whether every distinct relabelling was tried.

    A statistic that is not finite with the true labels is not tested: no relabellings, p NaN.
    """

    statistic: float
    null: Array
    p_value: float
    exact: bool

    def p_words(self) -> str:
        """Write the p-value as prose says it.

        ``p = 0.0286 (exact)`` over every relabelling, else as `p_text` writes one drawn against
        random relabellings (``p <= 0.005`` at the floor).
        """
        if self.exact:
            return f"p = {self.p_value:.3g} (exact)"
        return p_text(self.p_value, self.null.size)

    def to_json_dict(self) -> dict[str, Any]:
        """Return the test's numbers (the null as its size, mean and SD)."""
        return {
            "statistic": self.statistic,
            "p_value": self.p_value,
            "exact": self.exact,
            "permutations": int(self.null.size),
            "null_mean": float(np.mean(self.null)) if self.null.size else math.nan,
            "null_sd": float(np.std(self.null)) if self.null.size else math.nan,
        }


def p_text(p: float, n_surrogates: int) -> str:
    """Write a p-value against ``n_surrogates`` surrogates as a report's prose says it.

    With ``m`` surrogates the smallest p-value is ``1 / (m + 1)``
    (`mirror_avatar.metrics.surrogates.p_value`): there the surrogates bound it from above
    only, written ``p <= 0.01`` (99 surrogates), never ``p = 0.01``. NaN (no finite
    surrogate, or nothing to test) is ``no p-value``.
    """
    if not math.isfinite(p):
        return "no p-value"
    floor = 1.0 / (n_surrogates + 1)
    if p <= floor * (1 + 1e-9):
        return f"p <= {floor:.3g}"
    return f"p = {p:.3g}"


def permutation_test(
    statistic: Callable[[NDArray[np.bool_]], float],
    labels: ArrayLike,
    n_permutations: int = N_PERMUTATIONS,
    seed: int = 0,
) -> PermutationTest:
    """Test a statistic of labelled units against its values with the labels permuted.

    Parameters
    ----------
    statistic
        Maps a label per unit (True for one side) to a number, larger meaning more different.
    labels
        The true label of each unit, shape (n,), both values present.
    n_permutations
        Random relabellings; when the distinct relabellings (``n choose k``) are at most this
        many, all of them are tried instead and the test is exact.
    seed
        Seeds the random relabellings.
    """
    truth = np.asarray(labels, dtype=bool)
    n, k = truth.size, int(truth.sum())
    if not 0 < k < n:
        raise InputError(None, "a permutation test needs units on both sides")
    observed = statistic(truth)
    if not np.isfinite(observed):
        return PermutationTest(observed, np.empty(0), math.nan, False)
    if math.comb(n, k) <= n_permutations:
        null = np.array([statistic(_labelling(n, chosen)) for chosen in _choices(n, k)])
        return PermutationTest(observed, null, float(np.mean(null >= observed)), True)
    rng = np.random.default_rng(seed)
    null = np.array([statistic(rng.permutation(truth)) for _ in range(n_permutations)])
    p_value = (1.0 + np.sum(null >= observed)) / (1.0 + n_permutations)
    return PermutationTest(observed, null, float(p_value), False)


def _choices(n: int, k: int) -> itertools.combinations[tuple[int, ...]]:
    return itertools.combinations(range(n), k)


def _labelling(n: int, chosen: tuple[int, ...]) -> NDArray[np.bool_]:
    labels = np.zeros(n, dtype=bool)
    labels[list(chosen)] = True
    return labels


def between_minus_within(distances: Array, labels: NDArray[np.bool_]) -> float:
    """Mean distance between the two sides minus the mean within either side.

    Parameters
    ----------
    distances
        Symmetric distances between units, shape (n, n).
    labels
        Side of each unit, shape (n,).
    """
    between, within = between_and_within(distances, labels)
    return between - within


def between_and_within(distances: Array, labels: NDArray[np.bool_]) -> tuple[float, float]:
    """Mean distance over pairs on different sides, and over pairs on one side (both pooled)."""
    i, j = np.triu_indices(labels.size, k=1)
    same = labels[i] == labels[j]
    pairs = distances[i, j]
    within = float(pairs[same].mean()) if same.any() else math.nan
    return float(pairs[~same].mean()), within
