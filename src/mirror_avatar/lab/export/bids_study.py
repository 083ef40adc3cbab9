"""A study's subjects and answers, and every recording's acquisition time, in a BIDS export.

Subjects: the people of different participants' runs of a study are different people, so the
BIDS subject of a person in a study session (its folder holds ``study.json``:
`mirror_avatar.lab.running.study`) is the participant's number and the person's label in the
protocol,
``sub-p003P1`` for person ``P1`` of participant 3 (`subject_label`); outside a study it is the
slot's label (``sub-P1``). Labels keep only their letters and digits.

Answers (BIDS 1.9.0, behavioural experiments): the answers a participant gave after trial n
(``trial-NN_answers.json`` of a study session: `mirror_avatar.lab.running.study`) become
``sub-<sub>/beh/sub-<sub>_task-mirrorgame_acq-<acq>_run-<n>_beh.tsv``, one row per question,
its columns (`BEH_COLUMNS`) described once for the dataset in ``task-mirrorgame_beh.json``.

Acquisition times: each subject's ``sub-<sub>/sub-<sub>_scans.tsv`` lists every file of theirs
the export wrote (``filename`` relative to the subject's folder) with its ``acq_time``: when the
trial's first sample was taken (its sidecar's ``started_utc``, else its ``created_utc``: the
trial's files are created just before its first sample), in UTC as BIDS writes it
(``YYYY-MM-DDThh:mm:ss.ffffffZ``), then the trial, block and condition (`SCAN_COLUMNS`,
described in ``scans.json``). Rows already there from another export are kept.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import write_atomic_json, write_atomic_text
from mirror_avatar.files.bids.names import MISSING, bids_label
from mirror_avatar.files.bids.tables import read_tsv
from mirror_avatar.files.bids.writing import tsv_table
from mirror_avatar.files.trial_io import read_sidecar_text
from mirror_avatar.files.trial_record import (
    KIND_NAMES,
    AnswersRecord,
    SlotRecord,
    TrialRecord,
    partner_kind,
    read_answers_record,
)
from mirror_avatar.files.user_files import parse_json
from mirror_avatar.lab.files import ANSWERS_SUFFIX, STUDY_FILE, companion

BEH_COLUMNS = (
    "question", "text", "kind", "answer", "partners", "partner_kind", "after", "trial", "block",
    "condition", "answered_utc",
)  # fmt: skip
"""Columns of a ``_beh.tsv``."""

BEH_COLUMN_INFO: dict[str, Any] = {
    "question": {"Description": "Identifier of the question in the study protocol"},
    "text": {"Description": "The question as the participant's page showed it"},
    "kind": {
        "Description": "How the question is answered",
        "Levels": {
            "choice": "one of the options the question offers",
            "likert": "a point of a Likert scale, 1 to the scale's number of points",
            "text": "free text",
        },
    },
    "answer": {"Description": "The participant's answer: the option, the point or the text"},
    "partners": {
        "Description": "The labels of the participant's partners in the trial, joined "
        "by + (n/a: none)"
    },
    "partner_kind": {
        "Description": "The true kind of the participant's partners in the trial, beside the "
        "answer (to score a person-or-computer question without a join)",
        "Levels": {
            "person": "every partner a person",
            "avatar": "every partner a computer player",
            "mixed": "persons and computer players",
            "none": "no partner (a solo trial)",
        },
    },
    "after": {
        "Description": "When the question was asked",
        "Levels": {"trial": "after the trial", "block": "after the last trial of the block"},
    },
    "trial": {"Description": "The trial after which it was asked (the run's index)"},
    "block": {"Description": "The block of the study protocol the trial belongs to"},
    "condition": {"Description": "The study protocol's condition of the trial"},
    "answered_utc": {"Description": "When the answer was given (UTC, ISO 8601)"},
}
"""The answers' columns, described once for the dataset (``task-<task>_beh.json``)."""

SCAN_COLUMNS = ("filename", "acq_time", "trial", "block", "condition")
"""Columns a ``_scans.tsv`` gets from the export (others already there are kept)."""

SCAN_COLUMN_INFO: dict[str, Any] = {
    "acq_time": {
        "Description": "When the trial's first sample was taken (UTC; the lab's clock, whose "
        "own times are the recording's clock channel)"
    },
    "trial": {"Description": "Number of the trial in its session (the run's index)"},
    "block": {"Description": "Block of the study protocol the trial belongs to (n/a: no study)"},
    "condition": {"Description": "Condition of the trial (the study protocol's, else the lab's)"},
}
"""The scans' columns beyond ``filename``, described once for the dataset (``scans.json``)."""


@dataclass(frozen=True)
class StudyRun:
    """Whose run of which protocol a study session is.

    ``participant`` is the participant's number (0-based: their row of the counterbalancing)
    and ``protocol`` the protocol's file name without its extension (the session's folder is
    ``<protocol>-p<participant:03d>``).
    """

    participant: int
    protocol: str

    def cells(self) -> dict[str, str]:
        """Return the run's ``participants.tsv`` cells (`STUDY_COLUMNS`)."""
        return {"study_participant": str(self.participant), "protocol": self.protocol}


STUDY_COLUMNS = ("study_participant", "protocol")
"""Columns ``participants.tsv`` gets when a study session is exported."""


