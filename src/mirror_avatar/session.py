"""Sessions: N players recorded together at the control period, on a coupling graph.

A `Session` holds the sample times and, per player, positions, velocities, the control applied
from each sample to the next and the reference velocity used meanwhile (NaN where a player has
none and at the last sample), each player's label and role, the coupling graph
(`mirror_avatar.graphs`) and JSON metadata (seeds, player descriptions). A dyad is N = 2, a solo
trial N = 1.

Files: Parquet or CSV with a ``time`` column and one column per player and channel,
``<channel>_<player>`` (``position_0``, ``velocity_0``, ``control_0``, ``reference_0``,
``position_1``...), plus a JSON sidecar beside it (same stem, ``.json``) with labels, roles,
graph and metadata. `SessionWriter` appends the same CSV a sample at a time, flushed, so a live
recording is readable at every moment; `load_session` reads every session the toolkit writes,
and plain files with only ``time`` and ``position_<i>`` columns (velocities are then computed as
for a trial, METHODS section 2). Other files of several players' positions are read with a
`mirror_avatar.importing.ColumnMap` (``--columns time=time,human=human,avatar=avatar``: labels
from the names), and irregularly sampled ones put on a uniform grid first (``resample``, PCHIP
as `mirror_avatar.trials.resample`; a step longer than ``max_gap`` is refused, not bridged).
"""

from __future__ import annotations

import io
import logging
import math
import os
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mirror_avatar import __version__
from mirror_avatar.atomic import (
    LineFile,
    atomic_path,
    json_text,
    write_atomic_json,
    write_atomic_text,
)
from mirror_avatar.bids.names import MOTION_SUFFIX
from mirror_avatar.bids.reading import (
    LabRecording,
    TrackedPoints,
    is_lab_recording,
    read_lab_recording,
    read_tracked_points,
)
from mirror_avatar.errors import InputError
from mirror_avatar.graphs import Graph, check_graph, complete_graph
from mirror_avatar.importing import MAX_GAP, ColumnMap, check_steps, excerpt
from mirror_avatar.trial_io import MAX_FILE_BYTES, MAX_SIDECAR_BYTES
from mirror_avatar.trials import compute_velocity, make_trial
from mirror_avatar.user_files import check_regular, open_regular, read_json, read_text

logger = logging.getLogger(__name__)

Array = NDArray[np.float64]
CHANNELS = ("position", "velocity", "control", "reference")
"""Per-player channels, in the order of the columns ``<channel>_<player>``."""

FORMAT_NAME = "mirror-avatar/session"
FORMAT_VERSION = 2
"""Sidecar format; version 1 (two players, no graph) is still read."""

MIN_SESSION_SAMPLES = 3
"""Fewest samples a session file may hold."""

_CHANNEL_FIELDS = ("positions", "velocities", "controls", "references")
"""The `Session` fields holding the `CHANNELS`, in order."""


def default_roles(n_players: int) -> tuple[str, ...]:
    """Roles when none are given: ``solo``; ``leader``, ``follower``; ``joint`` for everyone."""
    if n_players == 1:
        return ("solo",)
    if n_players == 2:
        return ("leader", "follower")
    return ("joint",) * n_players


