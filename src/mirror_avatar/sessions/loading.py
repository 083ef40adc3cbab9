"""Reading sessions: every file the toolkit writes, lab recordings, and other tools' tables.

`load_session` reads every session the toolkit writes (`mirror_avatar.sessions.session.Session`
files, `mirror_avatar.sessions.writer.SessionWriter` recordings, BIDS-Motion lab recordings and
tracked points), and plain files with only ``time`` and ``position_<i>`` columns (velocities are
then computed as for a trial, METHODS section 2). Other files of several players' positions are
read with a `mirror_avatar.files.importing.ColumnMap` (``--columns
time=time,human=human,avatar=avatar``: labels from the names), and irregularly sampled ones put
on a uniform grid first (``resample``, PCHIP as `mirror_avatar.files.trials.resample`; a step
longer than ``max_gap`` is refused, not bridged).
"""

from __future__ import annotations

import io
import logging
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.bids.names import MOTION_SUFFIX
from mirror_avatar.files.bids.reading import (
    LabRecording,
    TrackedPoints,
    is_lab_recording,
    read_lab_recording,
    read_tracked_points,
)
from mirror_avatar.files.importing import MAX_GAP, ColumnMap, check_steps, excerpt
from mirror_avatar.files.trial_io import (
    MAX_FILE_BYTES,
    MAX_SIDECAR_BYTES,
    check_version,
    refuse_ragged,
)
from mirror_avatar.files.trials import compute_velocity, make_trial
from mirror_avatar.files.user_files import check_regular, open_regular, read_json, read_text
from mirror_avatar.sessions.session import (
    CHANNELS,
    FORMAT_NAME,
    FORMAT_VERSION,
    MIN_SESSION_SAMPLES,
    Session,
)

logger = logging.getLogger(__name__)


Array = NDArray[np.float64]


def load_session(
    path: str | os.PathLike[str],
    columns: ColumnMap | None = None,
    resample: float | None = None,
    max_gap: float = MAX_GAP,
) -> Session:
    """Read a session: any file `Session.save`, `Session.save_csv` or `SessionWriter` wrote.

    A lab trial exported as BIDS-Motion (a ``_motion.tsv`` of `mirror_avatar.lab.export.bids`) is
    read as its whole N-player session (`mirror_avatar.files.bids.reading.read_lab_recording`;
    controls and references NaN); another tool's ``_motion.tsv`` as one player per tracked
    point (`mirror_avatar.files.bids.reading.read_tracked_points`; velocities computed from the
    positions). Also reads plain CSV or Parquet files with a ``time``
    column and ``position_0``, ``position_1``... (velocities are then computed from the
    positions as for a trial; controls and references are NaN). A last CSV line without its
    newline (a recording cut short) is ignored. The sidecar (``.json`` beside the file) is optional.

    Parameters
    ----------
    path
        The file.
    columns
        The time column and each player's position column, labels from the map (the sidecar's
        labels are then not used); None reads ``time``, ``position_0``...
    resample
        Rate (Hz) of a uniform grid the positions are interpolated onto (velocities computed
        on it; controls and references dropped), recorded in ``metadata["import"]``.
    max_gap
        Longest step between samples (s) that ``resample`` interpolates over.

    Raises
    ------
    InputError
        Missing or unreadable file, a sidecar of a session format newer than
        `mirror_avatar.sessions.session.FORMAT_VERSION`, no players, missing columns,
        non-finite positions, time not increasing, too few samples, irregular sampling without
        ``resample`` or a step over ``max_gap`` with it; each naming the option that fixes it.
    """
    path = Path(path)
    check_regular(path, MAX_FILE_BYTES)
    if path.name.endswith(MOTION_SUFFIX):
        if is_lab_recording(path):
            return _lab_recording_session(read_lab_recording(path))
        return _tracked_points_session(read_tracked_points(path))
    table = _read_columns(path)
    if columns is not None:
        table = _mapped(path, table, columns)
    n_players = _count_players(path, table)
    times = table["time"]
    _check_times(path, times)
    read: dict[str, Any] = {} if columns is None else {"columns": str(columns)}
    if resample is not None:
        table, recorded = _resampled(path, table, n_players, resample, max_gap)
        times = table["time"]
        read |= {"resampled_from": recorded, "resample": resample, "max_gap": max_gap}
    channels = {c: _channel(path, table, c, n_players, times) for c in CHANNELS}
    sidecar = _read_sidecar(path)
    metadata = dict(sidecar.get("metadata", {})) | ({"import": read} if read else {})
    labels = columns.labels if columns is not None else tuple(sidecar.get("labels", ()))
    graph = sidecar.get("graph")
    try:
        return Session(
            times,
            channels["position"],
            channels["velocity"],
            channels["control"],
            channels["reference"],
            labels=labels[:n_players],
            roles=tuple(sidecar.get("roles", ()))[:n_players],
            graph=np.zeros((0, 0), dtype=np.int8) if graph is None else np.asarray(graph),
            metadata=metadata,
        )
    except InputError as error:
        raise InputError(path, error.problem) from None


