"""Human-likeness: can motion be told from a person's own trials? (METHODS section 3, likeness).

The battery compares two sets of velocity signals at one rate: the **reference** (a person's
trials, held out of whatever made the other set) and the **candidate** (generated trials, an
avatar's sessions, another group's trials). Each test answers with a plain verdict,
``indistinguishable at this data size`` or ``distinguishable``, and its numbers:

- **Distances** between whole trials, each with a permutation test (labels permuted by trial):
  the velocity IMS EMD (`mirror_avatar.signatures.signature`), the amplitude distance
  (Wasserstein-1 between
  the distributions of stroke lengths, units) and the spectrum distance (Wasserstein-1 between the
  velocity power spectra as distributions over frequency, Hz). Each is reported as the mean
  distance from candidate to reference trials and its ratio to the person's own trial-to-trial
  distance.
- **A classifier two-sample test** (C2ST, Lopez-Paz & Oquab 2017): a linear classifier on features
  of 5 s windows (velocity and acceleration distributions, spectrum bands, amplitude),
  cross-validated with the folds grouped by trial, so that windows of one trial never sit on both
  sides; the statistic is the cross-validated AUC and its p-value comes from the same procedure with
  the labels permuted by trial.

Seeds: one integer seeds every part (`mirror_avatar.common.seeds.draw_seeds`) and is recorded.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
import scipy.signal
import scipy.stats
from numpy.typing import NDArray
from sklearn.model_selection import StratifiedGroupKFold

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import draw_seeds
from mirror_avatar.files.trials import DEFAULT_RATE, Trial
from mirror_avatar.signatures.permutations import (
    N_PERMUTATIONS,
    PermutationTest,
    between_minus_within,
    permutation_test,
)
from mirror_avatar.signatures.ridge import ridge_scores, roc_auc
from mirror_avatar.signatures.separation import Separation, separation
from mirror_avatar.signatures.signature import compute_emd_matrix, compute_ims, velocity_strokes

Array = NDArray[np.float64]

ALPHA = 0.05
"""A test whose p-value is below this calls the two sets distinguishable (**choice**)."""

WINDOW_SECONDS = 5.0
"""Length of the classifier's windows (s) (**choice**: several strokes of the slow bundled style,
about 0.1 Hz, still fit in two windows)."""

HOP_FRACTION = 0.5
"""Windows start every half window (**choice**)."""

MAX_FREQUENCY = 5.0
"""Highest frequency (Hz) of the spectra compared: hand motion has little power above it."""

SPECTRUM_BANDS = (0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, MAX_FREQUENCY)
"""Edges (Hz) of the bands whose share of a window's velocity power are classifier features."""

WELCH_SECONDS = 10.0
"""Segment length (s) of the Welch spectra of whole trials (0.1 Hz resolution)."""

MAX_UNITS = 24
"""Most trials of one side the classifier uses, spread evenly over the given order (**choice**:
an avatar plays over a hundred validation sessions, and more do not change the verdict)."""

MIN_STROKE_SECONDS = 0.2
"""Shortest stroke (s) whose amplitude counts: METHODS section 3's 20 samples at 100 Hz."""

FOLDS = 5
"""Cross-validation folds of the classifier, fewer when a side has fewer trials."""


def trial_velocity(trial: Trial, rate: float = DEFAULT_RATE) -> Array:
    """Velocity (units/s) of a trial resampled to ``rate`` Hz, shape (n,)."""
    uniform = (
        trial if trial.is_uniform and math.isclose(trial.rate, rate) else trial.resampled(rate)
    )
    return uniform.velocity()


def ims_distances(velocities: Sequence[Array]) -> Array:
    """Velocity IMS EMD between every pair of signals, shape (n, n) (METHODS section 3)."""
    return compute_emd_matrix(np.stack([compute_ims(v) for v in velocities]))


