"""The game engine: two players, one session, advanced one control period at a time.

Both players observe each other's state at t_k and advance simultaneously to t_k + T (METHODS
sections 1 and 5). A `Session` records both players' positions, velocities, controls and
reference velocities, and is saved as Parquet (one row per sample) with a JSON sidecar holding the
players, roles, parameters and seeds, or as CSV.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar import __version__
from mirror_avatar.atomic import atomic_path, write_atomic_text
from mirror_avatar.errors import InputError
from mirror_avatar.players import Player

Array = NDArray[np.float64]
CHANNELS = ("position", "velocity", "control", "reference")
"""Per-player columns of a saved session, named ``<channel>_<player index>``."""


@dataclass(eq=False)
class Session:
    """Two players' recordings at the control period.

    Parameters
    ----------
    times
        Sample times t_k, shape (n,), seconds from the start.
    positions, velocities
        Shape (2, n): player 0 and player 1 (units, units/s).
    controls
        Control applied from t_k to t_{k+1} (units/s²), shape (2, n); NaN where a player reports
        none and in the last column.
    references
        Reference velocity r_s used from t_k to t_{k+1} (units/s), shape (2, n); NaN where a
        player has none and in the last column.
    labels, roles
        Each player's name and role (``leader``, ``follower``, ``joint``, ``solo``...).
    metadata
        Seeds, player descriptions and anything else, JSON-serialisable.
    """

    times: Array
    positions: Array
    velocities: Array
    controls: Array
    references: Array
    labels: tuple[str, str] = ("player 0", "player 1")
    roles: tuple[str, str] = ("leader", "follower")
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def period(self) -> float:
        """Sampling period (s)."""
        return float(self.times[1] - self.times[0])

    @property
    def duration(self) -> float:
        """Length of the session (s)."""
        return float(self.times[-1] - self.times[0])

    def columns(self) -> dict[str, Array]:
        """Return the session as named columns: ``time`` and ``<channel>_<player>``."""
        arrays = dict(zip(CHANNELS, self._arrays(), strict=True))
        table = {"time": self.times}
        for player in (0, 1):
            for channel in CHANNELS:
                table[f"{channel}_{player}"] = arrays[channel][player]
        return table

    def _arrays(self) -> tuple[Array, Array, Array, Array]:
        return self.positions, self.velocities, self.controls, self.references

    def sidecar(self) -> dict[str, Any]:
        """Return what the JSON sidecar holds."""
        return {
            "format": "mirror-avatar/session",
            "version": 1,
            "library_version": __version__,
            "labels": list(self.labels),
            "roles": list(self.roles),
            "period": self.period,
            "n_samples": int(self.times.size),
            "metadata": self.metadata,
        }

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write ``path`` (Parquet) and ``path`` with suffix ``.json`` (sidecar), atomically."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        table = pa.table(self.columns())
        with atomic_path(path) as temporary:
            pq.write_table(table, temporary)
        write_atomic_text(path.with_suffix(".json"), json.dumps(self.sidecar(), indent=2))
        return path

    def save_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write the columns as CSV (header row, NaN written as empty), plus the JSON sidecar."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        columns = self.columns()
        rows = np.column_stack(list(columns.values()))
        lines = [",".join(columns)]
        lines += [",".join("" if math.isnan(v) else repr(v) for v in row) for row in rows.tolist()]
        write_atomic_text(path, "\n".join(lines) + "\n")
        write_atomic_text(path.with_suffix(".json"), json.dumps(self.sidecar(), indent=2))
        return path


def load_session(path: str | os.PathLike[str]) -> Session:
    """Read a session saved by `Session.save` (Parquet) or `Session.save_csv`.

    Raises
    ------
    InputError
        Missing or unreadable file, missing columns, non-finite or too few positions.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "no such file")
    columns = _read_columns(path)
    names = ["time"] + [f"{c}_{p}" for p in (0, 1) for c in CHANNELS]
    missing = [name for name in names if name not in columns]
    if missing:
        raise InputError(path, f"not a session file: missing column(s) {', '.join(missing)}")
    times = columns["time"]
    stacked = {c: np.vstack([columns[f"{c}_{p}"] for p in (0, 1)]) for c in CHANNELS}
    if times.size < 3 or not np.all(np.diff(times) > 0):
        raise InputError(path, "time must hold at least 3 increasing samples")
    if not (np.all(np.isfinite(stacked["position"])) and np.all(np.isfinite(stacked["velocity"]))):
        raise InputError(path, "positions and velocities must be finite")
    sidecar = _read_sidecar(path)
    return Session(
        times,
        stacked["position"],
        stacked["velocity"],
        stacked["control"],
        stacked["reference"],
        labels=tuple(sidecar.get("labels", ("player 0", "player 1")))[:2],
        roles=tuple(sidecar.get("roles", ("leader", "follower")))[:2],
        metadata=dict(sidecar.get("metadata", {})),
    )