def _check_times(path: Path, times: Array) -> None:
    """Refuse too few samples, or a time that is missing, repeated or earlier than the last.

    The row named is the file's: a CSV file's line (its header is line 1), a Parquet file's
    row from 1.
    """
    if times.size < MIN_SESSION_SAMPLES:
        raise InputError(
            path, f"{times.size} samples; a session needs at least {MIN_SESSION_SAMPLES}"
        )
    first_row = 2 if path.suffix.lower() == ".csv" else 1
    missing = np.flatnonzero(~np.isfinite(times))
    if missing.size:
        k = int(missing[0])
        raise InputError(
            path, f"row {k + first_row}: no time ({times[k]}); every sample needs its time (s)"
        )
    steps = np.diff(times)
    wrong = np.flatnonzero(steps <= 0)
    if wrong.size:
        k = int(wrong[0]) + 1
        what = "repeats" if steps[k - 1] == 0 else "goes back"
        raise InputError(
            path,
            f"row {k + first_row}: time {what} ({times[k]:.9g} s after {times[k - 1]:.9g} s); "
            "the samples must be in time order, each at a time of its own",
        )


def _lab_recording_session(recording: LabRecording) -> Session:
    """Make the N-player session of a lab export's recording."""
    path = recording.metadata["bids"]["path"]
    if recording.times.size < MIN_SESSION_SAMPLES:
        raise InputError(path, f"{recording.times.size} samples, fewer than {MIN_SESSION_SAMPLES}")
    try:
        return Session(
            recording.times,
            recording.positions,
            recording.velocities,
            np.full_like(recording.positions, np.nan),
            np.full_like(recording.positions, np.nan),
            labels=recording.labels,
            roles=recording.roles,
            graph=np.asarray(recording.graph),
            metadata=recording.metadata,
        )
    except (InputError, ValueError, TypeError) as error:
        problem = error.problem if isinstance(error, InputError) else "malformed graph"
        raise InputError(path, f"MirrorGame: {problem}") from None


def _tracked_points_session(points: TrackedPoints) -> Session:
    """Make the session of another tool's recording: a player per tracked point."""
    path = points.metadata["bids"]["path"]
    if points.times.size < MIN_SESSION_SAMPLES:
        raise InputError(path, f"{points.times.size} samples, fewer than {MIN_SESSION_SAMPLES}")
    rate = 1.0 / float(np.mean(np.diff(points.times)))
    return Session(
        points.times,
        points.positions,
        np.vstack([compute_velocity(row, rate) for row in points.positions]),
        np.full_like(points.positions, np.nan),
        np.full_like(points.positions, np.nan),
        labels=points.labels,
        metadata=points.metadata,
    )


def _mapped(path: Path, table: dict[str, Array], columns: ColumnMap) -> dict[str, Array]:
    """Rename a file's columns as a session's: ``time`` and ``position_<i>`` per player."""
    names = (columns.time, *columns.columns)
    missing = [name for name in names if name not in table]
    if missing:
        found = ", ".join(excerpt(name) for name in list(table)[:8])
        raise InputError(
            path, f"no column {excerpt(missing[0])} (found {found}): name them in --columns"
        )
    return {"time": table[columns.time]} | {
        f"position_{p}": table[column] for p, column in enumerate(columns.columns)
    }


