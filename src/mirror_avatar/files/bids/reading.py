"""Reading BIDS-Motion recordings: one participant's trial, or a lab trial's N players.

A recording is ``<entities>_motion.tsv`` (no header, one column per channel, ``n/a`` missing)
beside ``<entities>_motion.json`` (``SamplingFrequency`` in Hz, between
`mirror_avatar.files.trials.MIN_RATE` and `mirror_avatar.files.trials.MAX_RATE`) and, when it holds
more than one channel, ``<entities>_channels.tsv`` naming them in column order. One set of rules
serves both readers: the sidecar and channels are read as `mirror_avatar.files.trial_io` reads
sidecars (size bound, one-line errors), the values with pandas' C parser straight into float64
arrays, so memory stays a small multiple of the file's size whichever reader is used.

`read_bids_motion` reads one position channel as a `mirror_avatar.files.trials.Trial` labelled by
the recording's entities (`mirror_avatar.files.bids.names.recording_stem`), never by ``TaskName``.
`read_lab_recording` reads a ``_motion.tsv`` that `mirror_avatar.lab.export.bids.export_bids` wrote,
whose ``MirrorGame`` sidecar key describes the trial's players, back as arrays for
`mirror_avatar.sessions.loading.load_session`; `read_tracked_points` reads any other tool's
recording the same way, one player per tracked point with a position (``POS``) channel.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.bids.names import (
    MISSING,
    MOTION_SUFFIX,
    channel_names,
    entities,
    recording_stem,
)
from mirror_avatar.files.importing import DEFAULT_IMPORT, POSITION_UNITS, ImportOptions, excerpt
from mirror_avatar.files.trial_io import (
    MAX_FILE_BYTES,
    MAX_SIDECAR_BYTES,
    _first_row,
    _json_kind,
    _json_object,
    _name_in,
    _read_numbers,
    _reading,
    check_version,
    import_trial,
    read_sidecar_text,
)
from mirror_avatar.files.trial_record import TrialRecord, trial_record
from mirror_avatar.files.trials import MAX_RATE, MIN_RATE, Trial
from mirror_avatar.files.user_files import check_regular, open_regular

Array = NDArray[np.float64]

GAME_KEY = "MirrorGame"
"""Non-standard ``_motion.json`` key of a lab export describing the trial (players, graph)."""

GAME_FORMAT, GAME_VERSION = "mirror-avatar/lab-bids", 2
"""Format name and version written under `GAME_KEY` (version 1 kept the ``lab`` object's
session id, condition, trial and slots at the top, and no study, perturbations, input events
or companion files); a newer version is refused."""


@dataclass(frozen=True)
class Recording:
    """The files of one recording and what its sidecar says.

    Attributes
    ----------
    motion
        The ``_motion.tsv`` file.
    sidecar
        Its ``_motion.json`` file.
    info
        The sidecar's JSON object.
    rate
        ``SamplingFrequency`` (Hz).
    channels
        The ``_channels.tsv`` rows (column name -> cell, stripped), in column order; empty when
        there is no channels file.
    width
        Values in the first row of the motion file.
    """

    motion: Path
    sidecar: Path
    info: dict[str, Any]
    rate: float
    channels: list[dict[str, str]]
    width: int

    @property
    def names(self) -> list[str]:
        """The channels' names, in column order."""
        return [row.get("name", "") for row in self.channels]


def open_recording(path: str | Path) -> Recording:
    """Check a ``_motion.tsv`` and read its sidecar and channels (not yet its values).

    Raises
    ------
    InputError
        Not a ``_motion.tsv``, missing or over a size limit; a sidecar that is missing, not a
        JSON object or without a plausible ``SamplingFrequency``; a channels file that is
        unreadable, has no ``name`` column, names a channel twice, or names more channels
        than the motion file's first row holds values.
    """
    path = Path(path)
    if not path.name.endswith(MOTION_SUFFIX):
        raise InputError(path, f"not a BIDS-Motion file (names end in {MOTION_SUFFIX})")
    check_regular(path, MAX_FILE_BYTES)
    stem = recording_stem(path.name)
    sidecar = path.with_name(f"{stem}_motion.json")
    if not sidecar.is_file():
        raise InputError(path, f"no sidecar {sidecar.name}")
    info = _json_object(read_sidecar_text(sidecar), sidecar, "the sidecar")
    channels_path = path.with_name(f"{stem}_channels.tsv")
    channels = _read_channels(channels_path) if channels_path.is_file() else []
    width = len(_first_row(path, "\t"))
    if len(channels) > width:
        raise InputError(
            channels_path,
            f"{len(channels)} channels, but the first row of {path.name} holds {width} values",
        )
    return Recording(path, sidecar, info, _sampling_frequency(info, sidecar), channels, width)