def stroke_amplitudes(velocity: Array, rate: float) -> Array:
    """Distance travelled (units) in each complete stroke (`velocity_strokes`), shape (k,).

    Strokes shorter than `MIN_STROKE_SECONDS` are left out.
    """
    strokes = velocity_strokes(velocity, max(3, round(MIN_STROKE_SECONDS * rate)))
    return np.array([np.abs(s).sum() / rate for s in strokes])


def amplitude_distances(velocities: Sequence[Array], rate: float) -> Array:
    """Wasserstein-1 distance (units) between the signals' stroke amplitudes, shape (n, n).

    NaN where a signal has no complete stroke.
    """
    amplitudes = [stroke_amplitudes(v, rate) for v in velocities]
    return _pairwise(
        len(amplitudes),
        lambda a, b: (
            scipy.stats.wasserstein_distance(amplitudes[a], amplitudes[b])
            if amplitudes[a].size and amplitudes[b].size
            else math.nan
        ),
    )


def velocity_spectrum(velocity: Array, rate: float) -> tuple[Array, Array]:
    """Welch power spectrum of a velocity up to `MAX_FREQUENCY`, normalised to sum to 1.

    Segments of `WELCH_SECONDS` (the whole signal if shorter), Hann window, half overlap.

    Returns
    -------
    tuple of numpy.ndarray
        Frequencies (Hz) and the share of power at each, both shape (m,).
    """
    segment = min(velocity.size, round(WELCH_SECONDS * rate))
    frequencies, power = scipy.signal.welch(velocity, fs=rate, nperseg=segment)
    keep = frequencies <= MAX_FREQUENCY
    total = power[keep].sum()
    if not total > 0:
        raise InputError(None, "a motion without velocity has no spectrum")
    return frequencies[keep], power[keep] / total


def spectrum_distances(velocities: Sequence[Array], rate: float) -> Array:
    """Wasserstein-1 distance (Hz) between the signals' velocity spectra, shape (n, n)."""
    spectra = [velocity_spectrum(v, rate) for v in velocities]
    return _pairwise(
        len(spectra),
        lambda a, b: scipy.stats.wasserstein_distance(
            spectra[a][0], spectra[b][0], spectra[a][1], spectra[b][1]
        ),
    )


def _pairwise(n: int, distance: Callable[[int, int], float]) -> Array:
    matrix = np.zeros((n, n))
    for a, b in itertools.combinations(range(n), 2):
        matrix[a, b] = matrix[b, a] = distance(a, b)
    return matrix


DISTANCES: dict[str, tuple[str, Callable[[Sequence[Array], float], Array]]] = {
    "velocity IMS EMD": ("", lambda velocities, _rate: ims_distances(velocities)),
    "amplitude": ("units", amplitude_distances),
    "spectrum": ("Hz", spectrum_distances),
}
"""Name -> (unit, distances between signals at a rate) of each distance in the battery."""


def verdict_line(distinguishable: bool, numbers: str) -> str:
    """``distinguishable: NUMBERS`` or ``indistinguishable at this data size: NUMBERS``."""
    words = "distinguishable" if distinguishable else "indistinguishable at this data size"
    return f"{words}: {numbers}"


@dataclass(frozen=True)
class DistanceResult:
    """One distance of the battery: candidate against reference, beside the person's own.

    Attributes
    ----------
    measure, unit
        Which distance (a key of `DISTANCES`) and its unit.
    to_reference
        Mean distance from each candidate signal to each reference signal.
    own
        Mean distance between the person's own trials (NaN with fewer than two).
    spread
        Mean distance between the candidate signals (NaN with fewer than two).
    test
        Permutation test of `between_minus_within`, labels permuted by trial.
    """

    measure: str
    unit: str
    to_reference: float
    own: float
    spread: float
    test: PermutationTest

    @property
    def ratio(self) -> float:
        """``to_reference / own``: 1 is as far as the person's trials are from each other."""
        return self.to_reference / self.own if self.own > 0 else math.nan

    @property
    def distinguishable(self) -> bool:
        """Whether the permutation test's p-value is below `ALPHA`."""
        return self.test.p_value < ALPHA

    def verdict(self) -> str:
        """One line: distinguishable or not, with both ratios and the p-value.

        The test asks whether the two sets are one distribution, so a candidate as near the
        held-out trials as the person's own but less varied (a small spread) is distinguishable.
        """
        if math.isnan(self.test.p_value):
            return f"not measured: {self.measure} (a trial without a complete stroke or motion)"
        spread = self.spread / self.own if self.own > 0 else math.nan
        numbers = (
            f"{self.ratio:.2f} x the person's own, spread {spread:.2f} x ({self.test.p_words()})"
        )
        return verdict_line(self.distinguishable, f"{self.measure} {numbers}")

    def to_json_dict(self) -> dict[str, Any]:
        """Return the numbers and the verdict."""
        return {
            "unit": self.unit,
            "to_reference": self.to_reference,
            "own": self.own,
            "spread": self.spread,
            "ratio": self.ratio,
            "test": self.test.to_json_dict(),
            "verdict": self.verdict(),
        }


