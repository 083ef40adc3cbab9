"""BIDS-Motion export of lab sessions and study sessions (BIDS 1.9.0, motion and beh).

A lab session folder holds, per trial n, ``trial-NN_session.csv`` and its sidecar
``trial-NN_session.json`` (`mirror_avatar.sessions.writer.SessionWriter`), whose ``metadata``
describes the trial (``lab``: session id, trial, condition, slots, and in a study session its block,
protocol condition, delay and occlusion; ``created_utc``, ``started_utc``, ``complete``,
``dropped``, ``held``, ``input_events``), its ``trial-NN_inputs.csv`` (each sample's clock time:
`mirror_avatar.realtime.trial.TickLog`) and, in a study session, ``trial-NN_answers.json``.
`export_bids` writes, for every trial and every human slot, one motion recording holding the
whole trial as that participant played it, and the answers they gave after it::

    <out>/dataset_description.json, README, participants.tsv, participants.json, scans.json
    <out>/task-mirrorgame_events.json, task-mirrorgame_beh.json (with answers)
    <out>/sub-<sub>/sub-<sub>_scans.tsv
    <out>/sub-<sub>/motion/sub-<sub>_task-mirrorgame_tracksys-<device>_acq-<acq>_run-<n>_motion.tsv
    <out>/sub-<sub>/motion/sub-<sub>_task-mirrorgame_tracksys-<device>_acq-<acq>_run-<n>_channels.tsv
    <out>/sub-<sub>/motion/sub-<sub>_task-mirrorgame_tracksys-<device>_acq-<acq>_run-<n>_motion.json
    <out>/sub-<sub>/motion/sub-<sub>_task-mirrorgame_tracksys-<device>_acq-<acq>_run-<n>_events.tsv
    <out>/sub-<sub>/beh/sub-<sub>_task-mirrorgame_acq-<acq>_run-<n>_beh.tsv
    <out>/sourcedata/<session id>/ the trial files (session, sidecar, inputs, answers),
                                   plan.json or study.json, ended.json, refusal-<label>.json

Entities follow the order of the specification (sub, task, tracksys, acq, run). ``<sub>`` is the
slot's label, in a study session after ``p`` and the participant's number (``p003P1``: the
people of different participants' runs are different subjects; `mirror_avatar.lab.export.bids_study.
subject_label`), ``<acq>`` the session id and ``<device>`` the slot's input device (``pointer``
or ``lsl``), each with its non-alphanumeric characters removed (`bids_label`); ``<n>`` is the
trial number (in a study, numbered across the protocol: one run per trial). A study's block and
condition are columns of the events (`mirror_avatar.lab.export.bids_events`) and of the scans
(`mirror_avatar.lab.export.bids_study`), not entities: ``acq`` already names the session and BIDS
has no entity for a condition. Channels are the participant's own ``position`` and ``velocity``,
then
``position_<label>`` and ``velocity_<label>`` of every other player in player order, in playing
range units (-0.5..0.5; per second for velocities), then, when the inputs file is there, the
`mirror_avatar.lab.export.bids_trial.TIMING_CHANNELS`: each sample's ``latency`` from the first
(type LATENCY, s), its ``clock`` time (the LSL clock when the lab ran with pylsl), and how ``late``
its tick was and how long its ``step`` took (ms). The non-standard ``MirrorGame`` key of each
``_motion.json`` carries the trial's record whole, as its sidecar's metadata holds it
(`mirror_avatar.files.trial_record.TrialRecord`), with the recording's slot, graph and start, so
that `mirror_avatar.sessions.loading.load_session` rebuilds the N-player session and its record
(`mirror_avatar.files.bids.reading.read_lab_recording`); the participant's own file
stays readable as their solo trial by `mirror_avatar.files.bids.reading.read_bids_motion` (it reads
the channel named ``position``), so every command that reads trials reads the export. Names,
values and tables follow the rules of `mirror_avatar.files.bids`.

A dataset is made to be shared: it never holds the researcher's folders. A file named under
`PATH_KEYS` (an avatar's ``spec``, a protocol's ``source``) is named by its base name
(`without_folders`) in the ``MirrorGame`` key and in the JSON files of ``sourcedata/``; the
other files are copied as they are.
"""

