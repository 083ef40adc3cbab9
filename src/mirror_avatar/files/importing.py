"""A researcher's file conventions: which columns, which units, and short tracking drop-outs.

The toolkit's exchange format is a ``time,position`` CSV in seconds and normalised units (the
playing range [-0.5, 0.5]; the Bristol set-up maps 60 cm of hand travel to one unit). Recordings
from other set-ups are read with `ImportOptions`: the time and position columns by name, time in
seconds, milliseconds or microseconds (Leap Motion's frames), or a clock's stamps in any of them
counted from the first sample (Unix time, a tracker's clock), positions normalised or in mm, cm or
m with the playing range as a setting. Nothing is guessed: a file that does not fit the options
is refused with one line naming the option that would read it. Short drop-outs (blank cells or
NaN, where tracking was lost) are interpolated linearly up to `ImportOptions.max_gap` seconds and
reported; longer ones are refused. Values quoted from a file in an error line are cut to
`ECHO_CHARS` characters (`excerpt`).

A recording of several players in one file (``time,human,avatar``) is read with a `ColumnMap`
(``--columns time=time,human=human,avatar=avatar``): the time column, then one player per
``LABEL=COLUMN``, labels taken from the names. An irregularly sampled recording (web pages and
hand trackers stamp each frame as it comes) is put on a uniform grid with ``--resample HZ``
(`check_steps` first refuses a step between samples longer than ``--max-gap``: resampling does
not bridge what was never recorded).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from mirror_avatar.common.constraints import Interval
from mirror_avatar.common.errors import InputError

Array = NDArray[np.float64]

TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "epoch": 1.0, "epoch_ms": 1e-3, "epoch_us": 1e-6}
"""Time units and their length in seconds; the epoch ones, a clock's stamps (Unix time, a
tracker's clock such as Leap Motion's microseconds), count from the first sample."""

POSITION_UNITS = {"normalised": None, "mm": 0.1, "cm": 1.0, "m": 100.0}
"""Position units and their length in cm (None: already normalised)."""

PLAYING_RANGE_CM = 60.0
"""Centimetres of hand travel that make one normalised unit (the Bristol set-up)."""

MAX_GAP = 0.2
"""Longest drop-out (s) interpolated by default."""

LATEST_PLAUSIBLE_START = 1e5
"""A first time stamp later than this (s, about a day) is a clock, not a trial's time axis."""

GAP_TOLERANCE = 1e-6
"""Seconds by which a drop-out may exceed ``--max-gap`` and still be interpolated: a clock's
rounding, finer than any tracker's sampling (**choice**)."""

MISSING_CELLS = ("", "nan", "na", "n/a")
"""Cells that are a missing sample (compared after stripping spaces, in any letter case)."""

RESAMPLE_RANGE = Interval(float, 1.0, 10_000.0, "both", "Hz")
"""Rates ``--resample`` accepts: `mirror_avatar.files.trials.MIN_RATE` to ``MAX_RATE``."""

MAX_GAP_RANGE = Interval(float, 0.0, None, "both", "s")
"""Values ``--max-gap`` accepts (0 refuses every gap)."""

ECHO_CHARS = 40
"""Most characters of a value from a file quoted in an error line (**choice**)."""


@dataclass(frozen=True)
class ColumnMap:
    """Which columns of a file hold the time and each player's position.

    Parameters
    ----------
    time
        The time column.
    players
        ``(label, column)`` per player, in order: the label names the player in every output.
    """

    time: str
    players: tuple[tuple[str, str], ...]

    @property
    def labels(self) -> tuple[str, ...]:
        """The players' labels, in order."""
        return tuple(label for label, _ in self.players)

    @property
    def columns(self) -> tuple[str, ...]:
        """The players' position columns, in order."""
        return tuple(column for _, column in self.players)

    def __str__(self) -> str:
        """Write the map as ``--columns`` takes it."""
        return ",".join(f"{key}={value}" for key, value in (("time", self.time), *self.players))


COLUMNS_EXAMPLE = "time=time,human=human,avatar=avatar"
"""A ``--columns`` value, quoted in error lines."""


