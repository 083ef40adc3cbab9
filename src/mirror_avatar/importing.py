"""A researcher's file conventions: which columns, which units, and short tracking drop-outs.

The toolkit's exchange format is a ``time,position`` CSV in seconds and normalised units (the
playing range [-0.5, 0.5]; the Bristol set-up maps 60 cm of hand travel to one unit). Recordings
from other set-ups are read with `ImportOptions`: the time and position columns by name, time in
seconds, milliseconds or Unix-epoch seconds or milliseconds, positions normalised or in mm, cm or
m with the playing range as a setting. Nothing is guessed: a file that does not fit the options
is refused with one line naming the option that would read it. Short drop-outs (blank cells or
NaN, where tracking was lost) are interpolated linearly up to `ImportOptions.max_gap` seconds and
reported; longer ones are refused. Values quoted from a file in an error line are cut to
`ECHO_CHARS` characters (`excerpt`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from mirror_avatar.errors import InputError

Array = NDArray[np.float64]

TIME_UNITS = {"s": 1.0, "ms": 1e-3, "epoch": 1.0, "epoch_ms": 1e-3}
"""Time units and their length in seconds; the epoch ones count from the first sample."""

POSITION_UNITS = {"normalised": None, "mm": 0.1, "cm": 1.0, "m": 100.0}
"""Position units and their length in cm (None: already normalised)."""

PLAYING_RANGE_CM = 60.0
"""Centimetres of hand travel that make one normalised unit (the Bristol set-up)."""

MAX_GAP = 0.2
"""Longest drop-out (s) interpolated by default."""

LATEST_PLAUSIBLE_START = 1e5
"""A first time stamp later than this (s, about a day) is a clock, not a trial's time axis."""

MISSING_CELLS = ("", "nan", "na", "n/a")
"""Cells that are a missing sample (compared after stripping spaces, in any letter case)."""

ECHO_CHARS = 40
"""Most characters of a value from a file quoted in an error line (**choice**)."""


@dataclass(frozen=True)
class ImportOptions:
    """How to read a researcher's trial files.

    Parameters
    ----------
    time_column, position_column
        Column names (CSV and Parquet) or, for BIDS-Motion, the position channel's name.
    time_unit
        One of `TIME_UNITS`: ``s``, ``ms``, ``epoch`` (Unix seconds) or ``epoch_ms``.
    position_unit
        One of `POSITION_UNITS`: ``normalised``, ``mm``, ``cm`` or ``m``. BIDS-Motion files
        with a ``channels.tsv`` take the unit named there.
    playing_range
        Centimetres of hand travel that make one normalised unit.
    max_gap
        Longest run of missing positions interpolated (s); 0 refuses every gap.
    """

    time_column: str = "time"
    time_unit: str = "s"
    position_column: str = "position"
    position_unit: str = "normalised"
    playing_range: float = PLAYING_RANGE_CM
    max_gap: float = MAX_GAP

    def __post_init__(self) -> None:
        if self.time_unit not in TIME_UNITS:
            raise InputError("--time-unit", f"must be one of {', '.join(TIME_UNITS)}")
        if self.position_unit not in POSITION_UNITS:
            raise InputError("--position-unit", f"must be one of {', '.join(POSITION_UNITS)}")
        if not (np.isfinite(self.playing_range) and self.playing_range > 0):
            raise InputError("--playing-range", "must be a positive number of centimetres")
        if not (np.isfinite(self.max_gap) and self.max_gap >= 0):
            raise InputError("--max-gap", "must be a non-negative number of seconds")

    def describe(self) -> dict[str, Any]:
        """Return the options as recorded in each trial's metadata."""
        return asdict(self)

    def seconds(self, times: Array, source: str) -> Array:
        """Convert a time column to seconds (epoch units: from the first sample)."""
        seconds = times * TIME_UNITS[self.time_unit]
        if seconds.size == 0:
            return seconds
        if self.time_unit.startswith("epoch"):
            return seconds - seconds[0]
        if abs(seconds[0]) > LATEST_PLAUSIBLE_START:
            raise InputError(
                source,
                f"time starts at {seconds[0]:.6g} s, a clock rather than a trial's time: for "
                "Unix-epoch time stamps give --time-unit epoch (or epoch_ms)",
            )
        return seconds

    def normalised(self, positions: Array, unit: str | None = None) -> Array:
        """Convert positions to normalised units (``unit`` overrides `position_unit`)."""
        length_cm = POSITION_UNITS[unit or self.position_unit]
        if length_cm is None:
            return positions
        return positions * length_cm / self.playing_range