from __future__ import annotations

import collections
import os
import re
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar import __version__
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import (
    json_text,
    write_atomic_bytes,
    write_atomic_json,
    write_atomic_text,
)
from mirror_avatar.files.bids.names import MISSING, bids_label, channel_names
from mirror_avatar.files.bids.reading import GAME_FORMAT, GAME_KEY, GAME_VERSION
from mirror_avatar.files.bids.tables import read_tsv
from mirror_avatar.files.bids.writing import tsv_table, tsv_values
from mirror_avatar.files.trial_io import MAX_FILE_BYTES, read_sidecar_text
from mirror_avatar.files.user_files import parse_json, read_bytes
from mirror_avatar.lab.export.bids_events import EVENT_COLUMN_INFO, EVENT_COLUMNS, trial_events
from mirror_avatar.lab.export.bids_lock import dataset_lock
from mirror_avatar.lab.export.bids_study import (
    STUDY_COLUMNS,
    StudyRun,
    acq_time,
    answer_rows,
    read_study,
    subject_label,
    trial_row,
    write_beh,
    write_descriptions,
    write_scans,
)
from mirror_avatar.lab.export.bids_trial import (
    TIMING_CHANNELS,
    LabTrial,
    clock_start,
    read_lab_trial,
    trial_files,
)
from mirror_avatar.lab.export.run_outcomes import read_outcomes
from mirror_avatar.lab.files import (
    ANSWERS_SUFFIX,
    ENDED_FILE,
    INPUTS_SUFFIX,
    PLAN_FILE,
    REFUSAL_PATTERN,
    STUDY_FILE,
    companion,
)

Array = NDArray[np.float64]

BIDS_VERSION = "1.9.0"
"""Version of the BIDS specification the export follows."""

TASK = "mirrorgame"
"""The ``task-`` label and ``TaskName`` of every recording."""

"""Trial files of a lab session folder."""

CHANNEL_COLUMNS = ("name", "component", "type", "tracked_point", "units", "description")
"""Columns of a ``_channels.tsv``."""

PARTICIPANT_COLUMNS = ("participant_id", "label", "device")
"""Columns `export_bids` fills in ``participants.tsv``, with the study's
(`mirror_avatar.lab.export.bids_study.STUDY_COLUMNS`) when it exports a study session (others
already there are kept)."""

COMPLETION = "completion_code"
"""The column of ``participants.tsv`` holding what a study participant's end page showed."""

CONDITIONS = {
    "solo": "one player moves alone",
    "leader_follower": "one player leads and the other follows",
    "joint": "the players improvise motion together, with no designated leader",
    "group": "several players move together, coupled on a graph",
}
"""What each lab condition asks of the players, for ``TaskDescription``."""


def motion_stem(subject: str, device: str, acquisition: str, run: int) -> str:
    """Return ``<subject>_task-mirrorgame_tracksys-<device>_acq-<acquisition>_run-<run>``.

    ``subject`` is the subject's folder, ``sub-<label>``.
    """
    return f"{subject}_task-{TASK}_tracksys-{device}_acq-{acquisition}_run-{run}"


