"""A lab trial read for its BIDS export: its session, record, clock channels and answers.

`read_lab_trial` reads ``trial-NN_session.csv`` with its sidecar's record
(`mirror_avatar.files.trial_record.TrialRecord`), checks the slots against the players, and reads
each sample's true time from ``trial-NN_inputs.csv`` (`TIMING_CHANNELS`) and the answers given
after it; `mirror_avatar.lab.export.bids.export_bids` writes what it holds.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.bids.names import bids_label
from mirror_avatar.files.trial_io import _first_row, _read_numbers, read_sidecar_text
from mirror_avatar.files.trial_record import (
    AnswersRecord,
    SlotRecord,
    TrialRecord,
    lab_trial_record,
)
from mirror_avatar.files.user_files import parse_json
from mirror_avatar.lab.export.bids_study import StudyRun, read_answers
from mirror_avatar.lab.files import INPUTS_SUFFIX, TRIAL_PATTERN, companion
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.sessions.session import Session

Array = NDArray[np.float64]


@dataclass(frozen=True)
class LabTrial:
    """One recorded trial of a lab session, read for its export, with its record.

    ``record`` is the trial's (`mirror_avatar.files.trial_record.TrialRecord`), its slots in player
    order; ``period`` the control period (s), ``timing`` the `TIMING_CHANNELS` (shape
    (4, samples)) when the trial's inputs file is there, and ``answers`` the answers given
    after the trial (`mirror_avatar.lab.export.bids_study.read_answers`); ``study`` is whose run of
    which protocol the trial belongs to, None outside a study.
    """

    path: Path
    session: Session
    record: TrialRecord
    period: float
    timing: Array | None
    answers: AnswersRecord | None
    study: StudyRun | None

    @property
    def slots(self) -> tuple[SlotRecord, ...]:
        """The players' slots, in player order."""
        return self.record.slots

    def humans(self) -> list[int]:
        """Return the indices of the human slots."""
        return [k for k, slot in enumerate(self.slots) if slot.kind == "human"]


def trial_files(session_dir: Path) -> list[Path]:
    """Return the trial files of a lab session folder, sorted."""
    if not session_dir.is_dir():
        raise InputError(session_dir, "no such folder")
    files = sorted(path for path in session_dir.glob(TRIAL_PATTERN) if path.is_file())
    if not files:
        raise InputError(
            session_dir, "no trial file (trial-NN_session.csv) in it: not a lab session folder"
        )
    return files


def read_lab_trial(path: Path, study: StudyRun | None) -> LabTrial:
    """Read a trial file of ``study`` (None: no study) and check its record."""
    session = load_session(path)
    record = lab_trial_record(session.metadata, path.with_suffix(".json"))
    if record is None:
        raise InputError(path, "no lab metadata in its sidecar: not a lab trial")
    _check_slots(path, record.slots, session)
    if not _is_folder_name(record.session_id):
        raise InputError(path, f"lab session_id {record.session_id!r} is not a usable folder name")
    recorded = record.study
    if study is not None and recorded is not None and recorded.participant != study.participant:
        raise InputError(
            path,
            f"a trial of participant {recorded.participant!r} in participant "
            f"{study.participant}'s study folder: export each participant's folder as recorded",
        )
    return LabTrial(
        path=path,
        session=session,
        record=record,
        period=_nominal_period(path, session),
        timing=_read_timing(path, record, session),
        answers=read_answers(path),
        study=study,
    )


def _check_slots(path: Path, slots: tuple[SlotRecord, ...], session: Session) -> None:
    """Check the lab slots: one per player, labels as the session's, unique, devices named."""
    if len(slots) != session.n_players:
        raise InputError(path, f"lab slots must be a list of {session.n_players} (one per player)")
    for k, slot in enumerate(slots):
        if slot.label != session.labels[k]:
            raise InputError(
                path, f"lab slot {k} is {slot.label!r} but player {k} is {session.labels[k]!r}"
            )
        if slot.kind == "human":
            if not slot.device:
                raise InputError(path, f"human slot {slot.label!r} names no input device")
            bids_label(slot.device, path)
            bids_label(slot.label, path)
    if len(set(session.labels)) != len(session.labels):
        raise InputError(path, f"two players share a label in {list(session.labels)}")


INPUT_COLUMNS = ("clock_s", "late_ms", "step_ms")
"""Columns of a trial's inputs file (`mirror_avatar.realtime.trial.TickLog`) the export keeps."""

TIMING_CHANNELS = (
    ("latency", "LATENCY", "s",
     "time at which the sample was taken, from the first sample's (the clock channel minus "
     "its first value); the first sample's is the acq_time of the scans file"),
    ("clock", "MISC", "s",
     "clock time at which the sample was taken: the Lab Streaming Layer clock "
     "(pylsl.local_clock) when the lab ran with pylsl, else the monotonic clock (see "
     "MirrorGame.clock), so that samples line up with EEG recorded through LSL"),
    ("late", "MISC", "ms", "how late the sample's tick came against its schedule"),
    ("step", "MISC", "ms", "time the players' step took at that tick (file writes excluded)"),
)  # fmt: skip
"""Name, type, units and description of the channels of each sample's true time."""


def _read_timing(path: Path, record: TrialRecord, session: Session) -> Array | None:
    """Read the `TIMING_CHANNELS` of a trial from its inputs file, shape (4, samples).

    The inputs file is the record's ``files["inputs"]`` (``trial-NN_inputs.csv``) beside the
    trial; None when it is not there. Samples it lacks (a crash between the two files'
    lines) are NaN; the latency is rounded to the microsecond.

    Raises
    ------
    InputError
        An inputs file without the `INPUT_COLUMNS`, or with values that are not numbers.
    """
    name = record.files.get("inputs")
    inputs = path.with_name(Path(name).name) if name else companion(path, INPUTS_SUFFIX)
    if not inputs.is_file():
        return None
    header = _first_row(inputs, ",")
    missing = [column for column in INPUT_COLUMNS if column not in header]
    if missing:
        raise InputError(inputs, f"no {', '.join(missing)} column: not a lab trial's inputs file")
    columns = [header.index(column) for column in INPUT_COLUMNS]
    values = _read_numbers(inputs, columns, list(INPUT_COLUMNS), ",", 2)
    n = session.n_samples
    clock, late, step = (np.pad(v[:n], (0, max(0, n - v.size)), constant_values=np.nan)
                         for v in values)  # fmt: skip
    latency = np.round(clock - clock[0], 6) if n else clock
    return np.vstack([latency, clock, late, step])


def _nominal_period(path: Path, session: Session) -> float:
    """Return the sidecar's control period (s), or the one the sample times give."""
    try:
        period = parse_json(read_sidecar_text(path.with_suffix(".json")), path).get("period")
    except (ValueError, AttributeError):
        period = None
    if isinstance(period, int | float) and not isinstance(period, bool) and period > 0:
        return float(period)
    return session.period


def _is_folder_name(text: str) -> bool:
    """Whether ``text`` can name one folder: not empty, no separator, not hidden."""
    return bool(text) and not text.startswith(".") and not re.search(r"[/\\\x00-\x1f]", text)


def clock_start(timing: Array | None) -> float | None:
    """Return the clock time (s) of the first sample, or None when unknown."""
    if timing is None or not timing.shape[1] or np.isnan(timing[1, 0]):
        return None
    return float(timing[1, 0])