DEFAULT_IMPORT = ImportOptions()
"""The exchange format: ``time`` in seconds and ``position`` in normalised units."""


def excerpt(value: object, quote: bool = True) -> str:
    """Show a value from a user's file in an error line, cut to `ECHO_CHARS` characters.

    Text is escaped as ``repr`` does (so control characters cannot garble the line) and, with
    ``quote``, quoted; anything else is shown with ``str``. A longer value ends in ``...`` and
    its length in characters.
    """
    text = value if isinstance(value, str) else str(value)
    shown = text[:ECHO_CHARS]
    if isinstance(value, str):
        shown = repr(shown) if quote else repr(shown)[1:-1]
    return shown if len(text) <= ECHO_CHARS else f"{shown}... ({len(text)} characters)"


def parse_cells(cells: pd.Series) -> tuple[Array, int | None]:
    """Read text cells as numbers; a blank or `MISSING_CELLS` cell is a missing sample (NaN).

    Parameters
    ----------
    cells
        Text cells, shape (n,); a NaN entry is a blank cell.

    Returns
    -------
    values : ndarray
        The numbers, shape (n,), NaN where missing.
    bad : int or None
        Position of the first cell that is neither a number nor missing; None if there is none.
    """
    text = cells.fillna("").astype(str).str.strip()
    missing = text.str.lower().isin(MISSING_CELLS).to_numpy()
    values = pd.to_numeric(text.mask(missing), errors="coerce").to_numpy(np.float64)
    bad = np.flatnonzero(np.isnan(values) & ~missing)
    return values, (int(bad[0]) if bad.size else None)


def fill_gaps(
    times: Array, positions: Array, max_gap: float, source: str
) -> tuple[Array, Array, int]:
    """Interpolate missing positions (NaN) over gaps of at most ``max_gap`` seconds.

    Missing samples at the start or end cannot be interpolated and are dropped. Infinite
    positions are not missing: `mirror_avatar.trials.make_trial` refuses them.

    Returns
    -------
    times, positions : ndarray
        The samples kept, positions filled.
    filled : int
        How many samples were interpolated.

    Raises
    ------
    InputError
        A gap longer than ``max_gap`` (naming its times and length, and ``--max-gap``), or fewer
        than two positions.
    """
    missing = np.isnan(positions)
    if not missing.any():
        return times, positions, 0
    valid = np.flatnonzero(~missing)
    if valid.size < 2:
        raise InputError(source, "fewer than two positions are present")
    keep = slice(valid[0], valid[-1] + 1)
    times, positions, missing = times[keep], positions[keep].copy(), missing[keep]
    starts = np.flatnonzero(np.diff(np.concatenate([[0], missing.astype(np.int8)])) == 1)
    ends = np.flatnonzero(np.diff(np.concatenate([missing.astype(np.int8), [0]])) == -1)
    for start, end in zip(starts, ends, strict=True):
        length = times[end + 1] - times[start - 1]
        if length > max_gap:
            raise InputError(
                source,
                f"no position from t = {times[start]:.3f} s to {times[end]:.3f} s ({length:.3g} s "
                f"of tracking lost); gaps up to --max-gap {max_gap:g} s are interpolated",
            )
    good = ~missing
    positions[missing] = np.interp(times[missing], times[good], positions[good])
    return times, positions, int(missing.sum())