def export_bids(session_dir: str | os.PathLike[str], out_dir: str | os.PathLike[str]) -> list[Path]:
    """Export a lab session folder to a BIDS-Motion dataset (BIDS 1.9.0), merging into it.

    Every trial file ``trial-*_session.csv`` of ``session_dir`` (sorted) gives one recording per
    human slot, in ``out_dir/sub-<label>/motion/`` (layout in the module docstring); avatars get
    none but appear as channels of every human's recording. BIDS labels must be alphanumeric:
    the participant label is the slot's label with every other character removed (``P_1``
    becomes ``sub-P1``), in a study session (``session_dir`` holds ``study.json``) after ``p``
    and the participant's number (``sub-p003P1``), and likewise the ``acq-`` label from the
    session id. An incomplete trial (a crash) is exported as far as it was recorded,
    ``complete`` being false in its ``MirrorGame`` key. ``participants.tsv`` gains the session's
    participants (one row each, with the study's participant number and protocol in a study, and
    the panel identifiers their join links gave and, once the run ended, the completion code
    their end page showed: `COMPLETION`; existing rows kept);
    ``dataset_description.json`` and ``README`` are written only when absent; each subject's
    ``_scans.tsv`` gains their files with their acquisition times (existing rows kept); a
    trial's answers become each participant's ``_beh.tsv``; ``sourcedata/<session id>/``
    receives copies of the trial files (with their inputs and answers), ``plan.json`` or
    ``study.json``, and a study run's end and refusals (`mirror_avatar.lab.export.run_outcomes`),
    a file they name by its base name only (`shared_json`), as in each ``MirrorGame`` key.
    Every file is written atomically, and nothing
    is written before every trial (and every table merged into) has been read. Exports into one
    ``out_dir`` take turns (`mirror_avatar.lab.export.bids_lock.dataset_lock`, across threads and
    processes), so that none loses the rows another adds to the tables.

    Parameters
    ----------
    session_dir
        A lab session folder ``<out>/<session_id>/``.
    out_dir
        The BIDS dataset root, created if needed.

    Returns
    -------
    list of Path
        The ``_motion.tsv`` files written, by trial then slot.

    Raises
    ------
    InputError
        No such folder, no trial file in it, a trial without lab metadata (or with slots that
        do not match its players), trials of different sessions, a human slot without a device,
        two players with one label, two participants mapping to one BIDS label (also against
        ``participants.tsv``, where a study's participant number and protocol must match too),
        a session id already exported under the same ``acq-`` label, a ``study.json`` without
        a participant number or a trial of another participant, an inputs file without its
        clock columns, an answers file that is not one, or a damaged ``participants.tsv`` or
        ``_scans.tsv``.
    """
    session_dir, out_dir = Path(session_dir), Path(out_dir)
    files = trial_files(session_dir)
    study = read_study(session_dir)
    trials = [read_lab_trial(path, study) for path in files]
    session_id = _one_session(session_dir, trials)
    copies = _source_copies(session_dir, files)
    with dataset_lock(out_dir):  # the tables are read, merged and written by one export at once
        _check_acquisition(out_dir, session_id)
        columns, participants = _read_participants(out_dir / "participants.tsv", study)
        for trial in trials:
            _add_participants(participants, trial, out_dir / "participants.tsv")
        panel = _panel_ids(trials)
        columns += [name for name in panel if name not in columns]
        if _add_completion(participants, session_dir, study) and COMPLETION not in columns:
            columns.append(COMPLETION)
        described = _read_column_info(out_dir / "participants.json") | panel_info(panel)
        subjects = {_subject(trial, k) for trial in trials for k in trial.humans()}
        for subject in sorted(subjects):  # a damaged table is refused before anything is written
            read_tsv(out_dir / subject / f"{subject}_scans.tsv", "filename")
        written, answered = _write_trials(trials, out_dir)
        _write_sources(copies, out_dir / "sourcedata" / session_id)
        _write_participants(out_dir, columns, participants, described)
        _write_description(out_dir)
        write_atomic_json(out_dir / f"task-{TASK}_events.json", EVENT_COLUMN_INFO)
        write_descriptions(out_dir, TASK, answers=answered)
    return written


def _write_trials(trials: list[LabTrial], out_dir: Path) -> tuple[list[Path], bool]:
    """Write every human's recording and answers, and list them in their ``_scans.tsv``.

    Returns the ``_motion.tsv`` files written and whether any answers were.
    """
    written: list[Path] = []
    answered = False
    scans: dict[str, list[dict[str, str]]] = collections.defaultdict(list)
    for trial in trials:
        when = {"acq_time": acq_time(trial.record)} | trial_row(trial.record)
        for k in trial.humans():
            motion = _write_recording(trial, k, out_dir)
            behaviour = _write_answers(trial, k, out_dir)
            written.append(motion)
            answered |= behaviour is not None
            for path in (motion, behaviour):
                if path is not None:
                    filename = f"{path.parent.name}/{path.name}"
                    scans[_subject(trial, k)].append({"filename": filename} | when)
    for subject, rows in scans.items():
        write_scans(out_dir / subject, rows)
    return written, answered


def _subject(trial: LabTrial, slot: int) -> str:
    """Return the ``sub-<label>`` folder of a trial's human slot."""
    return f"sub-{subject_label(trial.slots[slot].label, trial.study, trial.path)}"


