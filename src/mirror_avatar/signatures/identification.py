"""Are people told apart by their signatures: each trial identified by its nearest person.

Each trial, in turn, is put with the person whose other trials are nearest to it on average
(mean velocity-IMS EMD; the trial itself left out of its own person's mean). The identification
rate is the share of trials put with their own person. Chance is measured, not assumed: the
trials' person labels are shuffled (each person keeping their number of trials) and the rate
recomputed; the p-value is the share of shuffles at least as high (Phipson & Smyth 2010).
Only trials whose person has another trial can be identified; every person is a candidate.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.signatures.permutations import p_text

Array = NDArray[np.float64]

ALPHA = 0.05
"""A p-value below this calls the people told apart (**choice**)."""

SHUFFLES = 999
"""Shufflings of the person labels (**choice**: p-values resolve 0.001; a shuffle costs one
matrix product over the trials)."""


@dataclass(frozen=True)
class Identification:
    """Each trial put with its nearest person, against shuffled labels.

    Attributes
    ----------
    people
        The people (candidates), in order of first appearance.
    truth, predicted
        Each identifiable trial's person and the person it was put with.
    rate
        Share of identifiable trials put with their own person, in [0, 1].
    null
        The rate with the labels shuffled, shape (SHUFFLES,).
    p_value
        ``(1 + b) / (1 + shuffles)``, ``b`` the shuffles with a rate at least ``rate``.
    """

    people: list[str]
    truth: list[str]
    predicted: list[str]
    rate: float
    null: Array
    p_value: float

    @property
    def chance(self) -> float:
        """The mean rate with the labels shuffled."""
        return float(self.null.mean())

    @property
    def told_apart(self) -> bool:
        """Whether the rate is above chance (p below `ALPHA`)."""
        return self.p_value < ALPHA

    def verdict(self) -> str:
        """One line: are the people told apart, and how well."""
        right = sum(t == p for t, p in zip(self.truth, self.predicted, strict=True))
        how = (
            f"{right} of {len(self.truth)} trials ({self.rate:.0%}) are nearest their own "
            f"person's other trials; chance {self.chance:.0%} (labels shuffled, "
            f"{p_text(self.p_value, self.null.size)})"
        )
        if self.told_apart:
            return f"The {len(self.people)} people are told apart: {how}."
        return f"The {len(self.people)} people are not told apart at this data size: {how}."

    def to_json_dict(self) -> dict[str, Any]:
        """Return the identification's numbers and verdict."""
        return {
            "people": self.people,
            "truth": self.truth,
            "predicted": self.predicted,
            "rate": self.rate,
            "chance": self.chance,
            "p_value": self.p_value,
            "shuffles": int(self.null.size),
            "told_apart": self.told_apart,
            "verdict": self.verdict(),
        }


def identify_people(
    emd: Array, people: Sequence[str], shuffles: int = SHUFFLES, seed: int = 0
) -> Identification | None:
    """Put each trial with the person whose other trials are nearest on average.

    Parameters
    ----------
    emd
        EMD between trials, shape (m, m), zero diagonal.
    people
        Each trial's person, length m.
    shuffles, seed
        Shufflings of the labels for chance, and their seed.

    Returns
    -------
    Identification or None
        None when there are fewer than two people or no person has two trials.
    """
    names = list(dict.fromkeys(people))
    index = np.array([names.index(p) for p in people])
    sizes = np.bincount(index, minlength=len(names))
    scored = sizes[index] > 1
    if len(names) < 2 or not scored.any():
        return None
    predicted = _nearest(emd, index, len(names))
    rate = float(np.mean(predicted[scored] == index[scored]))
    rng = np.random.default_rng(seed)
    null = np.empty(shuffles)
    for k in range(shuffles):
        shuffled = rng.permutation(index)
        kept = sizes[shuffled] > 1
        null[k] = np.mean(_nearest(emd, shuffled, len(names))[kept] == shuffled[kept])
    p_value = float((1 + np.sum(null >= rate)) / (1 + shuffles))
    return Identification(
        people=names,
        truth=[names[i] for i in index[scored]],
        predicted=[names[i] for i in predicted[scored]],
        rate=rate,
        null=null,
        p_value=p_value,
    )


def _nearest(emd: Array, index: NDArray[np.intp], n_people: int) -> NDArray[np.intp]:
    """Each trial's nearest person by mean EMD to their trials, itself left out."""
    members = np.eye(n_people)[index]
    totals = emd @ members
    counts = members.sum(axis=0)[None, :] - members
    with np.errstate(divide="ignore", invalid="ignore"):
        means = np.where(counts > 0, totals / counts, np.inf)
    return np.argmin(means, axis=1)
