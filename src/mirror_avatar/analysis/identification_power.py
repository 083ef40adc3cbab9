"""The power of the identification test, by simulating studies from a pilot's answers.

The report says whether persons told their partners' kinds apart by `Identification.chance_test`:
each person's rate of right answers a unit, their mean against chance by a two-sided one-sample
t-test (`mirror_avatar.analysis.identification`). A pilot's answers give the persons' rates'
mean and spread as a logit-normal model, the random-intercept logistic model of a person's
right answers (Jaeger 2008): person i is right with probability expit(mu + sigma z_i), z_i
standard normal, mu and sigma fitted by maximum marginal likelihood, the integral over z by the
trapezoidal rule on a fine grid. A simulated study draws n persons' probabilities around a
planned mean rate (mu moved, sigma kept), each person's right answers binomial over the
protocol's answers per person, and runs the report's test on them (`chance_tests`). The power
is the share of studies that say the planned side of chance (above chance for a rate above
it), with its binomial Monte Carlo standard error and Wilson interval
(`mirror_avatar.analysis.power`). docs/METHODS.md, section 15.1.1.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, special, stats

from mirror_avatar.analysis.identification import CHANCE, chance_tests, scored_answers
from mirror_avatar.analysis.power import CHUNK_VALUES, PowerPoint
from mirror_avatar.analysis.study_file import StudyTable
from mirror_avatar.analysis.study_report import analysed_rows
from mirror_avatar.analysis.study_text import ALPHA
from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.guesses import asks_identification
from mirror_avatar.lab.design.protocol import Protocol

NODES = np.linspace(-9.0, 9.0, 801)
"""Shape (801,): the values of z every expectation over z sums over (the trapezoidal rule: a
smooth integrand decaying as the normal density, whose error falls exponentially with the
nodes; Trefethen & Weideman 2014)."""

WEIGHTS = stats.norm.pdf(NODES) / stats.norm.pdf(NODES).sum()
"""Shape (801,): their weights, the standard normal density normalised to sum to 1."""

LOGIT_BOUND = 10.0
"""The largest |mu| fitted: a rate within 5e-5 of 0 or 1 (a pilot whose every answer is right)."""

SD_BOUND = 10.0
"""The largest sigma fitted, on the logit scale."""


@dataclass(frozen=True)
class RateSpread:
    """The persons' probabilities of a right answer: logit-normal.

    Parameters
    ----------
    logit_mean, logit_sd
        mu and sigma: a person's probability is expit(mu + sigma z), z standard normal.
    persons
        The pilot's persons who answered.
    answers
        The pilot's answers scored.
    pilot_rate
        The pilot's persons' mean rate of right answers (the report's).
    """

    logit_mean: float
    logit_sd: float
    persons: int
    answers: int
    pilot_rate: float

    @property
    def mean_rate(self) -> float:
        """The persons' mean probability of a right answer, E[expit(mu + sigma z)]."""
        return _mean_rate(self.logit_mean, self.logit_sd)

    def to_json(self) -> dict[str, Any]:
        """Return the pilot's rates in numbers, for ``power.json``."""
        return {
            "persons": self.persons, "answers": self.answers, "mean_rate": self.pilot_rate,
            "logit_mean": self.logit_mean, "logit_sd": self.logit_sd,
            "model_mean_rate": self.mean_rate,
        }  # fmt: skip

    def planned(self, rate: float) -> float:
        """Return the mu whose mean rate, with this sigma, is ``rate`` (0 < rate < 1)."""
        return float(optimize.brentq(lambda mu: _mean_rate(mu, self.logit_sd) - rate, -40, 40))


def _mean_rate(logit_mean: float, logit_sd: float) -> float:
    return float(WEIGHTS @ special.expit(logit_mean + logit_sd * NODES))


def log_likelihood(
    correct: NDArray[np.int64], answers: NDArray[np.int64], logit_mean: float, logit_sd: float
) -> float:
    """Return the logit-normal model's marginal log likelihood of the persons' counts.

    Parameters
    ----------
    correct, answers
        Shape (persons,): each person's right answers and answers.
    logit_mean, logit_sd
        mu and sigma.

    Returns
    -------
    float
        The sum over persons of log E_z[Binomial(correct; answers, expit(mu + sigma z))], the
        expectation by `NODES` and `WEIGHTS` (once per distinct count, times the persons with it).
    """
    counts, persons = np.unique(np.stack([correct, answers], axis=1), axis=0, return_counts=True)
    rate = special.expit(logit_mean + logit_sd * NODES)
    each = stats.binom.logpmf(counts[:, :1], counts[:, 1:], rate[None, :])
    return float(persons @ special.logsumexp(each, b=WEIGHTS[None, :], axis=1))


def fit_rates(correct: NDArray[np.int64], answers: NDArray[np.int64]) -> tuple[float, float]:
    """Return mu and sigma maximising `log_likelihood` (L-BFGS-B within the bounds)."""
    pooled = np.clip(correct.sum() / answers.sum(), 0.01, 0.99)
    found = optimize.minimize(
        lambda x: -log_likelihood(correct, answers, x[0], x[1]),
        x0=[special.logit(pooled), 0.5],
        method="L-BFGS-B",
        bounds=[(-LOGIT_BOUND, LOGIT_BOUND), (0.0, SD_BOUND)],
    )
    return float(found.x[0]), float(found.x[1])


def pilot_rates(table: StudyTable) -> RateSpread:
    """Fit the persons' rates of right answers in a pilot's table.

    The answers are those the report scores (`analysed_rows`, then
    `mirror_avatar.analysis.identification.scored_answers`).

    Raises
    ------
    InputError
        Fewer than two persons answered "person or computer?" about partners of one kind.
    """
    rows, _, _ = analysed_rows(table)
    answers, _ = scored_answers(rows)
    counts = answers.groupby("person")["right"].agg(["sum", "size"])
    if len(counts) < 2:
        raise InputError(table.source, f"{len(counts)} person(s) answered \"person or computer?\" "
                         "about partners of one kind: the identification test's spread needs "
                         "two or more (pilot with `lab pilot --answer ID=detect:P`)")  # fmt: skip
    correct, total = counts["sum"].to_numpy(np.int64), counts["size"].to_numpy(np.int64)
    logit_mean, logit_sd = fit_rates(correct, total)
    return RateSpread(logit_mean, logit_sd, persons=len(counts), answers=int(total.sum()),
                      pilot_rate=float(np.mean(correct / total)))  # fmt: skip


def answers_per_person(protocol: Protocol) -> int:
    """Count the trials of a participant after which the protocol asks "person or computer?".

    Raises
    ------
    InputError
        The protocol asks it after no trial.
    """
    asking = {qid for qid, q in protocol.questions.items() if asks_identification(q.text, q.kind)}
    found = sum(condition.trials for block in protocol.blocks for condition in block.conditions
                if asking & set(condition.after_trial))  # fmt: skip
    if found == 0:
        raise InputError(protocol.source, "asks \"person or computer?\" after no trial: the "
                         "identification test's power needs its answers, or give --trials K "
                         "answers per person")  # fmt: skip
    return found


def simulate_identification(
    spread: RateSpread,
    persons: int,
    answers: int,
    simulations: int,
    seed: int,
    rate: float | None = None,
) -> PowerPoint:
    """Simulate the identification test's power with ``persons`` persons.

    Parameters
    ----------
    spread
        The persons' rates (`pilot_rates`).
    persons, answers
        n per study, and each person's answers.
    simulations, seed
        The studies, and the seed; the generator is seeded by (``seed``, ``persons``), and the
        studies drawn in chunks of at most `CHUNK_VALUES` persons.
    rate
        The planned mean rate of right answers (default: the pilot's, `RateSpread.mean_rate`).

    Returns
    -------
    PowerPoint
        ``all_rejections``: the studies whose test is significant at the report's `ALPHA` on
        the planned side of chance (either side when the planned rate is chance itself);
        ``rejections`` those significant on either side.
    """
    rng = np.random.default_rng([seed, persons])
    planned = spread.mean_rate if rate is None else rate
    logit_mean = spread.planned(planned)
    chunk = max(1, CHUNK_VALUES // persons)
    significant, sided = 0, 0
    for start in range(0, simulations, chunk):
        shape = (min(chunk, simulations - start), persons)
        truth = special.expit(logit_mean + spread.logit_sd * rng.standard_normal(shape))
        correct = rng.binomial(answers, truth)
        found, p = chance_tests(correct, np.full(shape, answers))
        rejected = p < ALPHA
        side = np.sign(planned - CHANCE)
        significant += int(rejected.sum())
        sided += int((rejected & ((side == 0) | (np.sign(found - CHANCE) == side))).sum())
    return PowerPoint(persons, simulations, rejections=(significant,), all_rejections=sided)