def _one_session(session_dir: Path, trials: list[LabTrial]) -> str:
    """Return the session id the trials share."""
    ids = sorted({trial.record.session_id for trial in trials})
    if len(ids) != 1:
        raise InputError(session_dir, f"trials of several sessions in one folder: {ids}")
    return ids[0]


def _check_acquisition(out_dir: Path, session_id: str) -> None:
    """Refuse a session id whose ``acq-`` label another exported session already has."""
    acquisition = bids_label(session_id, out_dir)
    sources = out_dir / "sourcedata"
    others = [p.name for p in sources.iterdir() if p.is_dir()] if sources.is_dir() else []
    for other in others:
        if other != session_id and re.sub(r"[^A-Za-z0-9]", "", other) == acquisition:
            raise InputError(
                out_dir,
                f"session {session_id!r} and the exported session {other!r} both map to "
                f"acq-{acquisition}",
            )


def _read_participants(
    path: Path, study: StudyRun | None
) -> tuple[list[str], dict[str, dict[str, str]]]:
    """Read ``participants.tsv`` (columns and rows by participant id); empty if absent.

    The columns gain the `PARTICIPANT_COLUMNS`, and the study's when ``study`` is one.
    """
    header, rows = read_tsv(path, "participant_id")
    wanted = PARTICIPANT_COLUMNS + (() if study is None else STUDY_COLUMNS)
    return header + [c for c in wanted if c not in header], rows


def _add_participants(rows: dict[str, dict[str, str]], trial: LabTrial, path: Path) -> None:
    """Add a trial's human slots to the participants rows, refusing two people for one id.

    A row already there is the same person when its label (and in a study, its participant
    number and protocol) are the trial's, or unknown (``n/a``).
    """
    for k in trial.humans():
        label, device = trial.slots[k].label, str(trial.slots[k].device)
        subject = _subject(trial, k)
        person = {"label": label} | ({} if trial.study is None else trial.study.cells())
        row = rows.setdefault(subject, {"participant_id": subject} | person)
        if any(row.get(key, MISSING) not in (value, MISSING) for key, value in person.items()):
            raise InputError(
                path,
                f"{_who(person)} of {trial.path.name} and the participant {_who(row)} both map "
                f"to {subject} (relabel one, or export into another --out folder)",
            )
        devices = set(row.get("device", MISSING).split(",")) - {MISSING, ""}
        row |= person | {"device": ",".join(sorted(devices | {device}))}
        row |= {} if trial.record.study is None else trial.record.study.panel.get(label, {})


def _add_completion(
    rows: dict[str, dict[str, str]], session_dir: Path, study: StudyRun | None
) -> bool:
    """Give each person of a study run shown the completion its `COMPLETION` cell.

    Returns whether anyone was (`mirror_avatar.lab.export.run_outcomes`: the run's end).
    """
    if study is None:
        return False
    completion = read_outcomes(session_dir).completion
    for label, code in completion.items():
        subject = f"sub-{subject_label(label, study, session_dir)}"
        if subject in rows:
            rows[subject][COMPLETION] = code
    return bool(completion)


def _panel_ids(trials: list[LabTrial]) -> list[str]:
    """Return the names of the panel identifiers the trials record, in order of appearance."""
    names: dict[str, None] = {}
    for trial in trials:
        for ids in ({} if trial.record.study is None else trial.record.study.panel).values():
            names |= dict.fromkeys(ids)
    return list(names)


def panel_info(names: list[str]) -> dict[str, Any]:
    """Describe the panel identifiers' columns of ``participants.tsv`` (``participants.json``)."""
    return {
        name: {
            "Description": f"The participant's {name} on their recruitment panel, from the query "
            "of their join link (n/a: the link had none)"
        }
        for name in names
    }


def _who(cells: dict[str, str]) -> str:
    """Name a participant by their label, and in a study their participant number and protocol."""
    study = [cells.get(key, MISSING) for key in STUDY_COLUMNS]
    run = "" if MISSING in study else f" (participant {study[0]} of protocol {study[1]!r})"
    return f"{cells.get('label', MISSING)!r}{run}"