def parse_columns(text: str) -> ColumnMap:
    """Read ``--columns``: ``time=TIME``, then ``LABEL=COLUMN`` per player, comma-separated.

    Raises
    ------
    InputError
        A part that is not ``KEY=COLUMN``, a first key other than ``time``, no player, or a
        label or column named twice.
    """
    usage = f"give time=TIME,LABEL=COLUMN,... (for instance {COLUMNS_EXAMPLE})"
    pairs = []
    for part in text.split(","):
        key, equals, value = (piece.strip() for piece in part.partition("="))
        if not (equals and key and value):
            raise InputError("--columns", f"{excerpt(part)} is not KEY=COLUMN: {usage}")
        pairs.append((key, value))
    if pairs[0][0] != "time" or len(pairs) < 2:
        raise InputError("--columns", f"the time column first, then at least one player: {usage}")
    players = tuple(pairs[1:])
    for what, names in (("label", [p[0] for p in players]), ("column", [p[1] for p in players])):
        repeated = sorted({name for name in names if names.count(name) > 1})
        if repeated:
            raise InputError("--columns", f"{what} {excerpt(repeated[0])} is given twice: {usage}")
    if any(label.startswith(".") or "/" in label for label, _ in players):
        raise InputError("--columns", f"labels may not start with '.' or hold '/': {usage}")
    return ColumnMap(pairs[0][1], players)


@dataclass(frozen=True)
class ImportOptions:
    """How to read a researcher's trial files.

    Parameters
    ----------
    time_column, position_column
        Column names (CSV and Parquet) or, for BIDS-Motion, the position channel's name.
    time_unit
        One of `TIME_UNITS`: ``s``, ``ms``, ``us``, or a clock's stamps counted from the first
        sample, ``epoch`` (Unix seconds), ``epoch_ms`` or ``epoch_us``.
    position_unit
        One of `POSITION_UNITS`: ``normalised``, ``mm``, ``cm`` or ``m``. BIDS-Motion files
        with a ``channels.tsv`` take the unit named there.
    playing_range
        Centimetres of hand travel that make one normalised unit.
    max_gap
        Longest drop-out interpolated (s): the time between the positions on either side of
        missing ones (`fill_gaps`); 0 refuses every gap.
    offset
        Position (in ``position_unit``) subtracted from every position: where the tracker
        reads the middle of the playing range.
    centre
        Move each trial so that the middle of its positions' span is 0 (after ``offset``).
    columns
        The time column and each player's position column (overrides ``time_column`` and
        ``position_column``); one trial is read per player.
    resample
        Rate (Hz) of the uniform grid each trial is interpolated onto (PCHIP, METHODS section
        2), after `check_steps`; None keeps the samples' own times.
    """

    time_column: str = "time"
    time_unit: str = "s"
    position_column: str = "position"
    position_unit: str = "normalised"
    playing_range: float = PLAYING_RANGE_CM
    max_gap: float = MAX_GAP
    offset: float = 0.0
    centre: bool = False
    columns: ColumnMap | None = None
    resample: float | None = None

    def __post_init__(self) -> None:
        if self.time_unit not in TIME_UNITS:
            raise InputError("--time-unit", f"must be one of {', '.join(TIME_UNITS)}")
        if self.position_unit not in POSITION_UNITS:
            raise InputError("--position-unit", f"must be one of {', '.join(POSITION_UNITS)}")
        if not (np.isfinite(self.playing_range) and self.playing_range > 0):
            raise InputError("--playing-range", "must be a positive number of centimetres")
        if self.max_gap not in MAX_GAP_RANGE:
            raise InputError("--max-gap", f"must be {MAX_GAP_RANGE}")
        if not np.isfinite(self.offset):
            raise InputError("--offset", "must be a finite number (in --position-unit)")
        if self.resample is not None and self.resample not in RESAMPLE_RANGE:
            raise InputError("--resample", f"must be {RESAMPLE_RANGE}")

    @property
    def player_columns(self) -> ColumnMap:
        """The columns read: `columns`, or ``time_column`` and ``position_column`` (one player)."""
        if self.columns is not None:
            return self.columns
        return ColumnMap(self.time_column, (("", self.position_column),))

    def describe(self) -> dict[str, Any]:
        """Return the options as recorded in each trial's metadata."""
        return asdict(self)

    def seconds(self, times: Array, source: str) -> Array:
        """Convert a time column to seconds (epoch units: from the first sample).

        An epoch clock's first stamp is subtracted in the clock's own unit before scaling, so
        that whole milliseconds stay exact (`clock_offsets` reads a text column exactly).
        """
        if times.size and self.time_unit.startswith("epoch"):
            return (times - times[0]) * TIME_UNITS[self.time_unit]
        seconds = times * TIME_UNITS[self.time_unit]
        if seconds.size == 0:
            return seconds
        if abs(seconds[0]) > LATEST_PLAUSIBLE_START:
            raise InputError(
                source,
                f"time starts at {seconds[0]:.6g} s, a clock rather than a trial's time: for "
                "a clock's stamps give --time-unit epoch, epoch_ms or epoch_us",
            )
        return seconds

    def normalised(self, positions: Array, unit: str | None = None) -> Array:
        """Convert positions to normalised units (``unit`` overrides `position_unit`).

        ``offset`` is subtracted first (in the file's unit); with ``centre`` the span of the
        positions present (NaN: missing) is then centred on 0.
        """
        length_cm = POSITION_UNITS[unit or self.position_unit]
        moved = positions - self.offset
        normalised = moved if length_cm is None else moved * length_cm / self.playing_range
        present = normalised[np.isfinite(normalised)]
        if self.centre and present.size:
            normalised = normalised - (present.min() + present.max()) / 2
        return normalised


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

    A gap's length is the time between the positions on either side of it (what interpolation
    bridges: two missing samples at 10 Hz make 0.3 s), within `GAP_TOLERANCE`.

    Missing samples at the start or end cannot be interpolated and are dropped. Infinite
    positions are not missing: `mirror_avatar.files.trials.make_trial` refuses them.

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
        before, after = times[start - 1], times[end + 1]
        if after - before > max_gap + GAP_TOLERANCE:
            raise InputError(
                source,
                f"no position between t = {before:.3f} s and {after:.3f} s ({after - before:.3g} "
                f"s of tracking lost, {end - start + 1} sample(s) missing); drop-outs up to "
                f"--max-gap {max_gap:g} s are interpolated",
            )
    good = ~missing
    positions[missing] = np.interp(times[missing], times[good], positions[good])
    return times, positions, int(missing.sum())


