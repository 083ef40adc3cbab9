"""How the benchmark ranks its followers: by closeness to recorded humans, or by one measure.

Two kinds of criterion (``--rank-by``; METHODS, "Benchmark"):

- ``humans`` or ``humans:MEASURE,...``: the standardised distance of each follower's mean scores
  to the recorded human followers' mean scores over `HUMAN_MEASURES` (or the measures named):
  ``d = sqrt(mean_m ((f_m - h_m) / s_m)^2)`` with ``f_m`` the follower's and ``h_m`` the humans'
  mean of measure m over the same leaders and ``s_m`` the humans' standard deviation between
  their recordings (ddof 1), never under the measure's `FLOORS`. ``d = 1``: on average over the
  measures, one human standard deviation from the humans' mean.
- ``MEASURE``: the distance of each follower's mean to the measure's ideal value (`IDEALS`:
  0 for the errors, the lag and the EMD, 1 for phase locking and the amplitude ratio).

A follower lacking a measure (NaN, a follower that does not move) is ranked after every
follower that has it; ties keep the order given.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from mirror_avatar.common.errors import InputError
from mirror_avatar.experiments.partner_benchmark import HUMAN, SCORES, BenchmarkResult

HUMANS = "humans"
"""The criterion naming closeness to the recorded human followers."""

HUMAN_MEASURES = (
    "rms",
    "rpe",
    "time_lag",
    "phase_locking",
    "emd",
    "rms_velocity_error",
    "amplitude_ratio",
)
"""The measures of closeness to the humans by default (**choice**; METHODS states why): tracking
error, lateness, lag, phase locking, the velocity distribution, the corrective oscillation and
the amplitude. The largest errors are left out: one sample each, set by the leaders' tracking
drop-outs."""

IDEALS = {
    "rms": 0.0,
    "rpe": 0.0,
    "phase_locking": 1.0,
    "time_lag": 0.0,
    "emd": 0.0,
    "amplitude_ratio": 1.0,
    "max_position_error": 0.0,
    "max_velocity_error": 0.0,
    "rms_velocity_error": 0.0,
}
"""A perfect tracker's value of each score (`SCORES`), for ranking by one measure."""

FLOORS = {
    "rms": 0.005,
    "rpe": 0.005,
    "phase_locking": 0.01,
    "time_lag": 0.01,
    "emd": 0.005,
    "amplitude_ratio": 0.01,
    "max_position_error": 0.005,
    "max_velocity_error": 0.01,
    "rms_velocity_error": 0.01,
}
"""Smallest human spread each measure is divided by (**choice**: units, units, 1, s, 1, 1,
units, units/s, units/s; 0.005 units is 3 mm of a 60 cm playing range, 0.01 s one sample at
100 Hz), so that humans who happen to agree closely do not make a tiny difference count."""

MIN_HUMANS = 2
"""Fewest human recordings the distance to the humans needs (a spread between them)."""

NO_HUMANS_DEFAULT = "rms"
"""The criterion when no human follower is recorded: the task's own, tracking accuracy."""


@dataclass(frozen=True)
class Ranking:
    """The followers in order by a criterion, and the distance that ordered them.

    Attributes
    ----------
    criterion
        As given to ``--rank-by`` (``humans:...`` spelt out).
    measures
        The measures the distance is taken over.
    table
        One row per follower in rank order: ``distance`` and, per measure, the follower's
        mean and (by humans) its standardised difference ``z_MEASURE``.
    humans
        By humans: the humans' mean and the scale ``s`` of each measure (rows ``mean``,
        ``scale``); else empty.
    """

    criterion: str
    measures: tuple[str, ...]
    table: pd.DataFrame
    humans: pd.DataFrame

    def order(self) -> list[str]:
        """Return the followers, nearest first."""
        return list(self.table.index)

    def describe(self) -> str:
        """One sentence saying what the ranking measures."""
        if self.criterion.startswith(HUMANS):
            return (
                "nearest the recorded human followers first: RMS over "
                f"{', '.join(self.measures)} of (follower - humans) / the humans' spread"
            )
        (measure,) = self.measures
        return f"{measure} nearest its ideal {IDEALS[measure]:g} first"