def _write_recording(trial: LabTrial, slot: int, out_dir: Path) -> Path:
    """Write slot ``slot``'s motion, channels and sidecar files; return the motion file."""
    subject = _subject(trial, slot)
    device = bids_label(str(trial.slots[slot].device))
    stem = motion_stem(subject, device, bids_label(trial.record.session_id), trial.record.trial)
    folder = out_dir / subject / "motion"
    folder.mkdir(parents=True, exist_ok=True)
    order = _player_order(slot, trial.session.n_players)
    channels = [row for j in order for row in _channel_rows(trial, j, own=j == slot)]
    session = trial.session
    arrays = [array[j] for j in order for array in (session.positions, session.velocities)]
    if trial.timing is not None:
        channels += [_timing_row(*channel) for channel in TIMING_CHANNELS]
        arrays += list(trial.timing)
    motion = folder / f"{stem}_motion.tsv"
    write_atomic_text(motion, tsv_values(np.vstack(arrays).T))
    write_atomic_text(folder / f"{stem}_channels.tsv", tsv_table(CHANNEL_COLUMNS, channels))
    write_atomic_json(folder / f"{stem}_motion.json", _motion_sidecar(trial, slot, len(channels)))
    events = trial_events(trial.record, session.n_samples, trial.period)
    write_atomic_text(folder / f"{stem}_events.tsv", tsv_table(EVENT_COLUMNS, events))
    return motion


def _timing_row(name: str, kind: str, units: str, description: str) -> dict[str, str]:
    """Make the ``_channels.tsv`` row of one of the `TIMING_CHANNELS`."""
    return {"name": name, "component": MISSING, "type": kind, "tracked_point": MISSING,
            "units": units, "description": description}  # fmt: skip


def _write_answers(trial: LabTrial, slot: int, out_dir: Path) -> Path | None:
    """Write slot ``slot``'s answers after ``trial`` as ``_beh.tsv``; None if they gave none."""
    label = trial.slots[slot].label
    rows = [] if trial.answers is None else answer_rows(trial.answers, label, trial.slots)
    if not rows:
        return None
    subject = _subject(trial, slot)
    acquisition = bids_label(trial.record.session_id)
    name = f"{subject}_task-{TASK}_acq-{acquisition}_run-{trial.record.trial}"
    path = out_dir / subject / "beh" / f"{name}_beh.tsv"
    write_beh(path, rows)
    return path


def _player_order(slot: int, n_players: int) -> list[int]:
    """Order the players: the participant at ``slot`` first, then the others in order."""
    return [slot, *(j for j in range(n_players) if j != slot)]


def _channel_rows(trial: LabTrial, player: int, own: bool) -> list[dict[str, str]]:
    """Make a player's ``_channels.tsv`` rows: position (POS), then velocity (VEL)."""
    slot = trial.slots[player]
    who = f"{slot.label} ({slot.kind}, {slot.role})"
    position, velocity = channel_names(slot.label, own)
    common = {"component": "x", "tracked_point": slot.label, "units": MISSING}
    return [
        common | {"name": position, "type": "POS",
                  "description": f"position of {who} in playing range units: -0.5..0.5"},
        common | {"name": velocity, "type": "VEL",
                  "description": f"velocity of {who} in playing range units per second "
                  "(playing range units: -0.5..0.5)"},
    ]  # fmt: skip


def _motion_sidecar(trial: LabTrial, slot: int, n_channels: int) -> dict[str, Any]:
    """Make the ``_motion.json`` of slot ``slot``'s recording of ``trial``."""
    n_players, n_samples = trial.session.n_players, trial.session.n_samples
    return {
        "TaskName": TASK,
        "TaskDescription": _task_description(trial),
        "SamplingFrequency": 1.0 / trial.period,
        "TrackingSystemName": trial.slots[slot].device,
        "MotionChannelCount": n_channels,
        "POSChannelCount": n_players,
        "VELChannelCount": n_players,
        **({} if trial.timing is None else {"LATENCYChannelCount": 1, "MiscChannelCount": 3}),
        "TrackedPointsCount": n_players,
        "RecordingDuration": n_samples * trial.period,
        "RecordingType": "continuous",
        "MissingValues": MISSING,
        "SubjectArtefactDescription": _artefacts(trial, slot),
        GAME_KEY: _game_info(trial, slot),
    }