def _read_channels(path: Path) -> list[dict[str, str]]:
    """Read a ``_channels.tsv``: its rows, cells stripped, with unique names."""
    with _reading(path, "TSV"), open_regular(path, MAX_SIDECAR_BYTES) as file:
        table = pd.read_csv(file, sep="\t", dtype=str, na_filter=False, encoding="utf-8-sig")
    rows = [{str(key).strip(): str(value).strip() for key, value in row.items()}
            for row in table.to_dict("records")]  # fmt: skip
    if "name" not in (rows[0] if rows else {str(c).strip() for c in table.columns}):
        raise InputError(path, "no 'name' column")
    names = [row["name"] for row in rows]
    if len(set(names)) != len(names):
        raise InputError(path, "two channels share a name")
    return rows


def _sampling_frequency(info: dict[str, Any], sidecar: Path) -> float:
    """Return the sidecar's ``SamplingFrequency`` (Hz) if it is a rate a trial can have."""
    if "SamplingFrequency" not in info:
        raise InputError(sidecar, "no SamplingFrequency (Hz)")
    value = info["SamplingFrequency"]
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(sidecar, f"SamplingFrequency is {_json_kind(value)}, not a number of Hz")
    if not MIN_RATE <= value <= MAX_RATE:
        raise InputError(
            sidecar,
            f"SamplingFrequency {excerpt(value)} Hz is outside {MIN_RATE:g}-{MAX_RATE:g} Hz",
        )
    return float(value)


def read_bids_motion(path: str | Path, options: ImportOptions = DEFAULT_IMPORT) -> Trial:
    """Read a BIDS-Motion recording's position channel as a trial.

    Sample times are ``k / SamplingFrequency``. With a ``_channels.tsv``, the position channel
    is the one ``options.position_column`` names, or the only one (or the only one of type
    ``POS``), and its ``units`` (mm, cm, m) convert it; without one, the file must hold one
    column. Blank or ``n/a`` samples are missing (`mirror_avatar.files.importing.fill_gaps`). The
    label is the recording's entities (``sub-01_ses-2_task-mirror_run-3``);
    ``metadata["bids"]`` holds the entities and the sidecar's ``TaskName``.

    Raises
    ------
    InputError
        As `open_recording`; a ``TaskName`` that is not a short text; several channels and
        none chosen (naming them and ``--position-column``); a non-numeric value (naming the
        row); or any `mirror_avatar.files.trial_io.import_trial` problem.
    """
    recording = open_recording(path)
    task = _name_in(recording.info, "TaskName", recording.sidecar, "")
    column, name, unit = _position_channel(recording, options)
    (positions,) = _read_numbers(recording.motion, [column], [name], "\t", 1)
    times = np.arange(positions.size) / recording.rate
    trial = import_trial(times, positions, recording.motion, replace(options, time_unit="s"), unit)
    found = entities(recording.motion.name)
    bids = {"entities": found} | ({"TaskName": task} if task else {})
    return replace(
        trial, label=recording_stem(recording.motion.name), metadata=trial.metadata | {"bids": bids}
    )


def _position_channel(recording: Recording, options: ImportOptions) -> tuple[int, str, str | None]:
    """Return the position channel's column, name and unit (None: as the options say)."""
    rows, names = recording.channels, recording.names
    if not rows:
        if recording.width > 1:
            raise InputError(
                recording.motion,
                f"{recording.width} columns and no channels file naming them: give the "
                "channels file, or keep one column",
            )
        return 0, "1", None
    if options.position_column in names:
        index = names.index(options.position_column)
    else:
        positional = [i for i, row in enumerate(rows) if row.get("type", "").upper() == "POS"]
        if len(rows) == 1:
            positional = [0]
        if len(positional) != 1:
            shown = ", ".join(excerpt(name, quote=False) for name in names[:8])
            raise InputError(
                recording.motion,
                f"{len(rows)} channels ({shown}): choose the position channel "
                "with --position-column NAME",
            )
        index = positional[0]
    return index, names[index], _length_unit(recording, index)


@dataclass(frozen=True)
class LabRecording:
    """A lab trial's players as a participant's exported recording holds them.

    Attributes
    ----------
    times
        Sample times (s), shape (n,): ``start_time + k / SamplingFrequency``.
    positions, velocities
        Shape (players, n), in the trial's player order; NaN where ``n/a``.
    labels, roles
        Of each player.
    graph
        The coupling graph as the sidecar gives it (checked by the session).
    metadata
        The trial's record as a sidecar's metadata holds it
        (`mirror_avatar.files.trial_record.TrialRecord.metadata_json`), and ``bids`` (this file, its
        participant, their slot index and the entities).
    """

    times: Array
    positions: Array
    velocities: Array
    labels: tuple[str, ...]
    roles: tuple[str, ...]
    graph: object
    metadata: dict[str, Any]