def _read_columns(path: Path) -> dict[str, Array]:
    if path.suffix.lower() == ".csv":
        import pandas as pd

        try:
            frame = pd.read_csv(path)
        except (ValueError, OSError, UnicodeDecodeError) as error:
            raise InputError(path, f"not a readable CSV file ({type(error).__name__})") from None
    else:
        import pyarrow as pa
        import pyarrow.parquet as pq

        try:
            frame = pq.read_table(path).to_pandas()
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
    try:
        info = json.loads(sidecar.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError):
        raise InputError(sidecar, "not valid JSON") from None
    if not isinstance(info, dict):
        raise InputError(sidecar, "not a JSON object")
    return info


def player_seeds(seed: int | None) -> tuple[int, int, int]:
    """Return the session's seed (fresh entropy if None) and the players' seeds spawned from it."""
    sequence = np.random.SeedSequence(seed)
    children = sequence.spawn(2)
    return (
        int(sequence.entropy),  # type: ignore[arg-type]
        int(children[0].generate_state(1)[0]),
        int(children[1].generate_state(1)[0]),
    )


def describe_player(player: Player) -> dict[str, Any]:
    """JSON description of a player: its class, label and parameters when it has them."""
    description: dict[str, Any] = {"class": type(player).__name__}
    for name in ("label", "params"):
        value = getattr(player, name, None)
        if value is not None:
            description[name] = value.to_dict() if hasattr(value, "to_dict") else str(value)
    return description


def play(
    player_a: Player,
    player_b: Player,
    duration: float = 60.0,
    seed: int | None = None,
    roles: tuple[str, str] = ("leader", "follower"),
) -> Session:
    """Play one session of two players.

    Parameters
    ----------
    player_a, player_b
        Players 0 and 1, with the same control period.
    duration
        Session length (s); ``round(duration / period)`` periods are played.
    seed
        Session seed; the players are reset with seeds spawned from it (`player_seeds`), so the
        same seed replays the same session. None draws fresh entropy (recorded in the metadata).
    roles
        The players' roles, recorded in the session.

    Returns
    -------
    Session
        ``round(duration / period) + 1`` samples.
    """
    period = float(player_a.period)
    if not math.isclose(period, float(player_b.period)):
        raise InputError("players", f"control periods differ: {period} s and {player_b.period} s")
    if not duration > period:
        raise InputError("duration", f"must exceed one control period ({period} s)")
    n = int(round(duration / period)) + 1
    session_seed, seed_a, seed_b = player_seeds(seed)
    players = (player_a, player_b)
    states = np.full((4, 2, n), np.nan)  # position, velocity, control, reference
    for index, (player, player_seed) in enumerate(zip(players, (seed_a, seed_b), strict=True)):
        states[:2, index, 0] = player.reset(seed=player_seed)
    for k in range(n - 1):
        observed = states[:2, :, k]
        for index, player in enumerate(players):
            partner = observed[:, 1 - index]
            states[:2, index, k + 1] = player.step(float(partner[0]), float(partner[1]))
            states[2, index, k] = getattr(player, "last_control", math.nan)
            states[3, index, k] = getattr(player, "last_reference", math.nan)
    return Session(
        np.arange(n, dtype=np.float64) * period,
        states[0],
        states[1],
        states[2],
        states[3],
        labels=(_label(player_a, "player 0"), _label(player_b, "player 1")),
        roles=roles,
        metadata={
            "seed": session_seed,
            "player_seeds": [seed_a, seed_b],
            "players": [describe_player(p) for p in players],
        },
    )


def _label(player: Player, default: str) -> str:
    return str(getattr(player, "label", "") or default)
