"""The power of a protocol's declared test, by simulating studies from a pilot's spread.

A pilot's study table gives, per primary measure, the participants' paired differences
(condition minus reference, each participant's mean over their trials); their covariance
across the primary measures, taken about their means so the pilot's own effect does not count,
is the spread of a simulated study. Each simulated study draws n participants' differences
from a normal distribution with that covariance, centred on the planned effect in the declared
direction, and runs the declared test on them (`mirror_avatar.analysis.hypothesis.declared_test`,
Holm over the primary measures as `confirm` does). The power is the share of studies in which
every primary measure is significant, with its binomial Monte Carlo standard error and a Wilson
interval. An angle among the primary measures (`mirror_avatar.analysis.dictionary.is_angle`)
is simulated and tested on the circle: the pilot's participants' circular means, their
differences and trial residuals wrapped to [-pi, pi) about their circular means; a simulated
study's differences are the normal draws wrapped (a wrapped normal), tested by the declared
sign-flip test (`mirror_avatar.analysis.circular.sign_flip_p`). docs/METHODS.md, section 15.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from numpy.typing import NDArray
from scipy import stats

from mirror_avatar.analysis.circular import circular_mean, sign_flip_p, wrapped
from mirror_avatar.analysis.dictionary import is_angle
from mirror_avatar.analysis.hypothesis import ALTERNATIVES, declared_test
from mirror_avatar.analysis.multiple_tests import holm
from mirror_avatar.analysis.statistics import TRIAL_KEYS, participant_means, trial_values
from mirror_avatar.analysis.study_file import StudyTable
from mirror_avatar.analysis.study_report import analysed_rows, check_hypothesis
from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.protocol import Analysis

INTERVAL = 0.95
"""The level of the Wilson interval of each simulated power."""

CHUNK_VALUES = 2_000_000
"""The simulated differences drawn at once, at most (16 MB): studies are drawn in chunks."""

SIGNS = {"lower": -1.0, "higher": 1.0, "two-sided": 1.0}
"""The sign of a planned effect in each declared direction (condition minus reference)."""


@dataclass(frozen=True)
class Spread:
    """The spread of the participants' paired differences, as a pilot shows it.

    Parameters
    ----------
    measures
        The primary measures, in the hypothesis's order.
    covariance
        Shape (m, m): the covariance of the differences across the measures (ddof 1), in the
        measures' squared units.
    participants
        The pilot's participants with a difference in every primary measure.
    pilot_differences
        Shape (m,): the pilot's mean difference per measure (reported, not simulated).
    trial_covariance
        Shape (m, m): the covariance of a trial's values about their participant's mean in the
        condition (pooled within participants and conditions), in squared units.
    trial_factor
        The pilot's mean over participants of 1/k_reference + 1/k_condition (k: their trials
        in the condition): the trial noise's share of a difference's variance is
        ``trial_factor * trial_covariance``.
    angles
        Shape (m,): whether each measure is an angle (rad; simulated and tested on the circle).
    """

    measures: tuple[str, ...]
    covariance: NDArray[np.float64]
    participants: int
    pilot_differences: NDArray[np.float64]
    trial_covariance: NDArray[np.float64]
    trial_factor: float
    angles: tuple[bool, ...] = ()

    def is_angle(self) -> NDArray[np.bool_]:
        """Shape (m,): whether each measure is an angle (none when `angles` is not given)."""
        return np.array(self.angles or (False,) * len(self.measures), dtype=bool)

    def with_trials(self, trials: int) -> NDArray[np.float64]:
        """Return the differences' covariance with ``trials`` trials per condition.

        The participants' own spread (the covariance less the pilot's trial noise, its
        negative eigenvalues set to 0) plus the trial noise over ``trials`` in each condition.
        """
        values, vectors = np.linalg.eigh(
            self.covariance - self.trial_factor * self.trial_covariance
        )
        participants = (vectors * np.clip(values, 0.0, None)) @ vectors.T
        return participants + (2.0 / trials) * self.trial_covariance

    @property
    def sd(self) -> NDArray[np.float64]:
        """Shape (m,): the SD of each measure's differences."""
        return np.sqrt(np.diag(self.covariance))