@dataclass(eq=False)
class Session:
    """N players recorded together.

    Parameters
    ----------
    times
        Sample times t_k, shape (n,), seconds, uniformly spaced (the control period).
    positions, velocities
        Shape (N, n): units, units/s.
    controls
        Control applied from t_k to t_{k+1} (units/s²), shape (N, n); NaN where a player reports
        none and at the last sample.
    references
        Reference velocity used from t_k to t_{k+1} (units/s), shape (N, n); NaN where a player
        has none and at the last sample.
    labels, roles
        Each player's name and role; defaults ``player i`` and `default_roles`.
    graph
        Adjacency matrix (N, N): ``graph[k, j] = 1`` when player k observes player j; default
        (None or empty) the complete graph.
    metadata
        Seeds, player descriptions and anything else, JSON-serialisable.
    """

    times: Array
    positions: Array
    velocities: Array
    controls: Array
    references: Array
    labels: tuple[str, ...] = ()
    roles: tuple[str, ...] = ()
    graph: Graph = field(default_factory=lambda: np.zeros((0, 0), dtype=np.int8))
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.times = np.asarray(self.times, dtype=np.float64)
        n = self.times.size
        channels = [np.asarray(a, dtype=np.float64) for a in self._arrays()]
        self.positions, self.velocities, self.controls, self.references = channels
        shapes = {a.shape for a in channels}
        if len(shapes) != 1 or self.positions.ndim != 2 or self.positions.shape[1] != n:
            raise InputError("session", f"channels {sorted(shapes)} do not match {n} samples")
        players = self.n_players
        self.labels = tuple(self.labels) or tuple(f"player {i}" for i in range(players))
        self.roles = tuple(self.roles) or default_roles(players)
        if len(self.labels) != players or len(self.roles) != players:
            raise InputError("session", f"need {players} labels and roles")
        self.graph = (
            complete_graph(players)
            if self.graph is None or np.size(self.graph) == 0
            else check_graph(self.graph, players, connected=False)
        )

    def __getstate__(self) -> dict[str, Any]:
        """Pickle the four channels as one array (sessions cross process boundaries in bulk).

        Channels that are already the four rows of one array (as the compiled loop writes
        them) are pickled without a copy.
        """
        state = dict(self.__dict__)
        fields = [state.pop(name) for name in _CHANNEL_FIELDS]
        base = fields[0].base
        rows = isinstance(base, np.ndarray) and base.shape == (4, *fields[0].shape)
        if rows and all(
            f.base is base and f.ctypes.data == base[i].ctypes.data and f.strides == base[i].strides
            for i, f in enumerate(fields)
        ):
            state["channels"] = base
        else:
            state["channels"] = np.stack(fields)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Restore a pickled session, its channels views of the one array."""
        channels = state.pop("channels")
        self.__dict__.update(state)
        for name, values in zip(_CHANNEL_FIELDS, channels, strict=True):
            setattr(self, name, values)

    @property
    def n_players(self) -> int:
        """Number of players N."""
        return int(self.positions.shape[0])

    @property
    def n_samples(self) -> int:
        """Number of samples n."""
        return int(self.times.size)

    @property
    def period(self) -> float:
        """Sampling period (s)."""
        return float(self.times[1] - self.times[0])

    @property
    def duration(self) -> float:
        """Length of the session (s)."""
        return float(self.times[-1] - self.times[0])

    def _arrays(self) -> tuple[Array, Array, Array, Array]:
        return self.positions, self.velocities, self.controls, self.references

    def trimmed(self, seconds: float) -> Session:
        """Return the session without its first ``seconds`` (samples at t >= t_0 + seconds).

        Raises
        ------
        InputError
            If fewer than two samples would remain.
        """
        keep = self.times >= self.times[0] + seconds
        if keep.sum() < 2:
            raise InputError("trim", f"{seconds:g} s leaves fewer than two samples")
        arrays = [a[:, keep] for a in self._arrays()]
        return replace(
            self,
            times=self.times[keep],
            positions=arrays[0],
            velocities=arrays[1],
            controls=arrays[2],
            references=arrays[3],
        )

    def column_names(self) -> list[str]:
        """Column names of the saved session: ``time``, then ``<channel>_<player>``."""
        return column_names(self.n_players)

    def table(self) -> Array:
        """Return the session as rows, shape (n, 1 + 4 N), columns `column_names`."""
        stacked = np.stack(self._arrays(), axis=1)  # (N, 4, n)
        return np.column_stack([self.times, stacked.reshape(-1, self.n_samples).T])

    def sidecar(self) -> dict[str, Any]:
        """Return what the JSON sidecar holds."""
        return make_sidecar(self.labels, self.roles, self.graph, self.period, self.metadata) | {
            "n_samples": self.n_samples
        }

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write ``path`` (Parquet) and ``path`` with suffix ``.json`` (sidecar), atomically."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        table = pa.table(dict(zip(self.column_names(), self.table().T, strict=True)))
        with atomic_path(path) as temporary:
            pq.write_table(table, temporary)
        write_atomic_json(path.with_suffix(".json"), self.sidecar())
        return path

    def save_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write the columns as CSV (header row, NaN written as empty), plus the JSON sidecar."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        lines = [",".join(self.column_names())] + [format_row(row) for row in self.table()]
        with atomic_path(path) as temporary:
            temporary.write_text("\n".join(lines) + "\n", encoding="utf-8")
        write_atomic_json(path.with_suffix(".json"), self.sidecar())
        return path


def column_names(n_players: int) -> list[str]:
    """``time``, then ``<channel>_<player>`` for each player and channel."""
    return ["time"] + [f"{c}_{p}" for p in range(n_players) for c in CHANNELS]


def format_row(values: ArrayLike) -> str:
    """One CSV line: every float written exactly (``repr``), NaN as an empty field."""
    return ",".join("" if math.isnan(v) else repr(v) for v in np.asarray(values).tolist())


def make_sidecar(
    labels: Sequence[str],
    roles: Sequence[str],
    graph: Graph,
    period: float,
    metadata: dict[str, Any],
) -> dict[str, Any]:
    """Make the sidecar of a session, without ``n_samples`` (a live recording does not know it)."""
    return {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "library_version": __version__,
        "n_players": len(labels),
        "labels": list(labels),
        "roles": list(roles),
        "graph": np.asarray(graph).tolist(),
        "period": period,
        "metadata": metadata,
    }


class SessionWriter:
    """Append a session to a CSV file one sample at a time, each line flushed as it is written.

    The sidecar is written when the file is opened and rewritten (atomically) by `close`, so a
    crash leaves a CSV whose complete lines `load_session` reads (a last line without its line
    end, torn, is left out with a logged warning naming the file and line), and a sidecar saying
    the recording did not finish (``metadata["complete"]`` is False until `close` says otherwise).

    Parameters
    ----------
    path
        The CSV file; it must not exist yet.
    labels, roles, graph, period, metadata
        As in `Session`.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        labels: Sequence[str],
        roles: Sequence[str],
        graph: Graph,
        period: float,
        metadata: dict[str, Any],
    ) -> None:
        self.path = Path(path)
        self.sidecar_path = self.path.with_suffix(".json")
        self.sidecar = make_sidecar(labels, roles, graph, period, dict(metadata))
        self.sidecar["metadata"]["complete"] = False
        self.n_samples = 0
        self._texts = self._written = 0
        self._writing = threading.Lock()
        self._file = LineFile(self.path, ",".join(column_names(len(labels))))
        try:
            self.annotate({})
        except OSError:
            self._file.close()
            raise

    def append(self, row: ArrayLike) -> None:
        """Write one sample: time, then each player's four channels (see `Session.table`)."""
        self._file.write(format_row(row))
        self.n_samples += 1

    def annotate(self, extra: dict[str, Any]) -> None:
        """Add ``extra`` to the sidecar's metadata now (rewritten atomically), file still open."""
        self.write_sidecar(self.sidecar_text(extra))

    def sidecar_text(self, extra: dict[str, Any]) -> tuple[int, str]:
        """Add ``extra`` to the sidecar's metadata; return its text to write, and its number.

        Call it where nothing else changes the sidecar meanwhile (under the caller's lock);
        `write_sidecar` may then write the text elsewhere, later (another thread).
        """
        self.sidecar["metadata"].update(extra)
        self._texts += 1
        return self._texts, json_text(self.sidecar)

    def write_sidecar(self, numbered: tuple[int, str]) -> None:
        """Write a text of `sidecar_text` atomically, unless a later one is on disk already."""
        number, text = numbered
        with self._writing:
            if number > self._written:
                write_atomic_text(self.sidecar_path, text)
                self._written = number

    def close(self, complete: bool, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        """Close the file and rewrite the sidecar with ``complete`` and ``extra`` metadata."""
        self._file.close()
        self.sidecar["n_samples"] = self.n_samples
        self.annotate((extra or {}) | {"complete": complete})
        return self.sidecar


def load_session(
    path: str | os.PathLike[str],
    columns: ColumnMap | None = None,
    resample: float | None = None,
    max_gap: float = MAX_GAP,
) -> Session:
    """Read a session: any file `Session.save`, `Session.save_csv` or `SessionWriter` wrote.

    A lab trial exported as BIDS-Motion (a ``_motion.tsv`` of `mirror_avatar.lab.export.bids`) is
    read as its whole N-player session (`mirror_avatar.bids.reading.read_lab_recording`;
    controls and references NaN); another tool's ``_motion.tsv`` as one player per tracked
    point (`mirror_avatar.bids.reading.read_tracked_points`; velocities computed from the
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
        Missing or unreadable file, no players, missing columns, non-finite positions, time
        not increasing, too few samples, irregular sampling without ``resample`` or a step
        over ``max_gap`` with it; each naming the option that fixes it.
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
    if times.size < MIN_SESSION_SAMPLES or not np.all(np.diff(times) > 0):
        raise InputError(path, f"time must hold at least {MIN_SESSION_SAMPLES} increasing samples")
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
        return {str(name): frame[name].to_numpy(dtype=np.float64) for name in frame.columns}
    except (ValueError, TypeError):
        raise InputError(path, "session columns must be numeric") from None


def _read_sidecar(path: Path) -> dict[str, Any]:
    sidecar = path.with_suffix(".json")
    if not sidecar.is_file():
        return {}
    info = read_json(sidecar, MAX_SIDECAR_BYTES)
    if not isinstance(info, dict):
        raise InputError(sidecar, "not a JSON object")
    return info