def check_steps(times: Array, max_gap: float, source: str) -> None:
    """Refuse a step between consecutive samples longer than ``max_gap`` before resampling.

    Parameters
    ----------
    times
        Sample times (s), shape (n,), increasing.
    max_gap
        Longest step (s) interpolated over, within `GAP_TOLERANCE`.
    source
        The file, named in the error line.

    Raises
    ------
    InputError
        Naming the longest step's times and length, and ``--max-gap``.
    """
    steps = np.diff(times)
    if not steps.size:
        return
    k = int(np.argmax(steps))
    if steps[k] > max_gap + GAP_TOLERANCE:
        raise InputError(
            source,
            f"no sample between t = {times[k]:.3f} s and {times[k + 1]:.3f} s ({steps[k]:.3g} s): "
            f"resampling bridges steps up to --max-gap {max_gap:g} s; give a larger --max-gap "
            "to bridge this one, or cut the recording there",
        )


def clock_offsets(cells: pd.Series) -> Array:
    """Read clock stamps as text and return their offsets from the first stamp, exactly.

    A Unix-epoch stamp such as ``1700000000.1`` has no float64 nearer than 1e-7 s, so parsed
    as one number the offsets between stamps carry that error (0.1 reads as 0.0999999).
    Each stamp is split at its decimal point and the whole and fractional parts are
    subtracted separately, in float64.

    Parameters
    ----------
    cells
        Text cells, shape (n,), already checked to be numbers or missing (`parse_cells`).

    Returns
    -------
    ndarray
        Offsets from the first stamp present, in the stamps' unit, shape (n,); NaN where
        missing. Stamps in exponent notation are parsed as single numbers.
    """
    text = cells.fillna("").astype(str).str.strip()
    if text.str.contains("[eE]", regex=True).any():
        values, _ = parse_cells(cells)
        present = values[np.isfinite(values)]
        return values - (present[0] if present.size else 0.0)
    missing = text.str.lower().isin(MISSING_CELLS).to_numpy()
    parts = text.mask(missing).str.partition(".")
    whole_text = parts[0].str.replace(r"^([+-]?)$", r"\g<1>0", regex=True)
    whole = pd.to_numeric(whole_text, errors="coerce").to_numpy(np.float64)
    fraction = pd.to_numeric("0." + parts[2], errors="coerce").to_numpy(np.float64)
    negative = parts[0].str.startswith("-", na=False).to_numpy(bool)
    fraction = np.where(negative, -fraction, fraction)
    stamped = np.flatnonzero(~missing)
    if not stamped.size:
        return np.full(text.size, np.nan)
    first = stamped[0]
    offsets = (whole - whole[first]) + (fraction - fraction[first])
    offsets[missing] = np.nan
    return offsets


def read_clock_offsets(path: Path, column: int) -> Array:
    """Read column ``column`` (from 0) of a CSV file with a header as clock stamps.

    Returns `clock_offsets` of its cells: offsets from the first stamp (the stamps' unit),
    shape (n,), one per row that the numeric reading of the same file gives.
    """
    cells = pd.read_csv(path, header=0, usecols=[column], dtype=str, na_filter=False,
                        encoding="utf-8-sig", skipinitialspace=True).iloc[:, 0]  # fmt: skip
    return clock_offsets(cells)
