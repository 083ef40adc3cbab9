"""A study's trials read back: each trial's session, record and answers, from run folders or BIDS.

`read_study_trials` takes any mix of the lab's run folders (a study participant's
``<out>/<protocol>-pNNN/``, a plain session's ``<out>/<session id>/``), folders holding them
(the lab's ``--out``), a BIDS dataset a lab export wrote (`mirror_avatar.lab.export.bids`) or one of
its subject folders. From a run folder, each trial's sidecar gives its record
(`mirror_avatar.files.trial_record.read_trial_record`) and ``trial-NN_answers.json`` its answers.
From a BIDS dataset (never its ``sourcedata/``), each trial is read once whichever of its people's
``_motion.tsv`` holds it (`mirror_avatar.sessions.loading.load_session`): the ``MirrorGame`` key
carries its record whole, read by the same reader (`mirror_avatar.files.trial_record.trial_record`)
as a sidecar's, so both sources give equal records; ``participants.tsv`` gives the study
participant's number and each ``_beh.tsv`` the answers.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import NamedTuple, TypeVar

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.bids.names import MISSING, bids_label, entities
from mirror_avatar.files.bids.reading import GAME_KEY, game_record, open_recording
from mirror_avatar.files.bids.tables import read_tsv, tsv_rows
from mirror_avatar.files.trial_record import (
    AnswerRecord,
    AnswersRecord,
    TrialRecord,
    read_answers_record,
    read_trial_record,
)
from mirror_avatar.lab.export.bids import TASK
from mirror_avatar.lab.export.bids_study import StudyRun, read_study, subject_label
from mirror_avatar.lab.files import (
    ANSWERS_SUFFIX,
    RECORD_PATTERN,
    TRIAL_PATTERN,
    companion,
    is_session_folder,
)
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.sessions.session import Session

T = TypeVar("T")

DATASET_FILE = "dataset_description.json"
"""The file that makes a folder a BIDS dataset's root."""


@dataclass(frozen=True)
class StudyTrial:
    """One trial of a study as read back.

    Attributes
    ----------
    participant
        The study participant (``p003``), or the session id of a plain lab session.
    record
        The trial's record.
    session
        Its N-player session.
    answers
        The answers given after it, None when none were asked.
    source
        The file it was read from.
    block, position
        The 1-based order of the trial's block and of its condition in the participant's run,
        counted over the run's trials as played.
    """

    participant: str
    record: TrialRecord
    session: Session
    answers: AnswersRecord | None
    source: Path
    block: int = 0
    position: int = 0


def read_study_trials(paths: Sequence[Path]) -> list[StudyTrial]:
    """Read every trial under ``paths`` (see the module docstring), by participant and trial.

    A trial read twice (a run folder and its export, a folder named twice) is kept once.

    Raises
    ------
    InputError
        A path that is neither a run folder, a folder of them, a BIDS dataset nor a subject
        folder of one; a file of a trial that cannot be read; two recordings of one trial of
        one participant's session (two labs' ``--out`` folders whose runs share names).
    """
    found = [trial for source in study_sources(paths) for trial in read_source(source)]
    return unique_trials(found, trial_identity)


def study_sources(paths: Sequence[Path]) -> list[Path]:
    """Return the sources of ``paths``' trials, in order: run folders, BIDS datasets or subjects.

    Raises
    ------
    InputError
        A path that is neither a run folder, a folder of them, a BIDS dataset nor a subject
        folder of one.
    """
    sources: list[Path] = []
    for path in paths:
        if not path.is_dir():
            raise InputError(
                path, "no such folder (give run folders, the lab's --out or a BIDS dataset)"
            )
        if is_session_folder(path) or _is_bids(path):
            sources.append(path)
        else:
            runs = sorted(p for p in path.iterdir() if p.is_dir() and is_session_folder(p))
            if not runs:
                raise InputError(
                    path, "no run folder (plan.json or study.json) and not a BIDS dataset in it"
                )
            sources += runs
    return sources


def read_source(source: Path) -> list[StudyTrial]:
    """Read the trials of one source `study_sources` returns: a run folder or a BIDS dataset."""
    return read_run_folder(source) if is_session_folder(source) else read_bids_trials(source)