def compare_distances(
    reference: Sequence[Array],
    candidate: Sequence[Array],
    own: Sequence[Array] | None = None,
    rate: float = DEFAULT_RATE,
    n_permutations: int = N_PERMUTATIONS,
    seed: int = 0,
) -> list[DistanceResult]:
    """Every distance of `DISTANCES`, candidate against reference, with its permutation test.

    Parameters
    ----------
    reference, candidate
        Velocity signals (units/s) at ``rate`` Hz, at least one each.
    own
        The person's trials whose pairwise distance is the baseline of the ratio (default:
        ``reference``).
    rate
        Sampling rate (Hz) of all signals.
    n_permutations, seed
        Of the permutation tests (`permutation_test`).
    """
    signals = [*reference, *candidate]
    labels = np.arange(len(signals)) >= len(reference)
    baseline = list(reference if own is None else own)
    results = []
    for (name, (unit, distances)), part_seed in zip(
        DISTANCES.items(), draw_seeds(seed, len(DISTANCES)), strict=True
    ):
        matrix = distances(signals, rate)
        own_matrix = distances(baseline, rate) if len(baseline) > 1 else np.zeros((1, 1))
        results.append(
            DistanceResult(
                measure=name,
                unit=unit,
                to_reference=float(np.mean(matrix[np.ix_(labels, ~labels)])),
                own=_mean_off_diagonal(own_matrix),
                spread=_mean_off_diagonal(matrix[np.ix_(labels, labels)]),
                test=permutation_test(
                    _between_minus_within_of(matrix),
                    labels,
                    n_permutations,
                    part_seed,
                ),
            )
        )
    return results


def _between_minus_within_of(distances: Array) -> Callable[[NDArray[np.bool_]], float]:
    return lambda side: between_minus_within(distances, side)


def _mean_off_diagonal(matrix: Array) -> float:
    i, j = np.triu_indices(matrix.shape[0], k=1)
    return float(matrix[i, j].mean()) if i.size else math.nan


FEATURE_NAMES = (
    *(f"{q}th percentile of velocity (units/s)" for q in (5, 25, 50, 75, 95)),
    "mean speed (units/s)",
    "90th percentile of speed (units/s)",
    "median |acceleration| (units/s²)",
    "90th percentile of |acceleration| (units/s²)",
    *(
        f"share of velocity power in {lo:g}-{hi:g} Hz"
        for lo, hi in itertools.pairwise(SPECTRUM_BANDS)
    ),
    "amplitude: SD of position (units)",
)
"""The words of each column of `window_features`, in order."""

FEATURE_GROUPS: dict[str, tuple[int, ...]] = {
    "velocity distribution": tuple(range(7)),
    "acceleration": (7, 8),
    "spectrum": tuple(range(9, 9 + len(SPECTRUM_BANDS) - 1)),
    "amplitude": (8 + len(SPECTRUM_BANDS),),
}
"""Groups of `window_features` columns whose separating power is reported apart
(`mirror_avatar.signatures.separation`)."""