def is_lab_recording(path: str | Path) -> bool:
    """Whether a ``_motion.tsv``'s sidecar has the lab export's ``MirrorGame`` key.

    Raises
    ------
    InputError
        As `open_recording`.
    """
    return GAME_KEY in open_recording(path).info


def read_lab_recording(path: str | Path) -> LabRecording:
    """Read a ``_motion.tsv`` that `mirror_avatar.lab.export.bids.export_bids` wrote: every player.

    Channels are named ``position`` and ``velocity`` (the participant's) and
    ``position_<label>``, ``velocity_<label>`` (each other player's).

    Raises
    ------
    InputError
        As `open_recording`; no channels file, no ``MirrorGame`` key (not a lab export) or a
        malformed one, missing channels, rows of the wrong width, or values that are not
        numbers.
    """
    recording = open_recording(path)
    if GAME_KEY not in recording.info:
        raise InputError(
            recording.sidecar,
            f"no {GAME_KEY} key: not a mirror-avatar lab export (`mirror-avatar signature` and "
            "`mirror-avatar generator fit` read single-participant motion files)",
        )
    game, record = _check_game(recording.sidecar, recording.info[GAME_KEY])
    slot = game["slot"]
    if not recording.channels:
        raise InputError(recording.motion, "no channels file naming its columns")
    names = recording.names
    _check_widths(recording.motion, len(names))
    values = _read_numbers(recording.motion, list(range(len(names))), names, "\t", 1)
    columns = {name: values[k] for k, name in enumerate(names)}
    slots = record.slots
    pairs = [_player_channels(recording.motion, columns, s.label, j == slot)
             for j, s in enumerate(slots)]  # fmt: skip
    n = values[0].size
    times = _sample_times(recording, float(game.get("start_time", 0.0)), n)
    return LabRecording(
        times=times,
        positions=np.vstack([p for p, _ in pairs]) if n else np.empty((len(slots), 0)),
        velocities=np.vstack([v for _, v in pairs]) if n else np.empty((len(slots), 0)),
        labels=tuple(s.label for s in slots),
        roles=tuple(s.role for s in slots),
        graph=game["graph"],
        metadata=record.metadata_json() | {"bids": _bids_origin(recording.motion, game)},
    )


def _sample_times(recording: Recording, start: float, n: int) -> Array:
    """Return ``start + k / rate`` (s), shape (n,), refusing times float64 cannot tell apart."""
    times = np.asarray(start + np.arange(n) * (1.0 / recording.rate), dtype=np.float64)
    if not np.all(np.diff(times) > 0):
        raise InputError(
            recording.sidecar,
            f"{GAME_KEY}: start_time {start:g} s and SamplingFrequency {recording.rate:g} Hz give "
            "samples no distinct times (float64 cannot tell them apart); give times from a "
            "nearer epoch",
        )
    return times


def _check_game(sidecar: Path, game: object) -> tuple[dict[str, Any], TrialRecord]:
    """Check a ``MirrorGame`` key's slot index, graph and start time; return it and its record."""
    if not isinstance(game, dict):
        raise InputError(sidecar, f"{GAME_KEY} is not a JSON object")
    record = game_record(sidecar, game)
    n_slots = len(record.slots)
    slot = game.get("slot")
    if isinstance(slot, bool) or not isinstance(slot, int) or not 0 <= slot < n_slots:
        raise InputError(sidecar, f"{GAME_KEY}: slot {slot!r} is not one of {n_slots} slots")
    if not isinstance(game.get("graph"), list):
        raise InputError(sidecar, f"{GAME_KEY}: graph must be a list of lists")
    start = game.get("start_time", 0.0)
    if isinstance(start, bool) or not isinstance(start, int | float) or not math.isfinite(start):
        raise InputError(sidecar, f"{GAME_KEY}: start_time {start!r} is not a number of seconds")
    return game, record


def game_record(sidecar: Path, game: dict[str, Any]) -> TrialRecord:
    """Read the trial's record a ``MirrorGame`` key carries, by the record's one reader.

    The key holds the record as a trial sidecar's metadata does; version 1 of the key (exports
    before the record was carried whole) held the ``lab`` object's keys at its top.

    Raises
    ------
    InputError
        A record that is not one (`mirror_avatar.files.trial_record.trial_record`), or a key
        of a version newer than `GAME_VERSION`, naming ``sidecar`` and the key.
    """
    check_version(game, GAME_VERSION, sidecar, GAME_KEY)
    metadata = {"lab": game} | game if game.get("version") == 1 else game
    return trial_record(metadata, sidecar, GAME_KEY)