@dataclass(frozen=True)
class PowerPoint:
    """The simulated power at one number of participants.

    Parameters
    ----------
    participants
        n, the simulated studies' participants.
    simulations
        The studies simulated.
    rejections
        Per primary measure, the studies in which its Holm-corrected p is below alpha.
    all_rejections
        The studies in which every primary measure's is (the hypothesis's power).
    """

    participants: int
    simulations: int
    rejections: tuple[int, ...]
    all_rejections: int

    @property
    def power(self) -> float:
        """The share of studies rejecting every primary measure's null hypothesis."""
        return self.all_rejections / self.simulations

    @property
    def standard_error(self) -> float:
        """The binomial Monte Carlo standard error of `power`, sqrt(p (1 - p) / N)."""
        return math.sqrt(self.power * (1.0 - self.power) / self.simulations)

    @property
    def interval(self) -> tuple[float, float]:
        """The Wilson interval of `power` at `INTERVAL` (Wilson 1927)."""
        found = stats.binomtest(self.all_rejections, self.simulations).proportion_ci(
            INTERVAL, method="wilson"
        )
        return float(found.low), float(found.high)


def pilot_spread(table: StudyTable, analysis: Analysis, protocol: str) -> Spread:
    """Estimate the spread of the paired differences of the hypothesis's primary measures.

    The rows are those the report analyses (`analysed_rows`: persons, complete trials, finite
    values); a participant counts when they have a mean in both conditions of every primary
    measure.

    ``protocol``: the protocol's file, named when the table lacks what it declares.

    Raises
    ------
    InputError
        The table lacks a primary measure or a condition of the contrast, or fewer than two
        participants have both conditions.
    """
    check_hypothesis(table, analysis, table.conditions(), protocol)
    rows, _, _ = analysed_rows(table)
    differences = pd.concat(
        {measure: _differences(rows, measure, analysis) for measure in analysis.primary}, axis=1
    ).dropna()
    if len(differences) < 2:
        raise InputError(table.source, f"{len(differences)} participant(s) with both "
                         f"{analysis.reference!r} and {analysis.condition!r}: the spread needs "
                         "two or more")  # fmt: skip
    angles = tuple(is_angle(measure) for measure in analysis.primary)
    values = differences.to_numpy(np.float64)
    centres = np.array([_average(v, angle) for v, angle in zip(values.T, angles, strict=True)])
    deviations = np.where(angles, wrapped(values - centres), values - centres)
    conditions = [analysis.reference, analysis.condition]
    kept = rows[rows["participant"].isin(differences.index) & rows["condition"].isin(conditions)]
    noise, factor = _trial_noise(kept, analysis)
    return Spread(
        measures=analysis.primary,
        covariance=np.atleast_2d(np.cov(deviations, rowvar=False, ddof=1)),
        participants=len(differences),
        pilot_differences=centres,
        trial_covariance=noise,
        trial_factor=factor,
        angles=angles,
    )


def _average(values: NDArray[np.float64], angle: bool) -> float:
    """Return the mean of ``values``: circular for an angle (rad)."""
    return circular_mean(values) if angle else float(np.mean(values))


def _differences(rows: pd.DataFrame, measure: str, analysis: Analysis) -> pd.Series:
    """Each participant's difference of means, condition minus reference (wrapped: an angle)."""
    angle = is_angle(measure)
    conditions = [analysis.reference, analysis.condition]
    means = participant_means(rows, measure, conditions, circular_mean if angle else "mean")
    difference = means[analysis.condition] - means[analysis.reference]
    return pd.Series(wrapped(difference), difference.index) if angle else difference


def _trial_noise(rows: pd.DataFrame, analysis: Analysis) -> tuple[NDArray[np.float64], float]:
    """Return the pooled within-cell covariance of the trials' values, and `Spread.trial_factor`.

    A cell is a participant in a condition; its trials' values (`trial_values`) about their
    mean (an angle's wrapped about its circular mean), pooled with the cells' degrees of
    freedom (trials less cells).
    """
    keys = [key for key in TRIAL_KEYS if key in rows]
    trials = pd.concat(
        [trial_values(rows, m).set_index(keys)[m] for m in analysis.primary], axis=1
    ).dropna()
    cells = trials.groupby(level=["participant", "condition"])
    angles = np.array([is_angle(measure) for measure in analysis.primary])
    centres = pd.concat(
        [cells[m].transform(circular_mean if angle else "mean")
         for m, angle in zip(analysis.primary, angles, strict=True)], axis=1,
    )  # fmt: skip
    offsets = (trials - centres).to_numpy(np.float64)
    residuals = np.where(angles, wrapped(offsets), offsets)
    freedom = max(len(trials) - cells.ngroups, 1)
    counts = cells.size().unstack("condition")
    factor = float((1.0 / counts).sum(axis=1).mean())
    return residuals.T @ residuals / freedom, factor