def _count_players(path: Path, columns: dict[str, Array]) -> int:
    n = 0
    while f"position_{n}" in columns:
        n += 1
    if "time" not in columns or n == 0:
        names = list(columns)
        found = ", ".join(excerpt(name) for name in names[:8])
        time = "time" if "time" in columns else "TIME"
        players = [name for name in names if name != time][:2] or ["A", "B"]
        pairs = [f"{excerpt(name, False)}={excerpt(name, False)}" for name in players]
        example = ",".join([f"time={time}", *pairs])
        what = "'time'" if "time" not in columns else "'position_0'"
        raise InputError(
            path,
            f"not a session file: no {what} column (found {found}): name the time and each "
            f"player's position column with --columns {example}",
        )
    return n


def _resampled(
    path: Path, table: dict[str, Array], n_players: int, rate: float, max_gap: float
) -> tuple[dict[str, Array], float]:
    """Interpolate each player's positions onto a uniform grid at ``rate`` Hz (PCHIP).

    Returns the table of ``time`` and ``position_<i>`` on the grid, and the recording's mean
    rate (Hz).
    """
    times = table["time"]
    check_steps(times, max_gap, str(path))
    trials = [
        make_trial(times, table[f"position_{p}"], source=str(path)).resampled(rate)
        for p in range(n_players)
    ]
    grid = {"time": trials[0].times} | {
        f"position_{p}": trial.positions for p, trial in enumerate(trials)
    }
    return grid, float(trials[0].metadata["resampled_from"])


def _channel(
    path: Path, columns: dict[str, Array], channel: str, n_players: int, times: Array
) -> Array:
    names = [f"{channel}_{p}" for p in range(n_players)]
    present = [name in columns for name in names]
    if channel == "position" or all(present):
        values = np.vstack([columns[name] for name in names])
        if channel in ("position", "velocity") and not np.all(np.isfinite(values)):
            raise InputError(path, f"{channel}s must be finite")
        return values
    if any(present):
        missing = [name for name, there in zip(names, present, strict=True) if not there]
        raise InputError(path, f"missing column(s) {', '.join(missing)}")
    if channel == "velocity":
        return _velocities(path, columns, n_players, times)
    return np.full((n_players, times.size), np.nan)


def _velocities(path: Path, columns: dict[str, Array], n_players: int, times: Array) -> Array:
    steps = np.diff(times)
    if np.any(np.abs(steps - steps.mean()) > 1e-6 * steps.mean()):
        raise InputError(
            path,
            f"irregular sampling (steps of {steps.min():.3g} to {steps.max():.3g} s, mean rate "
            f"{1 / steps.mean():.3g} Hz): give --resample HZ (for instance --resample 100)",
        )
    rate = 1.0 / float(steps.mean())
    return np.vstack([compute_velocity(columns[f"position_{p}"], rate) for p in range(n_players)])


def _read_columns(path: Path) -> dict[str, Array]:
    if path.suffix.lower() == ".csv":
        import pandas as pd

        refuse_ragged(path, ",")
        text = read_text(path, MAX_FILE_BYTES)
        complete = text if text.endswith("\n") else text[: text.rfind("\n") + 1]
        if text[len(complete) :].strip():
            logger.warning(
                "%s: line %d has no line end (a recording cut off, e.g. by a full disk): it may "
                "be torn and is left out",
                path,
                complete.count("\n") + 1,
            )
        try:
            frame = pd.read_csv(io.StringIO(complete))
        except (ValueError, OSError) as error:
            raise InputError(path, f"not a readable CSV file ({type(error).__name__})") from None
    else:
        import pyarrow as pa
        import pyarrow.parquet as pq

        try:
            with open_regular(path, MAX_FILE_BYTES) as file:
                frame = pq.read_table(file).to_pandas()
        except (pa.ArrowException, OSError) as error:
            raise InputError(
                path, f"not a readable Parquet file ({type(error).__name__})"
            ) from None
    try:
        values = np.ascontiguousarray(frame.to_numpy(dtype=np.float64).T)
    except (ValueError, TypeError):
        raise InputError(path, "session columns must be numeric") from None
    return {str(name): column for name, column in zip(frame.columns, values, strict=True)}


def _read_sidecar(path: Path) -> dict[str, Any]:
    """Read the sidecar beside ``path`` ({} when none); a session's of a known version only."""
    sidecar = path.with_suffix(".json")
    if not sidecar.is_file():
        return {}
    info = read_json(sidecar, MAX_SIDECAR_BYTES)
    if not isinstance(info, dict):
        raise InputError(sidecar, "not a JSON object")
    if info.get("format") == FORMAT_NAME:
        check_version(info, FORMAT_VERSION, sidecar)
    return info
