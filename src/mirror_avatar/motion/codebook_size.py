"""The IMS generator's codebook size: swept on held-out trials or chosen by cross-validation.

METHODS section 4, step 3: the paper fixed N = 256 after a sweep over 32-256 on 30 trials per
person; on a person's few trials the size is chosen by leave-one-trial-out cross-validation with
the one-standard-error rule (`choose_n_symbols`). Both work on any generator a factory makes for
a codebook size (`mirror_avatar.motion.generator.IMSGenerator.with_symbols`), so that this module
needs no generator of its own.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any, Protocol, Self

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.progress import counted
from mirror_avatar.files.trials import Trial, compute_velocity
from mirror_avatar.signatures.signature import compute_emd, compute_ims

Array = NDArray[np.float64]

MIN_FRAMES_PER_SYMBOL = 4
"""Fewest STFT frames per code vector a codebook is fitted on (**choice**: with fewer, most code
vectors are single frames and the chain only replays the training trials)."""

SYMBOL_CANDIDATES = (8, 16, 32, 64, 128, 256)
"""Codebook sizes `choose_n_symbols` tries (**choice**: powers of two up to the paper's 256)."""

CV_SAMPLES = 3
"""Generated trials compared with each held-out trial when cross-validating (**choice**)."""


class SizedGenerator(Protocol):
    """What the functions here need of a generator (`motion.generator.IMSGenerator`)."""

    rate: float
    random_state: int | None
    n_symbols_: int
    training_summary_: dict[str, Any]

    def fit(self, trials: Sequence[Trial]) -> Self:
        """Learn from trials."""

    def sample(self, duration: float, n: int = 1, random_state: Any = None) -> list[Trial]:
        """Generate ``n`` trials of ``duration`` seconds."""

    def score(self, trials: Sequence[Trial]) -> dict[str, float]:
        """Distortion, symbols used and log-likelihood on trials."""

    def frame_features(self, trial: Trial) -> Array:
        """STFT feature vectors of a trial's frames, shape (frames, window)."""

    def signal(self, trial: Trial) -> Array:
        """Return a trial's positions at the generator's rate."""


GeneratorFactory = Callable[[int], SizedGenerator]
"""Codebook size -> an unfitted generator of that size (and fixed other settings)."""


def sweep_codebook(
    make_generator: GeneratorFactory,
    train_trials: Sequence[Trial],
    test_trials: Sequence[Trial],
    sizes: Sequence[int] = (32, 64, 128, 256),
    random_state: int | None = 0,
    duration: float = 60.0,
) -> pd.DataFrame:
    """Fit a generator for each codebook size and compare it with held-out human trials.

    The paper chose N = 256 after such a sweep over 32-256 (METHODS section 4, step 3).

    Parameters
    ----------
    make_generator
        Codebook size -> unfitted generator (its seed seeds k-means).
    train_trials
        Trials the generators are fitted on.
    test_trials
        Held-out human trials of the same person or style (at least one).
    sizes
        Codebook sizes N to try.
    random_state
        Seed of the generated trials (the same for every size).
    duration
        Length (s) of each generated trial; as many are generated as there are test trials.

    Returns
    -------
    pandas.DataFrame
        Indexed by ``n_symbols``, columns ``train_distortion`` and ``test_distortion`` (mean
        squared quantisation error per feature), ``test_symbols_used`` (fraction of code vectors
        the test frames use: the training frames use them all, k-means leaving no code vector
        without one), ``test_log_likelihood`` (mean log-probability per transition of the
        test trials' symbols) and ``emd_to_test`` (mean EMD between the IMS of each generated
        trial and each test trial).
    """
    if not test_trials:
        raise InputError("test_trials", "the codebook sweep needs held-out trials")
    rows = []
    for size in sizes:
        model = make_generator(int(size)).fit(train_trials)
        human = [_trial_ims(model, t) for t in test_trials]
        test = model.score(test_trials)
        generated = model.sample(duration, n=len(test_trials), random_state=random_state)
        emd = [compute_emd(compute_ims(g.velocity()), h) for g in generated for h in human]
        rows.append(
            {
                "n_symbols": int(size),
                "train_distortion": model.training_summary_["distortion"],
                "test_distortion": test["distortion"],
                "test_symbols_used": test["symbols_used"],
                "test_log_likelihood": test["log_likelihood"],
                "emd_to_test": float(np.mean(emd)),
            }
        )
    return pd.DataFrame(rows).set_index("n_symbols")


def choose_n_symbols(
    trials: Sequence[Trial],
    make_generator: GeneratorFactory,
    candidates: Sequence[int] = SYMBOL_CANDIDATES,
) -> dict[str, Any]:
    """Choose a codebook size for ``trials`` by leave-one-trial-out cross-validation.

    Each trial is held out in turn (a single trial is split into two halves); a generator of
    each candidate size is fitted on the others and generates `CV_SAMPLES` trials as long as
    the held-out one, and the score of a size is the mean EMD between their IMS and the
    held-out trial's. The smallest size whose score lies within one standard error of the best
    is chosen (the one-standard-error rule, Hastie, Tibshirani & Friedman, *The Elements of
    Statistical Learning*, section 7.10): the simplest chain that generates motion as close to
    the person's unseen trials as the best one. Sizes for which some fold has fewer than
    `MIN_FRAMES_PER_SYMBOL` frames per symbol, or fewer distinct frames than symbols (motion
    that repeats exactly), are not tried. **Choice** (the paper fixed 256
    after a sweep on 30 trials per person; METHODS section 4).

    Parameters
    ----------
    trials
        The person's solo trials.
    make_generator
        Codebook size -> unfitted generator with the other settings; its ``random_state``
        seeds every fit and every generated trial.
    candidates
        Codebook sizes to try.

    Returns
    -------
    dict
        ``rule``, ``chosen``, ``candidates`` (the sizes tried), ``emd_mean`` and ``emd_se``
        (per size), ``folds`` and ``human_emd`` (mean EMD between the IMS of two of the
        person's trials: the scale a score is to be read against; NaN for a single trial).

    Raises
    ------
    InputError
        Too few frames for the smallest candidate.
    """
    folds = _folds(trials)
    fitted = make_generator(min(candidates))
    seed = fitted.random_state
    frames = [_frame_counts(fitted, train) for train, _ in folds]
    feasible = [
        int(n)
        for n in sorted(candidates)
        if all(MIN_FRAMES_PER_SYMBOL * n <= total and n <= distinct for total, distinct in frames)
    ]
    if not feasible:
        raise InputError(
            "trials",
            f"{min(total for total, _ in frames)} frames per cross-validation fold are too few "
            f"for {min(candidates)} symbols: give more or longer trials",
        )
    human = [_trial_ims(fitted, t) for t in trials]
    scores = np.empty((len(feasible), len(folds)))
    for j, (train, held_out) in counted(enumerate(folds), len(folds), "choosing symbols", "fold"):
        target = _trial_ims(fitted, held_out)
        for i, size in enumerate(feasible):
            model = make_generator(size).fit(train)
            generated = model.sample(held_out.duration, n=CV_SAMPLES, random_state=seed)
            scores[i, j] = np.mean([compute_emd(_trial_ims(model, g), target) for g in generated])
    mean = scores.mean(axis=1)
    se = scores.std(axis=1, ddof=1) / math.sqrt(len(folds))
    chosen = feasible[one_standard_error_rule(scores)]
    pairs = [compute_emd(a, b) for k, a in enumerate(human) for b in human[k + 1 :]]
    return {
        "rule": "cross-validation, one standard error",
        "chosen": chosen,
        "candidates": feasible,
        "emd_mean": [round(float(m), 6) for m in mean],
        "emd_se": [round(float(e), 6) for e in se],
        "folds": len(folds),
        "human_emd": round(float(np.mean(pairs)), 6) if pairs else math.nan,
    }


def one_standard_error_rule(scores: Array) -> int:
    """Pick the simplest model whose mean score is within one standard error of the best.

    Parameters
    ----------
    scores
        Cross-validation scores (lower is better), shape (models, folds), models ordered from
        the simplest; at least two folds.

    Returns
    -------
    int
        The index of the first model whose mean is at most the best mean plus the best
        model's standard error of the mean (Hastie, Tibshirani & Friedman, section 7.10).
    """
    mean = scores.mean(axis=1)
    se = scores.std(axis=1, ddof=1) / math.sqrt(scores.shape[1])
    best = int(np.argmin(mean))
    return int(np.argmax(mean <= mean[best] + se[best]))


def _frame_counts(model: SizedGenerator, trials: Sequence[Trial]) -> tuple[int, int]:
    """Count the STFT frames of ``trials``, and the distinct ones (a codebook's most).

    Frames equal to 9 decimals (units) count as one: motion that repeats exactly repeats its
    frames up to rounding.
    """
    features = np.vstack([model.frame_features(t) for t in trials])
    return len(features), len(np.unique(np.round(features, 9), axis=0))


def _folds(trials: Sequence[Trial]) -> list[tuple[list[Trial], Trial]]:
    """Training trials and the held-out trial of each fold (one trial: its two halves)."""
    if len(trials) == 1:
        (trial,) = trials
        middle = trial.n_samples // 2
        halves = [
            replace(trial, times=trial.times[part], positions=trial.positions[part])
            for part in (slice(None, middle), slice(middle, None))
        ]
        return [([halves[0]], halves[1]), ([halves[1]], halves[0])]
    return [([t for k, t in enumerate(trials) if k != j], trials[j]) for j in range(len(trials))]


def _trial_ims(model: SizedGenerator, trial: Trial) -> Array:
    """Compute the IMS of ``trial`` at the model's rate."""
    return compute_ims(compute_velocity(model.signal(trial), model.rate))