def simulate_differences(
    covariance: NDArray[np.float64],
    effect: float,
    direction: str,
    participants: int,
    simulations: int,
    rng: np.random.Generator,
) -> NDArray[np.float64]:
    """Draw the paired differences of simulated studies.

    Parameters
    ----------
    covariance
        Shape (m, m): their covariance across the primary measures.
    effect
        The planned effect, in the measures' units, in the declared direction (> 0).
    direction
        The hypothesis's direction: the effect is subtracted when it is "lower".
    participants, simulations
        n per study, and the studies.
    rng
        The generator drawn from.

    Returns
    -------
    numpy.ndarray
        Shape (simulations, m, participants).
    """
    mean = np.full(len(covariance), SIGNS[direction] * effect)
    drawn = rng.multivariate_normal(mean, covariance, size=(simulations, participants))
    return np.moveaxis(drawn, 1, 2)


def rejections(
    differences: NDArray[np.float64],
    analysis: Analysis,
    angles: NDArray[np.bool_] | None = None,
    rng: np.random.Generator | None = None,
) -> NDArray[np.bool_]:
    """Whether each simulated study rejects each primary measure's null hypothesis.

    Parameters
    ----------
    differences
        Shape (simulations, m, n), from `simulate_differences`.
    analysis
        The declared hypothesis: direction and alpha.
    angles
        Shape (m,): the measures that are angles (default none): their differences are wrapped
        to [-pi, pi) and tested by the sign-flip test, as
        `mirror_avatar.analysis.hypothesis.confirm` tests them.
    rng
        Draws the sign-flip test's flips above its exact size (default: seeded 0).

    Returns
    -------
    numpy.ndarray
        Shape (simulations, m): the Holm-corrected p below alpha.
    """
    _, p = declared_test(differences, analysis.direction)
    if angles is not None and angles.any():
        sines = np.sin(wrapped(differences[:, angles, :]))
        flips = rng if rng is not None else np.random.default_rng(0)
        p[:, angles] = sign_flip_p(sines, ALTERNATIVES[analysis.direction], flips)
    corrected = np.array([holm(study) for study in p])
    return corrected < analysis.alpha


def simulate_power(
    spread: Spread,
    analysis: Analysis,
    participants: int,
    simulations: int,
    seed: int,
    effect: float | None = None,
    trials: int | None = None,
) -> PowerPoint:
    """Simulate the declared test's power with ``participants`` participants.

    The generator is seeded by (``seed``, ``participants``): a number of participants gives the
    same studies whichever others are simulated with it. The studies are drawn in chunks of at
    most `CHUNK_VALUES` differences. ``effect`` defaults to the
    hypothesis's smallest effect of interest; ``trials``, the trials per condition, to the
    pilot's (`Spread.with_trials`).
    """
    rng = np.random.default_rng([seed, participants])
    planned = analysis.smallest_effect if effect is None else effect
    covariance = spread.covariance if trials is None else spread.with_trials(trials)
    chunk = max(1, CHUNK_VALUES // (participants * len(covariance)))
    rejected = np.concatenate([
        rejections(simulate_differences(covariance, planned, analysis.direction, participants,
                                        min(chunk, simulations - start), rng),
                   analysis, spread.is_angle(), rng)
        for start in range(0, simulations, chunk)
    ])  # fmt: skip
    return PowerPoint(
        participants=participants,
        simulations=simulations,
        rejections=tuple(int(count) for count in rejected.sum(axis=0)),
        all_rejections=int(rejected.all(axis=1).sum()),
    )


def smallest_participants(points: list[PowerPoint], target: float) -> int | None:
    """Return the smallest n whose power, and every larger n's, reaches ``target``.

    None when the largest n simulated does not reach it.
    """
    reached = None
    for point in sorted(points, key=lambda p: p.participants, reverse=True):
        if point.power < target:
            break
        reached = point.participants
    return reached