def parse_criterion(text: str, have_humans: bool) -> tuple[str, tuple[str, ...]]:
    """Read ``--rank-by``: ``humans[:MEASURE,...]`` or one measure of `SCORES`.

    Returns
    -------
    tuple
        ``humans`` or the measure, and the measures the distance is taken over.

    Raises
    ------
    InputError
        ``--rank-by: ...`` for an unknown measure or ``humans`` without recorded humans.
    """
    known = ", ".join(SCORES)
    name, colon, listed = text.strip().partition(":")
    if name == HUMANS:
        if not have_humans:
            raise InputError(
                "--rank-by", f"{HUMANS} needs recorded human followers: give --humans FILES"
            )
        measures = tuple(m.strip() for m in listed.split(",") if m.strip()) if colon else ()
        unknown = [m for m in measures if m not in SCORES]
        if unknown or (colon and not measures):
            shown = unknown[0] if unknown else "(none)"
            raise InputError("--rank-by", f"unknown measure {shown}; measures are {known}")
        return HUMANS, measures or HUMAN_MEASURES
    if colon or name not in SCORES:
        raise InputError(
            "--rank-by", f"unknown criterion {text!r}; give {HUMANS}, {HUMANS}:MEASURE,... or "
            f"one of {known}",
        )  # fmt: skip
    return name, (name,)


def check_human_count(count: int) -> None:
    """Refuse ranking by humans with fewer than `MIN_HUMANS` recordings, in one line."""
    if count < MIN_HUMANS:
        raise InputError(
            "--humans", f"{count} recording(s) give no spread between the humans' trials to "
            f"scale the distance by; give {MIN_HUMANS} or more, or --rank-by a measure",
        )  # fmt: skip


def rank(result: BenchmarkResult, criterion: str, measures: tuple[str, ...]) -> Ranking:
    """Rank the followers of ``result`` (`parse_criterion`'s output)."""
    if criterion == HUMANS:
        return rank_by_humans(result, measures)
    return rank_by_measure(result, criterion)


def rank_by_measure(result: BenchmarkResult, measure: str) -> Ranking:
    """Rank by |mean - `IDEALS`[measure]|, nearest first."""
    means = result.summary().loc[result.followers(), [measure]]
    table = means.assign(distance=(means[measure] - IDEALS[measure]).abs())
    return Ranking(measure, (measure,), _ordered(table), pd.DataFrame())


def rank_by_humans(result: BenchmarkResult, measures: tuple[str, ...]) -> Ranking:
    """Rank by the standardised distance to the human followers (module docstring).

    Raises
    ------
    InputError
        ``--humans: ...`` with fewer than `MIN_HUMANS` human recordings (`check_human_count`).
    """
    human = result.trials.loc[result.trials["follower"] == HUMAN, list(measures)]
    check_human_count(len(human))
    floors = pd.Series({m: FLOORS[m] for m in measures})
    humans = pd.DataFrame({"mean": human.mean(), "scale": np.maximum(human.std(ddof=1), floors)})
    means = result.summary().loc[result.followers(), list(measures)]
    z = (means - humans["mean"]) / humans["scale"]
    usable = [m for m in measures if np.isfinite(humans["mean"][m])]
    distance = np.sqrt((z[usable] ** 2).mean(axis=1, skipna=False))
    table = means.join(z.add_prefix("z_")).assign(distance=distance)
    return Ranking(f"{HUMANS}:{','.join(measures)}", measures, _ordered(table), humans.T)


def _ordered(table: pd.DataFrame) -> pd.DataFrame:
    """Rows by ``distance``, NaN last, ties in the order given; ``distance`` first."""
    ordered = table.sort_values("distance", kind="stable", na_position="last")
    return ordered[["distance", *[c for c in ordered.columns if c != "distance"]]]