def _task_description(trial: LabTrial) -> str:
    """Describe the mirror game and the trial's condition."""
    record = trial.record
    what = CONDITIONS.get(record.condition, "the players move together")
    named = None if record.study is None else record.study.condition
    game = record.condition or MISSING
    condition = f"{named} ({game}: {what})" if named else f"{game} ({what})"
    return (
        f"Mirror game, condition {condition}: each player moves a point "
        "along a line and sees the points of the players they are coupled to. Positions are in "
        f"playing range units (-0.5..0.5), sampled every {trial.period:g} s."
    )


def _artefacts(trial: LabTrial, slot: int) -> str:
    """Name the trial's connection drops and an early end, or return ``n/a``."""
    notes = []
    for who, sample in trial.record.dropped.items():
        whose = "this participant" if who == trial.slots[slot].label else "another participant"
        when = f" ({sample * trial.period:.3f} s)"
        notes.append(f"The connection of {who} ({whose}) dropped at sample {sample}{when}.")
    if not trial.record.complete:
        notes.append("The recording stopped before the end of the trial (incomplete).")
    return " ".join(notes) or MISSING


def _game_info(trial: LabTrial, slot: int) -> dict[str, Any]:
    """Make the ``MirrorGame`` key: the trial's record whole, and how this recording holds it.

    The record is written by its one writer (`mirror_avatar.files.trial_record.TrialRecord.
    metadata_json`: ``lab`` with the session, condition, study and slots, then the times,
    seed, drops, perturbations, held samples, input events, clock and companion files), so
    `mirror_avatar.files.bids.reading` reads it back with the record's one reader.
    """
    return {
        "format": GAME_FORMAT,
        "version": GAME_VERSION,
        "library_version": __version__,
        "clock_start_s": clock_start(trial.timing),
        "participant": trial.slots[slot].label,
        "slot": slot,
        "graph": trial.session.graph.tolist(),
        "start_time": float(trial.session.times[0]),
    } | shared_json(trial.record.metadata_json())


PATH_KEYS = ("spec", "source")
"""Keys of the lab's JSON files whose text may name a file on the researcher's machine: an
avatar's spec (a model, a recording, ``vt:`` and a recording) and a protocol's source."""

_FOLDERS = re.compile(r"(?:\b[A-Za-z]:)?[^\s:=,]*[/\\]")
"""A path's folders (a drive, names and separators, POSIX or Windows) up to its base name."""


def without_folders(text: str) -> str:
    """Drop the folders of every path in ``text``: ``vt:/home/me/trial.csv`` is ``vt:trial.csv``."""
    return _FOLDERS.sub("", text)


def shared_json(value: Any) -> Any:
    """Return a JSON value with the text under every `PATH_KEYS` key `without_folders`."""
    if isinstance(value, dict):
        return {
            key: without_folders(item)
            if key in PATH_KEYS and isinstance(item, str)
            else shared_json(item)
            for key, item in value.items()
        }
    if isinstance(value, list):
        return [shared_json(item) for item in value]
    return value


def _source_copies(session_dir: Path, files: list[Path]) -> dict[str, bytes]:
    """Read what ``sourcedata/`` holds of a session, by name (trial files, plan, study).

    The trial files are each trial's recording, sidecar, inputs and answers. A JSON file that
    names a file under `PATH_KEYS` is held `shared_json`; every other file byte for byte.

    Raises
    ------
    InputError
        A JSON file that cannot be read as JSON.
    """
    sources = [
        path
        for f in files
        for path in (
            f, f.with_suffix(".json"), companion(f, INPUTS_SUFFIX), companion(f, ANSWERS_SUFFIX)
        )
    ]  # fmt: skip
    sources += [session_dir / PLAN_FILE, session_dir / STUDY_FILE, session_dir / ENDED_FILE]
    sources += sorted(session_dir.glob(REFUSAL_PATTERN))
    return {source.name: _shared_copy(source) for source in sources if source.is_file()}


def _shared_copy(source: Path) -> bytes:
    """Return the bytes of ``source``, or of a JSON file's text `shared_json` when it differs."""
    data = read_bytes(source, MAX_FILE_BYTES)
    if source.suffix != ".json":
        return data
    value = parse_json(read_sidecar_text(source), source)
    shared = shared_json(value)
    return data if shared == value else json_text(shared).encode()