def window_features(velocity: Array, rate: float) -> Array:
    """Features of each `WINDOW_SECONDS` window of a velocity, shape (k, 17).

    Per window: velocity quantiles (5, 25, 50, 75, 95 %), mean and 90th-percentile speed,
    median and 90th-percentile |acceleration|, the share of velocity power in each band of
    `SPECTRUM_BANDS` (7), and the SD of the position (the velocity integrated). The columns'
    words are `FEATURE_NAMES`, their groups `FEATURE_GROUPS`.
    """
    width = round(WINDOW_SECONDS * rate)
    hop = max(1, round(width * HOP_FRACTION))
    if velocity.size < width:
        raise InputError(
            None, f"the classifier's windows need {WINDOW_SECONDS:g} s of motion per trial"
        )
    windows = np.lib.stride_tricks.sliding_window_view(velocity, width)[::hop]
    speed = np.abs(windows)
    acceleration = np.abs(np.diff(windows, axis=1)) * rate
    power = np.abs(np.fft.rfft(windows * np.hanning(width), axis=1)) ** 2
    frequencies = np.fft.rfftfreq(width, 1.0 / rate)
    bands = np.stack(
        [
            power[:, (frequencies >= lo) & (frequencies < hi)].sum(axis=1)
            for lo, hi in itertools.pairwise(SPECTRUM_BANDS)
        ],
        axis=1,
    )
    shares = bands / np.maximum(bands.sum(axis=1, keepdims=True), np.finfo(float).tiny)
    position = np.cumsum(windows, axis=1) / rate
    return np.column_stack(
        [
            np.percentile(windows, [5, 25, 50, 75, 95], axis=1).T,
            speed.mean(axis=1),
            np.percentile(speed, 90, axis=1),
            np.median(acceleration, axis=1),
            np.percentile(acceleration, 90, axis=1),
            shares,
            position.std(axis=1),
        ]
    )


@dataclass(frozen=True)
class ClassifierTest:
    """The classifier two-sample test: out-of-fold AUC and its permutation test.

    Attributes
    ----------
    test
        The AUC (statistic), its values with the labels permuted by trial, and the p-value.
    n_reference, n_candidate
        Trials (or trial halves, see ``halves``, or people) of each side the classifier used.
    n_windows
        Windows of each side, ``(reference, candidate)``.
    folds
        Cross-validation folds.
    halves
        Whether a side with a single trial had it cut into two halves, each its own group.
    separation
        Which features separate the sets and which way (each group of `FEATURE_GROUPS` alone,
        the features that moved most).
    """

    test: PermutationTest
    n_reference: int
    n_candidate: int
    n_windows: tuple[int, int]
    folds: int
    halves: bool
    separation: Separation

    @property
    def auc(self) -> float:
        """Cross-validated AUC: 0.5 is chance, 1 tells every candidate window from the reference."""
        return self.test.statistic

    @property
    def distinguishable(self) -> bool:
        """Whether the AUC's p-value is below `ALPHA`."""
        return self.test.p_value < ALPHA

    def verdict(self) -> str:
        """One line: ``distinguishable: AUC 0.83 (...); told apart by ...`` or not.

        ``indistinguishable at this data size: AUC 0.55 (...)``; only a distinguishable verdict
        says why (`Separation.words`).
        """
        numbers = f"classifier AUC {self.auc:.2f} ({self.test.p_words()})"
        if self.distinguishable:
            numbers += f"; {self.separation.words()}"
        return verdict_line(self.distinguishable, numbers)

    def to_json_dict(self) -> dict[str, Any]:
        """Return the numbers and the verdict."""
        return {
            "auc": self.auc,
            "test": self.test.to_json_dict(),
            "n_reference": self.n_reference,
            "n_candidate": self.n_candidate,
            "n_windows": list(self.n_windows),
            "folds": self.folds,
            "halves": self.halves,
            "separation": self.separation.to_json_dict(),
            "verdict": self.verdict(),
        }