def _bids_origin(motion: Path, game: dict[str, Any]) -> dict[str, Any]:
    """Return where a lab recording was read: the file, its participant, slot and entities."""
    return {"path": str(motion), "participant": game.get("participant"), "slot": game["slot"],
            "entities": entities(motion.name)}  # fmt: skip


def _check_widths(path: Path, width: int) -> None:
    """Refuse a row that does not hold ``width`` values (read line by line, in constant memory)."""
    with (
        _reading(path, "TSV"),
        open_regular(path, MAX_FILE_BYTES) as file,
        io.TextIOWrapper(file, encoding="utf-8-sig") as lines,
    ):
        for number, line in enumerate(lines, start=1):
            cells = line.count("\t") + 1
            if cells != width:
                raise InputError(
                    path, f"row {number} has {cells} values but the channels file names {width}"
                )


def _player_channels(
    path: Path, columns: dict[str, Array], label: str, own: bool
) -> tuple[Array, Array]:
    """Return a player's positions and velocities, shape (n,) each."""
    names = channel_names(label, own)
    missing = [name for name in names if name not in columns]
    if missing:
        raise InputError(path, f"missing channel(s) {', '.join(missing)} of player {label!r}")
    return columns[names[0]], columns[names[1]]


@dataclass(frozen=True)
class TrackedPoints:
    """The players of a BIDS-Motion recording made by any tool: one per tracked point.

    Attributes
    ----------
    times
        Sample times (s), shape (n,): ``k / SamplingFrequency``.
    positions
        Shape (points, n), normalised units (`mirror_avatar.files.importing`), short gaps filled.
    labels
        Each tracked point's name.
    metadata
        ``bids``: this file, its entities and the sidecar's ``TaskName``.
    """

    times: Array
    positions: Array
    labels: tuple[str, ...]
    metadata: dict[str, Any]


def read_tracked_points(path: str | Path, options: ImportOptions = DEFAULT_IMPORT) -> TrackedPoints:
    """Read a BIDS-Motion recording's tracked points as players, in the channels' order.

    Each tracked point (``_channels.tsv`` column ``tracked_point``) with a ``POS`` channel is a
    player: its ``x`` component's channel, else its first ``POS`` channel, converted from its
    ``units`` (mm, cm, m) as `read_bids_motion` converts one; a file without a channels file
    holds one column, one player.

    Raises
    ------
    InputError
        As `open_recording`; no ``POS`` channel; a channel's unit not a length; a value that is
        not a number; any `mirror_avatar.files.trial_io.import_trial` problem of a point's
        positions.
    """
    recording = open_recording(path)
    points: dict[str, int] = {}
    for index, row in enumerate(recording.channels):
        if row.get("type", "").upper() == "POS":
            point = row.get("tracked_point", MISSING)
            point = row.get("name", "") if point in ("", MISSING) else point
            if point not in points or row.get("component", "").lower() == "x":
                points[point] = index
    if recording.channels and not points:
        raise InputError(recording.motion, "no POS channel in its channels file: no tracked point")
    chosen = [(0, "1", None)] if not recording.channels else [
        (index, recording.names[index], _length_unit(recording, index))
        for index in points.values()
    ]  # fmt: skip
    if not recording.channels:
        _position_channel(recording, options)  # one column, or the refusal naming the problem
    values = _read_numbers(recording.motion, [c for c, _, _ in chosen], [n for _, n, _ in chosen],
                           "\t", 1)  # fmt: skip
    times = np.arange(values[0].size) / recording.rate
    trials = [import_trial(times, column, recording.motion, replace(options, time_unit="s"), unit)
              for column, (_, _, unit) in zip(values, chosen, strict=True)]  # fmt: skip
    if len({trial.n_samples for trial in trials}) != 1:
        raise InputError(recording.motion, "its tracked points have different blank rows")
    task = _name_in(recording.info, "TaskName", recording.sidecar, "")
    bids = {"path": str(recording.motion), "entities": entities(recording.motion.name)}
    return TrackedPoints(
        times=trials[0].times,
        positions=np.vstack([trial.positions for trial in trials]),
        labels=tuple(points) if points else (recording_stem(recording.motion.name),),
        metadata={"bids": bids | ({"TaskName": task} if task else {})},
    )


def _length_unit(recording: Recording, index: int) -> str | None:
    """Return a channel's length unit (None: not given), refusing one that is not a length."""
    unit = recording.channels[index].get("units", "")
    if unit in ("", MISSING):
        return None
    if unit not in POSITION_UNITS:
        raise InputError(
            recording.motion.with_name(f"{recording_stem(recording.motion.name)}_channels.tsv"),
            f"unit {excerpt(unit)} of channel {excerpt(recording.names[index])} is not mm, cm or m",
        )
    return unit