def _is_bids(path: Path) -> bool:
    return (path / DATASET_FILE).is_file() or path.name.startswith("sub-")


class TrialIdentity(NamedTuple):
    """What tells a trial from another, and one recording of it from another.

    Attributes
    ----------
    key
        The participant, the session id and the trial number.
    recorded
        When it was created and started (UTC, as its record says).
    source
        The file it was read from.
    """

    key: tuple[str, str, int]
    recorded: tuple[str | None, str | None]
    source: Path


def trial_identity(trial: StudyTrial) -> TrialIdentity:
    """Return a trial's `TrialIdentity`."""
    record = trial.record
    return TrialIdentity(
        (trial.participant, record.session_id, record.trial),
        (record.created_utc, record.started_utc),
        trial.source,
    )


def unique_trials(found: Iterable[T], identity: Callable[[T], TrialIdentity]) -> list[T]:
    """Keep one of each trial (`read_study_trials`), the first read, ordered by trial.

    ``identity`` gives the `TrialIdentity` of each item of ``found``.

    Raises
    ------
    InputError
        Two recordings of one trial of one participant's session.
    """
    unique: dict[tuple[str, str, int], T] = {}
    for item in found:
        found_id = identity(item)
        kept = identity(unique.setdefault(found_id.key, item))
        if kept.recorded != found_id.recorded:
            raise InputError(
                found_id.source,
                f"trial {found_id.key[2]} of {found_id.key[1]} is also {kept.source}, recorded "
                "at another time: give the folders of one lab --out (pilot the other with other "
                "participant numbers, lab pilot --first, to read both)",
            )
    return [unique[key] for key in sorted(unique)]


def participant_name(study: StudyRun | None, session_id: str) -> str:
    """Name a study participant ``pNNN`` (their number), a plain session by its id."""
    return session_id if study is None else f"p{study.participant:03d}"


def read_run_folder(folder: Path) -> list[StudyTrial]:
    """Read the trials of one lab run folder, in trial order.

    Raises
    ------
    InputError
        A trial's file that cannot be read, or a trial's record kept without its recording
        (never read as if the trial had not been played).
    """
    study = read_study(folder)
    _check_recordings(folder)
    trials: list[StudyTrial] = []
    for path in sorted(folder.glob(TRIAL_PATTERN)):
        record = read_trial_record(path.with_suffix(".json"))
        answers_file = companion(path, ANSWERS_SUFFIX)
        answers = read_answers_record(answers_file) if answers_file.is_file() else None
        trials.append(
            StudyTrial(
                participant_name(study, record.session_id),
                record,
                load_session(path),
                answers,
                path,
            )  # fmt: skip
        )
    return _number(trials)


def _check_recordings(folder: Path) -> None:
    """Refuse a trial's record (sidecar) whose recording is missing."""
    for sidecar in sorted(folder.glob(RECORD_PATTERN)):
        recording = sidecar.with_suffix(".csv")
        if not recording.is_file():
            raise InputError(
                recording,
                f"missing, but its record {sidecar.name} is kept: restore the recording, or "
                "move the record away to leave the trial out",
            )


def read_bids_trials(path: Path) -> list[StudyTrial]:
    """Read the lab trials of a BIDS dataset, or of one of its subject folders (not sourcedata).

    A subject folder's trials are placed in their run (block, position) by every subject's.
    """
    root = path if (path / DATASET_FILE).is_file() else path.parent
    subjects = sorted(root.glob("sub-*"))
    _, participants = read_tsv(root / "participants.tsv", "participant_id")
    by_trial: dict[tuple[str, int], StudyTrial] = {}
    holders: dict[tuple[str, int], set[str]] = {}
    for motion in (m for s in subjects for m in sorted(s.glob(f"motion/*{_MOTION}"))):
        recording = open_recording(motion)
        game = recording.info.get(GAME_KEY)
        if not isinstance(game, dict):
            continue
        record = game_record(recording.sidecar, game)
        key = (record.session_id, record.trial)
        holders.setdefault(key, set()).add(motion.parents[1].name)
        if key not in by_trial:
            by_trial[key] = _bids_trial(root, motion, record, participants)
    numbered = _number(list(by_trial.values()))
    if not path.name.startswith("sub-"):
        return numbered
    return [t for t in numbered if path.name in holders[(t.record.session_id, t.record.trial)]]


