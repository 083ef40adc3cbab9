"""Telling a person from a computer: the answers to "person or avatar?" scored (METHODS 15).

An answer is a row with a guess (``guess_kind``, "person" or "avatar") about a partner whose
true kind (``partner_kind``) is "person", "recording" (a person's recorded trial replayed: a
person's motion, `mirror_avatar.lab.design.guesses.MOTION_OF`) or "avatar"; rows whose partners
were mixed are left out. Scored as signal detection with the person as the signal: a hit is
"person" said of a person's motion, a false alarm "person" said of an avatar. Across persons,
each person's rate of right answers is a unit (`Identification.chance_test`): a person's answers
are not independent of each other, as the pooled binomial test takes them (docs/METHODS.md,
section 15.6); `chance_tests` runs the same test on many simulated studies at once (section 15.1.1).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray
from scipy import stats

from mirror_avatar.analysis.statistics import CONFIDENCE, has_spreads
from mirror_avatar.lab.design.guesses import MOTION_OF

CHANCE = 0.5
"""The rate of right answers by guessing between two kinds."""

KINDS = ("person", "avatar")


@dataclass(frozen=True)
class SignalDetection:
    """Sensitivity and bias of yes/no answers (Macmillan & Creelman 2005).

    Parameters
    ----------
    hits, misses, false_alarms, correct_rejections
        Counts: "person" and "avatar" said of persons, "person" and "avatar" said of avatars.
    hit_rate, false_alarm_rate
        The rates d' and c were computed from (corrected when ``corrected``).
    d_prime
        ``z(H) - z(F)``, z the standard normal quantile.
    criterion
        ``c = -(z(H) + z(F)) / 2``; negative: a bias towards answering "person".
    corrected
        Whether a rate of 0 or 1 called for the log-linear correction (Hautus 1995): 0.5 added
        to the hits and to the false alarms, 1 to the persons and to the avatars answered about.
    """

    hits: int
    misses: int
    false_alarms: int
    correct_rejections: int
    hit_rate: float
    false_alarm_rate: float
    d_prime: float
    criterion: float
    corrected: bool


def signal_detection(
    hits: int, misses: int, false_alarms: int, correct_rejections: int
) -> SignalDetection:
    """Return d' and criterion c of the counts, log-linear corrected when a rate is 0 or 1.

    Both are NaN when there were no persons or no avatars to answer about.
    """
    signal, noise = hits + misses, false_alarms + correct_rejections
    counts = {"hits": hits, "misses": misses, "false_alarms": false_alarms,
              "correct_rejections": correct_rejections}  # fmt: skip
    if signal == 0 or noise == 0:
        nan = float("nan")
        return SignalDetection(**counts, hit_rate=nan, false_alarm_rate=nan, d_prime=nan,
                               criterion=nan, corrected=False)  # fmt: skip
    hit_rate, false_alarm_rate = hits / signal, false_alarms / noise
    corrected = any(rate in (0.0, 1.0) for rate in (hit_rate, false_alarm_rate))
    if corrected:
        hit_rate, false_alarm_rate = (hits + 0.5) / (signal + 1), (false_alarms + 0.5) / (noise + 1)
    z_hit, z_false_alarm = stats.norm.ppf(hit_rate), stats.norm.ppf(false_alarm_rate)
    return SignalDetection(  # + 0.0: no unbiased criterion written as -0
        **counts, hit_rate=hit_rate, false_alarm_rate=false_alarm_rate,
        d_prime=float(z_hit - z_false_alarm), criterion=float(-(z_hit + z_false_alarm) / 2) + 0.0,
        corrected=corrected,
    )  # fmt: skip


@dataclass(frozen=True)
class Identification:
    """How well participants told persons from avatars.

    Parameters
    ----------
    answers, correct
        Answers scored and right answers, over all participants.
    rate, rate_ci_low, rate_ci_high
        ``correct / answers`` and its Clopper-Pearson interval.
    binomial_p
        Two-sided exact binomial test of ``correct`` against `CHANCE` (answers independent).
    detection
        Pooled signal detection.
    persons
        Persons who answered (a participant of a two-person protocol has two);
        ``person_d_prime_mean`` the mean of their own d' (each corrected as `signal_detection`
        says) and ``person_d_prime_p`` its one-sample t-test against 0 (persons as the unit;
        NaN for fewer than two).
    person_rate_mean, person_rate_p
        The mean of the persons' own rates of right answers, and its two-sided one-sample
        t-test against `CHANCE` (persons as the unit; NaN for fewer than two persons or rates
        all equal).
    confidence_right, confidence_wrong
        Mean confidence of right and of wrong answers (NaN without confidence ratings), over
        ``confidence_right_n`` and ``confidence_wrong_n`` answers; ``confidence_p`` the
        two-sided Mann-Whitney U test between them.
    per_person
        Per person who answered (``participant/person``, or the participant in a table
        without persons' labels): answers, correct, rate, hit_rate, false_alarm_rate, d_prime,
        criterion, corrected.
    per_condition
        Per condition (a partner's kind may be fixed by the condition, as in a three-arm
        design): answers, the partners' true kinds answered about (``partner_kind``), correct,
        rate, binomial_p (against `CHANCE`) and said_person, the share of answers "person".
    left_out
        Answers about mixed partners (persons and avatars together), not scored.
    """

    answers: int
    correct: int
    rate: float
    rate_ci_low: float
    rate_ci_high: float
    binomial_p: float
    detection: SignalDetection
    persons: int
    person_d_prime_mean: float
    person_d_prime_p: float
    person_rate_mean: float
    person_rate_p: float
    confidence_right: float
    confidence_wrong: float
    confidence_right_n: int
    confidence_wrong_n: int
    confidence_p: float
    per_person: pd.DataFrame
    per_condition: pd.DataFrame
    left_out: int

    @property
    def over_persons(self) -> bool:
        """Whether `chance_test` is the persons' t-test (else the pooled binomial)."""
        return not np.isnan(self.person_rate_p)

    @property
    def chance_test(self) -> tuple[float, float]:
        """Return the rate and the p-value that say whether answers beat chance.

        The persons' mean rate and its t-test over persons when there are two persons or more
        whose rates differ; else (one person, or every person's rate the same) the pooled rate
        and the exact binomial test of every answer.
        """
        if self.over_persons:
            return self.person_rate_mean, self.person_rate_p
        return self.rate, self.binomial_p

    def to_dict(self) -> dict[str, Any]:
        """Return every number, each table as a list of records."""
        found = asdict(self)
        for name in ("per_person", "per_condition"):
            found[name] = getattr(self, name).reset_index().to_dict(orient="records")
        return found


def scored_answers(rows: pd.DataFrame) -> tuple[pd.DataFrame, int]:
    """Return the answers to score and how many answers about mixed partners were left out.

    Returns
    -------
    tuple
        The answers (columns person, condition, partner (its true kind), truth (the right
        guess about it, `MOTION_OF`), guess, right, confidence; a row each with a guess of
        "person" or "avatar" about a partner of one true kind) and the number of guesses about
        mixed partners.
    """
    if "guess_kind" not in rows or "partner_kind" not in rows:
        columns = ["person", "condition", "partner", "truth", "guess", "right", "confidence"]
        return pd.DataFrame(columns=columns), 0
    guessed = rows[rows["guess_kind"].isin(KINDS)]
    scored = guessed[guessed["partner_kind"].isin(MOTION_OF)]
    confidence = scored.get("guess_confidence", pd.Series(np.nan, index=scored.index))
    truth = scored["partner_kind"].map(MOTION_OF)
    answers = pd.DataFrame({
        "person": _answerers(scored), "condition": scored["condition"],
        "partner": scored["partner_kind"], "truth": truth,
        "guess": scored["guess_kind"], "right": scored["guess_kind"] == truth,
        "confidence": pd.to_numeric(confidence, errors="coerce"),
    })  # fmt: skip
    return answers, len(guessed) - len(scored)


def identify(rows: pd.DataFrame, confidence: float = CONFIDENCE) -> Identification | None:
    """Score the answers in the rows; None when there are none."""
    answers, left_out = scored_answers(rows)
    if answers.empty:
        return None
    correct = int(answers["right"].sum())
    tested = stats.binomtest(correct, len(answers), CHANCE)
    interval = tested.proportion_ci(confidence, method="exact")
    per_person = pd.DataFrame(
        {p: _person_row(group) for p, group in answers.groupby("person")}
    ).T.rename_axis("person")
    per_condition = pd.DataFrame(
        {c: _condition_row(group) for c, group in answers.groupby("condition", sort=False)}
    ).T.rename_axis("condition")
    d_primes = per_person["d_prime"].astype(np.float64).dropna()
    rates = per_person["rate"].astype(np.float64)
    rated = answers.dropna(subset=["confidence"])
    right, wrong = rated.loc[rated["right"], "confidence"], rated.loc[~rated["right"], "confidence"]
    return Identification(
        answers=len(answers), correct=correct, rate=correct / len(answers),
        rate_ci_low=float(interval.low), rate_ci_high=float(interval.high),
        binomial_p=float(tested.pvalue), detection=_detection(answers),
        persons=len(per_person), person_d_prime_mean=_mean(d_primes),
        person_d_prime_p=float(one_sample_p(d_primes.to_numpy())),
        person_rate_mean=_mean(rates), person_rate_p=float(one_sample_p(rates.to_numpy() - CHANCE)),
        confidence_right=_mean(right), confidence_wrong=_mean(wrong),
        confidence_right_n=len(right), confidence_wrong_n=len(wrong),
        confidence_p=_mann_whitney_p(right.to_numpy(), wrong.to_numpy()),
        per_person=per_person, per_condition=per_condition, left_out=left_out,
    )  # fmt: skip


def _answerers(rows: pd.DataFrame) -> pd.Series:
    """Name who answered each row: ``participant/person``, or the participant alone."""
    if "person" not in rows:
        return rows["participant"].astype(str)
    return rows["participant"].astype(str) + "/" + rows["person"].astype(str)


def _detection(answers: pd.DataFrame) -> SignalDetection:
    said_person = answers["guess"] == "person"
    is_person = answers["truth"] == "person"
    return signal_detection(
        int((said_person & is_person).sum()), int((~said_person & is_person).sum()),
        int((said_person & ~is_person).sum()), int((~said_person & ~is_person).sum()),
    )  # fmt: skip


def _person_row(answers: pd.DataFrame) -> dict[str, Any]:
    detection = _detection(answers)
    return {
        "answers": len(answers), "correct": int(answers["right"].sum()),
        "rate": float(answers["right"].mean()), "hit_rate": detection.hit_rate,
        "false_alarm_rate": detection.false_alarm_rate, "d_prime": detection.d_prime,
        "criterion": detection.criterion, "corrected": detection.corrected,
    }  # fmt: skip


def _condition_row(answers: pd.DataFrame) -> dict[str, Any]:
    correct = int(answers["right"].sum())
    return {
        "answers": len(answers), "partners": ", ".join(sorted(set(answers["partner"]))),
        "correct": correct, "rate": correct / len(answers),
        "binomial_p": pooled_p(correct, len(answers)),
        "said_person": float((answers["guess"] == "person").mean()),
    }  # fmt: skip


def _mean(values: pd.Series) -> float:
    return float(values.mean()) if len(values) else float("nan")


def one_sample_p(values: NDArray[np.floating[Any]]) -> NDArray[np.float64]:
    """Two-sided one-sample t-test of each row (last axis) against 0: its p-value.

    Shape ``values.shape[:-1]``; NaN for a row of fewer than two values or values all equal
    (`mirror_avatar.analysis.statistics.has_spreads`).
    """
    p = np.full(values.shape[:-1], np.nan)
    tested = has_spreads(values) & (values.shape[-1] >= 2)
    if tested.any():
        p[tested] = stats.ttest_1samp(values[tested], 0.0, axis=-1).pvalue
    return p


def pooled_p(correct: int, answers: int) -> float:
    """Two-sided exact binomial test of ``correct`` right of ``answers`` against `CHANCE`."""
    return float(stats.binomtest(correct, answers, CHANCE).pvalue)


def chance_tests(
    correct: NDArray[np.int64], answers: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return `Identification.chance_test`'s rate and p for each set of persons' counts.

    Parameters
    ----------
    correct, answers
        Shape (studies, persons): each person's right answers and answers (answers > 0).

    Returns
    -------
    tuple of numpy.ndarray
        Shape (studies,) each: the persons' mean rate and its t-test's p (`one_sample_p` of
        the rates less `CHANCE`), or, for a study with fewer than two persons or every rate the
        same, the pooled rate and `pooled_p` of every answer.
    """
    rates = correct / answers
    rate, p = rates.mean(axis=-1), one_sample_p(rates - CHANCE)
    pooled = np.isnan(p)
    right, total = correct[pooled].sum(axis=-1), answers[pooled].sum(axis=-1)
    rate[pooled] = right / total
    counts, which = np.unique(np.stack([right, total], axis=-1), axis=0, return_inverse=True)
    p[pooled] = np.array([pooled_p(int(k), int(n)) for k, n in counts])[which.ravel()]
    return rate, p


def _mann_whitney_p(right: np.ndarray, wrong: np.ndarray) -> float:
    if right.size == 0 or wrong.size == 0:
        return float("nan")
    return float(stats.mannwhitneyu(right, wrong, alternative="two-sided").pvalue)