def read_study(session_dir: Path) -> StudyRun | None:
    """Read whose run a study session folder holds (its `STUDY_FILE`); None outside a study.

    Raises
    ------
    InputError
        A ``study.json`` that is not a JSON object with a participant number (an integer, 0 or
        more) and its protocol's source.
    """
    path = session_dir / STUDY_FILE
    if not path.is_file():
        return None
    study = parse_json(read_sidecar_text(path), path)
    participant = study.get("participant") if isinstance(study, dict) else None
    if isinstance(participant, bool) or not isinstance(participant, int) or participant < 0:
        raise InputError(path, f"participant {participant!r} is not a participant number")
    source = _mapping(study.get("protocol")).get("source")
    if not isinstance(source, str) or not source:
        raise InputError(path, "no protocol source: not a study session's schedule")
    return StudyRun(participant, Path(source).stem)


def subject_label(
    label: str, study: StudyRun | None, source: str | os.PathLike[str] | None = None
) -> str:
    """Return the BIDS subject label of the person labelled ``label``.

    ``label`` with its non-alphanumeric characters removed (`mirror_avatar.files.bids.names.
    bids_label`), after ``p`` and the participant's number on three digits or more in a study:
    ``P_1`` gives ``P1``, and ``p003P1`` in participant 3's run. One label gives a different
    subject label in every participant's run; two different labels may still give one
    (``P_1`` and ``P1``; ``0P1`` of participant 100 and ``P1`` of participant 1000), which the
    export refuses.
    """
    person = bids_label(label, source)
    return person if study is None else f"p{study.participant:03d}{person}"


def acq_time(record: TrialRecord) -> str:
    """Return when a trial's first sample was taken, as a BIDS ``acq_time``, or ``n/a``.

    The record's ``started_utc``, else its ``created_utc``; converted to UTC and written
    ``YYYY-MM-DDThh:mm:ss.ffffffZ``.
    """
    for stamp in (record.started_utc, record.created_utc):
        if stamp is not None:
            try:
                moment = datetime.fromisoformat(stamp)
            except ValueError:
                continue
            moment = moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment
            return moment.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    return MISSING


def trial_row(record: TrialRecord) -> dict[str, str]:
    """Return a trial's ``trial``, ``block`` and ``condition`` cells."""
    cells = (record.trial, record.block, record.named_condition)
    return {
        key: MISSING if value in (None, "") else str(value)
        for key, value in zip(("trial", "block", "condition"), cells, strict=True)
    }


def read_answers(session_csv: Path) -> AnswersRecord | None:
    """Read the answers given after a trial (``trial-NN_answers.json``), or None if none.

    Raises
    ------
    InputError
        As `mirror_avatar.files.trial_record.read_answers_record`.
    """
    path = companion(session_csv, ANSWERS_SUFFIX)
    return read_answers_record(path) if path.is_file() else None


def answer_rows(
    answers: AnswersRecord, label: str, slots: Sequence[SlotRecord]
) -> list[dict[str, str]]:
    """Return the ``_beh.tsv`` rows of one participant's answers after a trial.

    Questions are in the order they were asked (after the trial, then after the block); a
    question's text and kind are ``n/a`` when the file does not hold them. ``slots`` (the
    trial's records) give every row the participant's partners
    and their true kind (`mirror_avatar.files.trial_record.partner_kind`).
    """
    partners = [slot for slot in slots if slot.label != label]
    beside = {
        "partners": "+".join(slot.label for slot in partners) or MISSING,
        "partner_kind": partner_kind(KIND_NAMES[slot.kind] for slot in partners),
    }
    return [
        {
            "question": answer.question,
            "text": answer.text or MISSING,
            "kind": answer.kind or MISSING,
            "answer": _answer_cell(answer.value),
            **beside,
            "after": answer.after,
            "trial": str(answers.trial),
            "block": answers.block or MISSING,
            "condition": answers.condition or MISSING,
            "answered_utc": answer.utc or MISSING,
        }
        for answer in answers.of(label)
    ]


def _mapping(value: object) -> dict[str, Any]:
    """Return ``value`` if it is a JSON object, else an empty one."""
    return value if isinstance(value, dict) else {}


def _answer_cell(value: object) -> str:
    """Write an answer as one TSV cell: text as given, numbers as written, else JSON."""
    if value is None or value == "":
        return MISSING
    return value if isinstance(value, str) else json.dumps(value)


def write_beh(path: Path, rows: list[dict[str, str]]) -> None:
    """Write a participant's answers after one trial as ``_beh.tsv``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic_text(path, tsv_table(BEH_COLUMNS, rows))


def write_scans(subject_dir: Path, rows: Iterable[dict[str, str]]) -> None:
    """Add rows (by ``filename``) to ``sub-<sub>_scans.tsv`` in ``subject_dir``; keep the rest.

    Raises
    ------
    InputError
        An existing table without a ``filename`` column or with a malformed row.
    """
    path = subject_dir / f"{subject_dir.name}_scans.tsv"
    columns, existing = read_tsv(path, "filename")
    for row in rows:
        existing[row["filename"]] = existing.get(row["filename"], {}) | row
    columns += [c for c in SCAN_COLUMNS if c not in columns]
    ordered = [existing[name] for name in sorted(existing)]
    write_atomic_text(path, tsv_table(columns, ordered))


def write_descriptions(out_dir: Path, task: str, answers: bool) -> None:
    """Write the dataset's description of the scans' columns, and of the answers' if any."""
    write_atomic_json(out_dir / "scans.json", SCAN_COLUMN_INFO)
    if answers:
        write_atomic_json(out_dir / f"task-{task}_beh.json", {"TaskName": task} | BEH_COLUMN_INFO)
