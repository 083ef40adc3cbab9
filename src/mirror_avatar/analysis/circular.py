"""Circular statistics of a study's angles: means, resultant lengths and tests (METHODS 15.7).

A mean relative phase is a direction on the circle: -3.1 rad and 3.1 rad are 0.08 rad apart,
and their arithmetic mean, 0, is the opposite direction. An angle measure
(`mirror_avatar.analysis.dictionary.is_angle`) is averaged as unit vectors instead: the circular
mean is the direction of the mean vector and its length, the mean resultant length R, says how
concentrated the angles are (Fisher 1993, *Statistical Analysis of Circular Data*; Mardia &
Jupp 2000, *Directional Statistics*). Each participant's mean per
condition is the circular mean of their trials; the conditions' means are circular means of the
participants' (`circular_summaries`), tested for a preferred direction by Rayleigh's test
(`rayleigh_test`); a condition is compared with the reference by a sign-flip randomisation
test of each participant's difference of directions (`paired_direction_test`).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from mirror_avatar.analysis.multiple_tests import holm
from mirror_avatar.analysis.statistics import Contrast, MeasureModel, participant_means

EXACT_PARTICIPANTS = 14
"""Up to this many participants, `paired_direction_test` enumerates every sign flip (2^14 =
16384 of them); above it, it draws `RANDOM_FLIPS` (**choice**: both take well under a second)."""

RANDOM_FLIPS = 9999
"""Sign flips drawn above `EXACT_PARTICIPANTS` (**choice**: as the bootstrap's resamples)."""

FLIP_CHUNK = 4_000_000
"""Flipped sums computed at once, at most (32 MB): `sign_flip_p` goes through samples in chunks."""

DIRECTION_TEST = (
    "circular: sign-flip randomisation test of each participant's difference of directions"
)
"""The comparison of an angle measure's conditions, in words (`circular_contrasts`)."""


def _finite(angles: ArrayLike) -> NDArray[np.float64]:
    values = np.asarray(angles, dtype=np.float64).ravel()
    return values[np.isfinite(values)]


def circular_mean(angles: ArrayLike) -> float:
    """Return the direction of the angles' mean unit vector (rad, in (-pi, pi]).

    NaN without angles, or when the mean vector is of length 0 (no direction).
    """
    values = _finite(angles)
    if values.size == 0:
        return float("nan")
    sine, cosine = float(np.mean(np.sin(values))), float(np.mean(np.cos(values)))
    if np.hypot(sine, cosine) < 1e-12:
        return float("nan")
    return float(np.arctan2(sine, cosine))


def resultant_length(angles: ArrayLike) -> float:
    """Return the mean resultant length R of the angles (rad): 1 all alike, 0 no direction."""
    values = _finite(angles)
    if values.size == 0:
        return float("nan")
    return float(np.hypot(np.mean(np.sin(values)), np.mean(np.cos(values))))


def circular_sd(length: float) -> float:
    """Return the circular SD sqrt(-2 ln R) of a mean resultant length R (rad; Fisher 1993)."""
    return float(np.sqrt(-2.0 * np.log(length))) if length > 0 else float("inf")


def wrapped(angles: ArrayLike) -> NDArray[np.float64]:
    """Return the angles wrapped to [-pi, pi) (rad)."""
    return (np.asarray(angles, dtype=np.float64) + np.pi) % (2.0 * np.pi) - np.pi


class RayleighTest(NamedTuple):
    """Rayleigh's test of uniformity against one preferred direction.

    ``z`` = n R^2 (n angles, R their mean resultant length); ``p`` its p-value.
    """

    z: float
    p: float


def rayleigh_test(angles: ArrayLike) -> RayleighTest:
    """Test whether the angles have a preferred direction (Rayleigh's test).

    The p-value is Zar's approximation (Zar 1999, *Biostatistical Analysis*, 4th ed., p. 617,
    as CircStat's ``circ_rtest`` computes it, Berens 2009, J Stat Softw 31(10)):
    p = exp(sqrt(1 + 4n + 4(n^2 - Rn^2)) - (1 + 2n)), Rn = n R, closer to the exact tail for
    small n than the limit exp(-z). NaN for fewer than two angles.
    """
    values = _finite(angles)
    n = values.size
    if n < 2:
        return RayleighTest(float("nan"), float("nan"))
    summed = n * resultant_length(values)
    p = float(np.exp(np.sqrt(1.0 + 4.0 * n + 4.0 * (n * n - summed * summed)) - (1.0 + 2.0 * n)))
    return RayleighTest(summed * summed / n, min(1.0, p))


class DirectionTest(NamedTuple):
    """A condition's directions against the reference's, participant by participant.

    ``difference``: the circular mean of the participants' differences (condition minus
    reference, rad); ``length`` their mean resultant length; ``p`` the sign-flip test's
    two-sided p-value; ``exact`` whether every sign flip was enumerated.
    """

    difference: float
    length: float
    p: float
    exact: bool


def paired_direction_test(
    reference: ArrayLike, condition: ArrayLike, seed: int = 0, alternative: str = "two-sided"
) -> DirectionTest:
    """Test whether a condition shifts the participants' directions from the reference.

    Each participant's difference d = condition - reference (rad, wrapped). With no effect of
    the condition, and the conditions' order counterbalanced, d and -d are equally likely, so
    the statistic sum sin d is compared with its values under every flip of the differences'
    signs (a randomisation test, as Fisher 1993 gives for circular samples; Good 2005,
    *Permutation, Parametric and Bootstrap Tests of Hypotheses*, on the paired case;
    `sign_flip_p`). NaN for fewer than two pairs.

    sum sin d measures a shift of direction (positive: the condition later in the cycle); a
    change of concentration alone, at an unchanged direction, is not what it tests.
    ``alternative``: ``"two-sided"`` (|sum sin d|), ``"greater"`` (the condition later) or
    ``"less"`` (earlier), as scipy names them.
    """
    before = np.asarray(reference, dtype=np.float64)
    after = np.asarray(condition, dtype=np.float64)
    keep = np.isfinite(before) & np.isfinite(after)
    differences = wrapped(after[keep] - before[keep])
    n = differences.size
    if n < 2:
        nan = float("nan")
        return DirectionTest(nan, nan, nan, False)
    p = float(sign_flip_p(np.sin(differences), alternative, np.random.default_rng(seed)))
    return DirectionTest(
        circular_mean(differences), resultant_length(differences), p, n <= EXACT_PARTICIPANTS
    )


FLIP_STATISTICS = {"two-sided": np.abs, "greater": np.positive, "less": np.negative}
"""The sign-flip test's statistic of a sum of sines under each alternative."""


def sign_flip_p(
    sines: NDArray[np.float64], alternative: str, rng: np.random.Generator
) -> NDArray[np.float64]:
    """Return the sign-flip test's p-value of each sample of sines of differences.

    Parameters
    ----------
    sines
        Shape (..., n): each sample's sin d, n of them.
    alternative
        A key of `FLIP_STATISTICS`: the statistic is the sum's absolute value, itself or its
        negative.
    rng
        Draws the flips above `EXACT_PARTICIPANTS` (one set of `RANDOM_FLIPS` flips shared by
        every sample); unused up to it.

    Returns
    -------
    numpy.ndarray
        Shape (...): the share of flips whose statistic is at least the observed one (every
        flip of n up to `EXACT_PARTICIPANTS`, the observed among them); above it,
        (1 + count) / (1 + `RANDOM_FLIPS`) over the drawn flips. A statistic within 1e-12 of
        the sum of |sin d| below the observed one counts as equal (rounding).
    """
    n = sines.shape[-1]
    statistic = FLIP_STATISTICS[alternative]
    exact = n <= EXACT_PARTICIPANTS
    if exact:
        signs = np.array(list(itertools.product((1.0, -1.0), repeat=n)))
    else:
        signs = rng.choice((1.0, -1.0), size=(RANDOM_FLIPS, n))
    samples = sines.reshape(-1, n)
    counts = np.empty(len(samples))
    step = max(1, FLIP_CHUNK // len(signs))
    for start in range(0, len(samples), step):
        part = samples[start : start + step]
        observed = statistic(part.sum(axis=1)) - 1e-12 * np.abs(part).sum(axis=1)
        counts[start : start + step] = np.sum(statistic(part @ signs.T) >= observed[:, None], 1)
    p = counts / len(signs) if exact else (1.0 + counts) / (1.0 + RANDOM_FLIPS)
    return p.reshape(sines.shape[:-1])


def circular_summaries(
    rows: pd.DataFrame, measure: str, conditions: Sequence[str]
) -> list[dict[str, object]]:
    """Per condition: the participants' circular mean, its resultant length, SD and Rayleigh p.

    Returns
    -------
    list of dict
        One per condition, in order: ``measure, condition, participants, mean`` (rad),
        ``ci_low, ci_high`` (NaN: no interval is computed for a direction), ``sd`` (the
        circular SD, rad), ``resultant_length`` and ``rayleigh_p``.
    """
    directions = participant_means(rows, measure, conditions, circular_mean)
    found = []
    for condition in conditions:
        values = directions[condition].dropna().to_numpy()
        length = resultant_length(values)
        found.append({
            "measure": measure, "condition": condition, "participants": values.size,
            "mean": circular_mean(values), "ci_low": float("nan"), "ci_high": float("nan"),
            "sd": circular_sd(length) if values.size > 1 else float("nan"),
            "resultant_length": length, "rayleigh_p": rayleigh_test(values).p,
        })  # fmt: skip
    return found


def circular_contrasts(
    rows: pd.DataFrame, measure: str, conditions: Sequence[str], reference: str, seed: int = 0
) -> MeasureModel | None:
    """Compare each condition's directions with the reference's (`paired_direction_test`).

    No mixed model: a linear model of angles is wrong where they wrap at +-pi. Each contrast's
    difference is the circular mean of the participants' differences (rad), its p the
    sign-flip test's, Holm-corrected over the measure's contrasts; the reference and condition
    means are the participants' circular means; the model's intervals, effect sizes and paired
    linear tests are NaN.

    Returns
    -------
    MeasureModel or None
        None when fewer than two conditions or two participants have values of ``measure``.
    """
    directions = participant_means(rows, measure, conditions, circular_mean)
    present = [c for c in conditions if directions[c].notna().any()]
    if reference not in present or len(present) < 2 or len(directions) < 2:
        return None
    others = [c for c in present if c != reference]
    tests = {}
    for condition in others:
        paired = directions[[reference, condition]].dropna()
        tests[condition] = (paired, paired_direction_test(paired[reference], paired[condition],
                                                          seed))  # fmt: skip
    adjusted = holm([test.p for _, test in tests.values()])
    nan = float("nan")
    contrasts = [
        Contrast(
            measure=measure, condition=condition, reference=reference,
            difference=test.difference, ci_low=nan, ci_high=nan, p=test.p, p_holm=float(p_holm),
            standardised=nan, participants=len(paired),
            reference_mean=circular_mean(paired[reference]),
            condition_mean=circular_mean(paired[condition]), d_z=nan, t=nan, t_p=nan,
            wilcoxon_p=nan,
        )
        for (condition, (paired, test)), p_holm in zip(tests.items(), adjusted, strict=True)
    ]  # fmt: skip
    exact = all(test.exact for _, test in tests.values())
    flips = "every sign flip enumerated" if exact else f"{RANDOM_FLIPS} sign flips drawn"
    return MeasureModel(
        measure=measure, rows=int(rows[measure].notna().sum()),
        participants=int(directions.notna().any(axis=1).sum()), position_in_model=False,
        position_slope=nan, position_p=nan, participant_variance=nan, residual_variance=nan,
        contrasts=contrasts,
        notes=[f"an angle: compared by circular statistics ({flips}), order not checked"],
        fixed_effects=DIRECTION_TEST, converged=True,
    )  # fmt: skip