def classifier_test(
    reference: Sequence[Array],
    candidate: Sequence[Array],
    rate: float = DEFAULT_RATE,
    n_permutations: int = N_PERMUTATIONS,
    seed: int = 0,
    units: Sequence[str] | None = None,
) -> ClassifierTest:
    """Classifier two-sample test of windows of reference against candidate signals.

    A linear classifier (ridge-regularised least squares on standardised `window_features`,
    `mirror_avatar.signatures.ridge`: scikit-learn's ``RidgeClassifier`` in numpy); `FOLDS`-fold
    cross-validation stratified and grouped by trial (a trial's
    windows all in one fold); the mean over folds of each test fold's AUC (**choice**: the AUC
    of scores pooled over folds sits below 0.5 under the null with few trials, as each fold's
    model has its own offset); labels permuted by trial for the p-value, each relabelling
    cross-validated on the same folds' seed. A side of a single trial has it cut into two halves,
    each a group (**choice**: a test needs two groups a side). At most `MAX_UNITS` trials a side.

    Parameters
    ----------
    reference, candidate
        Velocity signals (units/s) at ``rate`` Hz, each at least `WINDOW_SECONDS` long.
    rate
        Sampling rate (Hz).
    n_permutations, seed
        Of the permutation test; ``seed`` also seeds the folds.
    units
        Whose each signal of ``[*reference, *candidate]`` is (a person): the groups of the folds
        and of the permutations instead of the signals, each unit on one side; every signal is
        used and none is halved.
    """
    if units is None:
        ref, ref_halves = _units(reference)
        cand, cand_halves = _units(candidate)
        unit_ids = list(range(len(ref) + len(cand)))
    else:
        ref, cand, ref_halves, cand_halves = list(reference), list(candidate), False, False
        unit_ids = [list(dict.fromkeys(units)).index(u) for u in units]
    signals = [*ref, *cand]
    features = [window_features(v, rate) for v in signals]
    groups = np.concatenate([np.full(len(f), u) for u, f in zip(unit_ids, features, strict=True)])
    x = np.concatenate(features)
    labels = np.zeros(max(unit_ids) + 1, dtype=bool)
    labels[unit_ids[len(ref) :]] = True
    if np.any(labels[unit_ids[: len(ref)]]):
        raise InputError(None, "a unit of the classifier test has signals on both sides")
    folds = min(FOLDS, int((~labels).sum()), int(labels.sum()))
    fold_seed, permutation_seed = draw_seeds(seed, 2)

    def auc(side: NDArray[np.bool_]) -> float:
        return _cross_validated_auc(x, side[groups], groups, folds, fold_seed)

    windows = (sum(len(f) for f in features[: len(ref)]), sum(len(f) for f in features[len(ref) :]))
    is_candidate = labels[groups]
    return ClassifierTest(
        test=permutation_test(auc, labels, n_permutations, permutation_seed),
        n_reference=int((~labels).sum()),
        n_candidate=int(labels.sum()),
        n_windows=windows,
        folds=folds,
        halves=ref_halves or cand_halves,
        separation=separation(
            x,
            is_candidate,
            FEATURE_NAMES,
            FEATURE_GROUPS,
            lambda columns: _cross_validated_auc(
                x[:, list(columns)], is_candidate, groups, folds, fold_seed
            ),
        ),
    )


def _cross_validated_auc(
    x: Array, y: NDArray[np.bool_], groups: NDArray[np.int_], folds: int, seed: int
) -> float:
    """Mean over folds of each test fold's AUC: folds stratified and grouped by unit.

    ``x`` has shape (n_windows, n_features), ``y`` and ``groups`` shape (n_windows,).
    """
    splitter = StratifiedGroupKFold(folds, shuffle=True, random_state=seed % 2**31)
    aucs = []
    for train, test in splitter.split(x, y, groups):
        aucs.append(roc_auc(y[test], ridge_scores(x[train], y[train], x[test])))
    return float(np.mean(aucs))


def _units(signals: Sequence[Array]) -> tuple[list[Array], bool]:
    """At most `MAX_UNITS` signals spread over the order; one signal cut into two halves."""
    if not signals:
        raise InputError(None, "the classifier test needs motion on both sides")
    if len(signals) == 1:
        half = signals[0].size // 2
        return [signals[0][:half], signals[0][half:]], True
    return spread(signals, MAX_UNITS), False


