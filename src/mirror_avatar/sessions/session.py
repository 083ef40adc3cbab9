"""Sessions: N players recorded together at the control period, on a coupling graph.

A `Session` holds the sample times and, per player, positions, velocities, the control applied
from each sample to the next and the reference velocity used meanwhile (NaN where a player has
none and at the last sample), each player's label and role, the coupling graph
(`mirror_avatar.sessions.graphs`) and JSON metadata (seeds, player descriptions). A dyad is N = 2,
a solo trial N = 1.

Files: Parquet or CSV with a ``time`` column and one column per player and channel,
``<channel>_<player>`` (``position_0``, ``velocity_0``, ``control_0``, ``reference_0``,
``position_1``...), plus a JSON sidecar beside it (same stem, ``.json``) with labels, roles,
graph and metadata. `Session.save` writes them; `mirror_avatar.sessions.writer.SessionWriter`
appends the same CSV a sample at a time and `mirror_avatar.sessions.loading.load_session` reads
them back.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mirror_avatar import __version__
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import (
    atomic_path,
    write_atomic_json,
)
from mirror_avatar.sessions.graphs import Graph, check_graph, complete_graph

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
