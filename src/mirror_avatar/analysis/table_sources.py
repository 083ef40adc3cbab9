"""The study table of a study's paths, composed one source at a time, in worker processes if asked.

`study_rows` reads each source of a study's paths (`mirror_avatar.analysis.trials.study_sources`:
a run folder, a BIDS dataset or one of its subject folders), measures its trials
(`mirror_avatar.analysis.table.trial_measures`) and composes their rows
(`mirror_avatar.analysis.table.trial_rows`) one source at a time, keeping only the rows: a
trial's recording is let go once it is measured, so memory grows with the rows, not with the
recordings. With ``jobs`` above 1 the sources are shared among that many worker processes,
forked from this one (so they start without importing the package again), each returning a
source's rows as it finishes it. The trial kept when one is read twice, and the rows' order,
are `mirror_avatar.analysis.trials.read_study_trials`'s, so the table is the same whatever
``jobs``: `mirror_avatar.analysis.table.study_table` of the trials read at once.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Iterator, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import pandas as pd

from mirror_avatar.analysis.outcomes import RunKey
from mirror_avatar.analysis.table import table_of_rows, trial_measures, trial_rows
from mirror_avatar.analysis.trials import (
    TrialIdentity,
    read_source,
    trial_identity,
    unique_trials,
)
from mirror_avatar.lab.export.run_outcomes import RunOutcomes


@dataclass(frozen=True)
class TrialRows:
    """One trial's rows and what the study's summary needs of it.

    Attributes
    ----------
    identity
        Which trial, and which recording of it.
    rows
        Its rows, one per player (`mirror_avatar.analysis.table.trial_rows`).
    questions
        Each question asked after it: (id, text), as its answers record them.
    complete
        Whether it ran to its end.
    duration
        Its session's length (s).
    measured
        Whether enough of it was left after the trim to be measured.
    """

    identity: TrialIdentity
    rows: list[dict[str, Any]]
    questions: list[tuple[str, str]]
    complete: bool
    duration: float
    measured: bool


@dataclass(frozen=True)
class StudyRows:
    """A study's table and the summary of its trials.

    Attributes
    ----------
    table
        The study table (`mirror_avatar.analysis.table.study_table`).
    questions
        Each question's text by id (`mirror_avatar.analysis.table.question_texts`).
    trials
        The trials, each read twice counted once.
    incomplete
        The trials that did not run to their end.
    measured
        The trials measured (long enough after the trim).
    longest
        The longest trial's length (s), 0 without trials.
    """

    table: pd.DataFrame
    questions: dict[str, str]
    trials: int
    incomplete: int
    measured: int
    longest: float


def study_rows(
    sources: Sequence[Path],
    trim: float,
    surrogates: int,
    outcomes: Mapping[RunKey, RunOutcomes],
    jobs: int = 1,
) -> StudyRows:
    """Make the study table of the trials under ``paths`` (module docstring).

    Parameters
    ----------
    sources
        The sources of the study's paths (`mirror_avatar.analysis.trials.study_sources`).
    trim, surrogates
        As `mirror_avatar.analysis.table.study_table` takes them (s; a count).
    outcomes
        The runs' outcomes (`mirror_avatar.analysis.outcomes.read_study_outcomes`).
    jobs
        Worker processes measuring the sources (1: none, this process measures them).

    Raises
    ------
    InputError
        As `mirror_avatar.analysis.trials.read_study_trials` raises it: a file of a trial that
        cannot be read, two recordings of one trial.
    """
    found = unique_trials(
        (
            trial
            for rows in _sources_rows(sources, trim, surrogates, outcomes, jobs)
            for trial in rows
        ),
        lambda trial: trial.identity,
    )
    questions = {qid: text for trial in found for qid, text in trial.questions}
    return StudyRows(
        table=table_of_rows([row for trial in found for row in trial.rows], outcomes),
        questions=questions,
        trials=len(found),
        incomplete=sum(not trial.complete for trial in found),
        measured=sum(trial.measured for trial in found),
        longest=max((trial.duration for trial in found), default=0.0),
    )


def _sources_rows(
    sources: Sequence[Path],
    trim: float,
    surrogates: int,
    outcomes: Mapping[RunKey, RunOutcomes],
    jobs: int,
) -> Iterator[list[TrialRows]]:
    """Yield each source's trials' rows, in the sources' order."""
    rows_of = partial(source_rows, trim=trim, surrogates=surrogates, outcomes=outcomes)
    if jobs <= 1 or len(sources) <= 1:
        yield from map(rows_of, sources)
        return
    fork = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(min(jobs, len(sources)), mp_context=fork) as pool:
        yield from pool.map(rows_of, sources)


def source_rows(
    source: Path, trim: float, surrogates: int, outcomes: Mapping[RunKey, RunOutcomes]
) -> list[TrialRows]:
    """Read, measure and compose the rows of one source's trials, in the source's order."""
    found = []
    for trial in read_source(source):
        measures = trial_measures(trial, trim, surrogates)
        answers = trial.answers.answers if trial.answers else ()
        found.append(
            TrialRows(
                identity=trial_identity(trial),
                rows=trial_rows(trial, measures or {}, outcomes),
                questions=[(answer.question, answer.text) for answer in answers],
                complete=trial.record.complete,
                duration=trial.session.duration,
                measured=measures is not None,
            )
        )
    return found
