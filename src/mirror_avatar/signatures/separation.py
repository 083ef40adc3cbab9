"""Why two sets of motion are told apart: which features separate them, and which way.

The classifier two-sample test (`mirror_avatar.signatures.likeness.classifier_test`) says
whether a classifier tells candidate windows from reference windows; this module says why, in
words a user and a developer can act on (METHODS section 3, likeness):

- **Each group of features alone.** The same cross-validated classifier is fitted on one group
  of columns at a time (for the battery: the velocity distribution, acceleration, the spectrum's
  band shares, amplitude); a group whose AUC alone reaches `GROUP_AUC` separates the sets by
  itself. These AUCs describe, they are not tested: the battery's p-value is the whole
  classifier's.
- **The features that moved most.** Each feature's standardised difference (candidate mean
  minus reference mean, over the pooled within-set SD of the windows); the `N_SHIFTS` largest in
  size are reported with the two sets' medians, so the words say which way (``more power in
  3-5 Hz: share 0.120 against 0.004``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

GROUP_AUC = 0.75
"""AUC at which one group of features alone is said to separate the sets (**choice**: halfway
between chance and a perfect separation, where most windows of a set are already told apart)."""

N_SHIFTS = 3
"""Features named in the words, the largest standardised differences first (**choice**)."""


@dataclass(frozen=True)
class FeatureShift:
    """How one feature differs between the sets.

    Attributes
    ----------
    feature
        The feature's words (``share of velocity power in 3-5 Hz``).
    reference_median, candidate_median
        Median of the feature over each set's windows, in the feature's unit.
    standardised_difference
        (candidate mean - reference mean) / pooled within-set SD: 0 where the means are equal,
        infinite where they differ and the feature is constant within each set (JSON ``null``).
    """

    feature: str
    reference_median: float
    candidate_median: float
    standardised_difference: float

    def words(self) -> str:
        """``higher share of velocity power in 3-5 Hz (0.120 against 0.004)``."""
        way = "higher" if self.standardised_difference > 0 else "lower"
        return (
            f"{way} {self.feature} ({self.candidate_median:.3g} against "
            f"{self.reference_median:.3g})"
        )

    def to_json_dict(self) -> dict[str, Any]:
        """Return the numbers and the words."""
        return {
            "feature": self.feature,
            "reference_median": self.reference_median,
            "candidate_median": self.candidate_median,
            "standardised_difference": self.standardised_difference,
            "words": self.words(),
        }


@dataclass(frozen=True)
class Separation:
    """Which features separate candidate from reference windows.

    Attributes
    ----------
    group_auc
        Group of features -> the cross-validated AUC of the classifier on that group alone, in
        the order the groups were given.
    shifts
        The `N_SHIFTS` features with the largest standardised differences, largest first.
    """

    group_auc: dict[str, float]
    shifts: tuple[FeatureShift, ...]

    @property
    def separating_groups(self) -> list[str]:
        """The groups whose AUC alone reaches `GROUP_AUC`, the most separating first."""
        apart = [name for name, auc in self.group_auc.items() if auc >= GROUP_AUC]
        return sorted(apart, key=lambda name: -self.group_auc[name])

    def words(self) -> str:
        """``told apart by spectrum (AUC 0.98 alone): higher share ... (0.12 against 0.004)``.

        Without a group that separates the sets alone, the words say so and still name the
        features that moved most.
        """
        groups = self.separating_groups
        if groups:
            head = "told apart by " + ", ".join(
                f"{name} (AUC {self.group_auc[name]:.2f} alone)" for name in groups
            )
        else:
            head = f"no group of features alone reaches AUC {GROUP_AUC:g}"
        shifts = "; ".join(shift.words() for shift in self.shifts)
        return f"{head}: {shifts}" if shifts else head

    def to_json_dict(self) -> dict[str, Any]:
        """Return each group's AUC alone, the separating groups, the largest shifts and words."""
        return {
            "group_auc": dict(self.group_auc),
            "group_auc_threshold": GROUP_AUC,
            "separating_groups": self.separating_groups,
            "shifts": [shift.to_json_dict() for shift in self.shifts],
            "words": self.words(),
        }


def feature_shifts(
    features: Array, is_candidate: NDArray[np.bool_], names: Sequence[str]
) -> tuple[FeatureShift, ...]:
    """Find the `N_SHIFTS` features that differ most between the sets, largest first.

    Parameters
    ----------
    features
        Windows' features, shape (n_windows, n_features).
    is_candidate
        Whether each window is the candidate's, shape (n_windows,); both sets non-empty.
    names
        Each feature's words, length n_features.
    """
    reference, candidate = features[~is_candidate], features[is_candidate]
    pooled = np.sqrt(
        (reference.var(axis=0) * len(reference) + candidate.var(axis=0) * len(candidate))
        / len(features)
    )
    difference = candidate.mean(axis=0) - reference.mean(axis=0)
    unbounded = np.copysign(np.inf, difference)
    standardised = np.where(pooled > 0, difference / np.where(pooled > 0, pooled, 1.0), unbounded)
    standardised[difference == 0] = 0.0
    order = np.argsort(-np.abs(standardised), kind="stable")[:N_SHIFTS]
    return tuple(
        FeatureShift(
            feature=names[k],
            reference_median=float(np.median(reference[:, k])),
            candidate_median=float(np.median(candidate[:, k])),
            standardised_difference=float(standardised[k]),
        )
        for k in order
        if standardised[k] != 0.0
    )


def separation(
    features: Array,
    is_candidate: NDArray[np.bool_],
    names: Sequence[str],
    groups: Mapping[str, Sequence[int]],
    auc_of: Callable[[Sequence[int]], float],
) -> Separation:
    """Say which features separate the candidate's windows from the reference's.

    Parameters
    ----------
    features
        Windows' features, shape (n_windows, n_features).
    is_candidate
        Whether each window is the candidate's, shape (n_windows,).
    names
        Each feature's words, length n_features.
    groups
        Group name -> the columns of ``features`` it holds.
    auc_of
        The classifier's cross-validated AUC on the given columns alone (the same folds and
        model as the whole test's).
    """
    return Separation(
        group_auc={name: auc_of(columns) for name, columns in groups.items()},
        shifts=feature_shifts(features, is_candidate, names),
    )