def spread(signals: Sequence[Array], n: int) -> list[Array]:
    """At most ``n`` of ``signals``, spread evenly over their order (first and last kept)."""
    keep = np.unique(np.linspace(0, len(signals) - 1, min(len(signals), n)).round())
    return [signals[int(k)] for k in keep]


@dataclass(frozen=True)
class Likeness:
    """The whole battery: the distances and the classifier test, with the seed used.

    ``classifier`` is None when the signals are too short for its windows (a held-out trial
    under two `WINDOW_SECONDS` windows): the distances judge alone, and the verdict says so.
    """

    distances: list[DistanceResult]
    classifier: ClassifierTest | None
    seed: int

    @property
    def distinguishable(self) -> bool:
        """Whether any test tells the candidate from the reference."""
        told = self.classifier is not None and self.classifier.distinguishable
        return told or any(d.distinguishable for d in self.distances)

    def verdict(self) -> str:
        """One line: the classifier's verdict, then the distances that tell the sets apart."""
        apart = [d.verdict().removeprefix("distinguishable: ") for d in self.distances]
        told = [v for v, d in zip(apart, self.distances, strict=True) if d.distinguishable]
        tail = f"; distances that tell them apart: {', '.join(told)}" if told else ""
        if self.classifier is None:
            head = (
                f"not measured: classifier (trials shorter than its {WINDOW_SECONDS:g} s windows)"
            )
            return head + tail
        return self.classifier.verdict() + tail

    def table(self) -> pd.DataFrame:
        """One row per test: its value, the person's own, the ratio, the p-value, the verdict."""
        rows = {
            f"{d.measure}{f' ({d.unit})' if d.unit else ''}": {
                "to held-out": d.to_reference,
                "person's own": d.own,
                "ratio": d.ratio,
                "spread": d.spread,
                "p": d.test.p_value,
                "verdict": d.verdict().partition(":")[0],
            }
            for d in self.distances
        }
        if self.classifier is not None:
            rows["classifier AUC (0.5 = chance)"] = {
                "to held-out": self.classifier.auc,
                "person's own": 0.5,
                "ratio": math.nan,
                "spread": math.nan,
                "p": self.classifier.test.p_value,
                "verdict": self.classifier.verdict().partition(":")[0],
            }
        return pd.DataFrame.from_dict(rows, orient="index")

    def to_json_dict(self) -> dict[str, Any]:
        """Return every test's numbers and verdict, and the seed."""
        return {
            "seed": self.seed,
            "verdict": self.verdict(),
            "distances": {d.measure: d.to_json_dict() for d in self.distances},
            "classifier": None if self.classifier is None else self.classifier.to_json_dict(),
        }


def compare_motion(
    reference: Sequence[Array],
    candidate: Sequence[Array],
    own: Sequence[Array] | None = None,
    rate: float = DEFAULT_RATE,
    n_permutations: int = N_PERMUTATIONS,
    seed: int = 0,
) -> Likeness:
    """Run the battery: whether ``candidate`` can be told from ``reference``.

    Parameters
    ----------
    reference
        A person's velocity signals (units/s) at ``rate`` Hz, held out of whatever made the
        candidate.
    candidate
        Velocity signals to judge (generated trials, an avatar's sessions).
    own
        The person's trials whose pairwise distances are their own variability (default
        ``reference``; give all their trials when few are held out).
    rate
        Sampling rate (Hz) of every signal.
    n_permutations, seed
        Of every permutation test; ``seed`` is recorded in the result.
    """
    distance_seed, classifier_seed = draw_seeds(seed, 2)
    try:
        classifier = classifier_test(reference, candidate, rate, n_permutations, classifier_seed)
    except InputError:  # signals too short for its windows: the distances judge alone
        classifier = None
    return Likeness(
        distances=compare_distances(reference, candidate, own, rate, n_permutations, distance_seed),
        classifier=classifier,
        seed=seed,
    )