def _write_sources(copies: dict[str, bytes], target: Path) -> None:
    """Write the ``sourcedata/`` copies (`_source_copies`) into ``target``."""
    target.mkdir(parents=True, exist_ok=True)
    for name, data in copies.items():
        write_atomic_bytes(target / name, data)


def _read_column_info(path: Path) -> dict[str, Any]:
    """Read an existing ``participants.json`` (its other columns are kept); empty if absent."""
    if not path.is_file():
        return {}
    described = parse_json(read_sidecar_text(path), path)
    if not isinstance(described, dict):
        raise InputError(path, "not a JSON object")
    return described


def _write_participants(
    out_dir: Path, columns: list[str], rows: dict[str, dict[str, str]], described: dict[str, Any]
) -> None:
    """Write ``participants.tsv`` (sorted by id) and ``participants.json``."""
    ordered = [rows[key] for key in sorted(rows)]
    write_atomic_text(out_dir / "participants.tsv", tsv_table(columns, ordered))
    columns_info = {column: _COLUMN_INFO[column] for column in columns if column in _COLUMN_INFO}
    write_atomic_json(out_dir / "participants.json", described | columns_info)


_COLUMN_INFO = {
    "participant_id": {
        "Description": "Participant: sub- and the slot label without non-alphanumeric "
        "characters; in a study, sub-, p, the participant number on three digits or more, "
        "then the label (sub-p003P1: person P1 of participant 3)"
    },
    "label": {
        "Description": "The participant's slot label in the lab sessions, as recorded; in a "
        "study, the person's label in the protocol (the same for every participant's run)"
    },
    "study_participant": {
        "Description": "The number of the participant whose run of the study protocol the "
        "person played in (0-based: their row of the counterbalancing; n/a: not a study)"
    },
    "protocol": {
        "Description": "The study protocol: its file name without extension (n/a: not a study)"
    },
    COMPLETION: {
        "Description": "The completion code the participant's end page showed when their run "
        "ended (the link back when the protocol gives only a link; n/a: not shown, the run did "
        "not end or their page was not connected then)"
    },
    "device": {
        "Description": "Input device(s) the participant used, separated by commas: pointer (the "
        "browser page's pointer) or lsl (a Lab Streaming Layer stream)"
    },
}


def _write_description(out_dir: Path) -> None:
    """Write ``dataset_description.json`` and ``README`` unless the dataset already has them."""
    description = out_dir / "dataset_description.json"
    if not description.exists():
        write_atomic_json(
            description,
            {
                "Name": "Mirror game lab sessions",
                "BIDSVersion": BIDS_VERSION,
                "DatasetType": "raw",
                "GeneratedBy": [{"Name": "mirror-avatar", "Version": __version__}],
            },
        )
    readme = out_dir / "README"
    if not readme.exists():
        write_atomic_text(readme, _README)


_README = """Mirror game lab sessions (BIDS-Motion), exported by mirror-avatar.

In the mirror game, players move a point along a line, each seeing the players they are coupled
to; some players may be avatars (computer-controlled). Each human participant (sub-<label>; in
a study, the participant's number then the person's label in the protocol: sub-p003P1, with
study_participant and protocol in participants.tsv) has, per session (acq-<session id>) and
trial (run-<trial>), one motion recording holding the whole
trial as they played it: their own position and velocity, then those of every other player.
Positions are in playing range units (-0.5..0.5), velocities in playing range units per second,
sampled at the control period; the channels latency and clock give when each sample was
really taken (clock: the Lab Streaming Layer clock when the lab ran with it, to align with EEG),
and sub-<label>_scans.tsv when each run's first sample was (acq_time, UTC). The MirrorGame key of
each _motion.json describes the trial (condition, players, coupling graph, connection drops);
each _events.tsv its condition (and block, in a study) and manipulations (visual delay,
occlusion, perturbations of an avatar, inputs lost). In a study, the answers a participant gave
after a trial are in sub-<label>/beh/, run-<trial>. sourcedata/<session id>/ holds the original
recordings.
"""