_MOTION = "_motion.tsv"


def _bids_trial(
    root: Path, motion: Path, record: TrialRecord, participants: dict[str, dict[str, str]]
) -> StudyTrial:
    """Read one exported trial of ``record`` (its ``MirrorGame`` key's): session and answers.

    Raises
    ------
    InputError
        A study's trial whose key carries no study (an export by a version before the record
        was carried whole).
    """
    session = load_session(motion)
    subject = f"sub-{entities(motion.name).get('sub', '')}"
    study = _study_run(participants.get(subject, {}))
    if study is not None and record.study is None:
        raise InputError(
            motion.with_name(motion.name.replace(".tsv", ".json")),
            f"{GAME_KEY} carries no study record (an export by an earlier version): read the "
            f"run folder sourcedata/{record.session_id}/ instead, or export it again",
        )
    answers = _bids_answers(root, record, study)
    return StudyTrial(participant_name(study, record.session_id), record, session, answers, motion)


def _study_run(row: dict[str, str]) -> StudyRun | None:
    """Return the study run a ``participants.tsv`` row names, None outside a study."""
    number = row.get("study_participant", MISSING)
    return None if not number.isdigit() else StudyRun(int(number), row.get("protocol", ""))


def _rows(path: Path) -> list[dict[str, str]]:
    """Read a TSV table's rows (none when the file is absent)."""
    if not path.is_file():
        return []
    return tsv_rows(path)[1]


def _bids_answers(root: Path, record: TrialRecord, study: StudyRun | None) -> AnswersRecord | None:
    """Read every person's ``_beh.tsv`` of a trial into one answers record (None: no answers)."""
    answers: list[AnswerRecord] = []
    first: dict[str, str] = {}
    acquisition = bids_label(record.session_id)
    for slot in (s for s in record.slots if s.kind == "human"):
        subject = f"sub-{subject_label(slot.label, study)}"
        name = f"{subject}_task-{TASK}_acq-{acquisition}_run-{record.trial}_beh.tsv"
        for row in _rows(root / subject / "beh" / name):
            first = first or row
            answers.append(AnswerRecord(
                label=slot.label, question=row["question"], text=row["text"], kind=row["kind"],
                value=_answer_value(row["answer"], row["kind"]), after=row["after"],
                utc=None if row["answered_utc"] == MISSING else row["answered_utc"],
            ))  # fmt: skip
    if not answers:
        return None
    return AnswersRecord(record.trial, first["block"], first["condition"], tuple(answers))


def _answer_value(cell: str, kind: str) -> object:
    """Return an answer as the lab recorded it: a Likert point as an integer, else the text."""
    if cell == MISSING:
        return None
    return int(cell) if kind == "likert" and cell.lstrip("-").isdigit() else cell


def _number(trials: Iterable[StudyTrial]) -> list[StudyTrial]:
    """Place each trial in its participant's run: its block and position.

    The two are counted over the run's trials in order; a plain session's trials are of one
    block, a condition being the game. A trial's number within its condition is its record's
    (`mirror_avatar.files.trial_record.StudyRecord.condition_trial`), as the lab played it.
    """
    numbered: list[StudyTrial] = []
    blocks: list[str] = []
    conditions: list[tuple[str, str]] = []
    run: tuple[str, str] | None = None
    for trial in sorted(trials, key=lambda t: (t.participant, t.record.session_id, t.record.trial)):
        record, study = trial.record, trial.record.study
        if run != (trial.participant, record.session_id):
            run, blocks, conditions = (trial.participant, record.session_id), [], []
        here = ("", record.condition) if study is None else (study.block, study.condition)
        if not blocks or blocks[-1] != here[0]:
            blocks.append(here[0])
        if not conditions or conditions[-1] != here:
            conditions.append(here)
        numbered.append(replace(trial, block=len(blocks), position=len(conditions)))
    return numbered
