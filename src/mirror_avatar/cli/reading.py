"""Options shared by the commands that read a researcher's trial files, and how they report.

`import_options` adds ``--time-column``, ``--time-unit``, ``--position-column``,
``--position-unit``, ``--playing-range``, ``--max-gap``, ``--columns`` and ``--resample`` and
hands the command one `mirror_avatar.files.importing.ImportOptions` (with ``--offset`` and
``--centre`` to move positions); `session_options` adds ``--columns``, ``--resample`` and
``--max-gap`` to the commands that read sessions, as one `SessionReading`;
`group_option` adds ``--group-by``; `read_and_report` reads the paths and prints the groups
found, the files skipped and a table of each trial's checks
(`mirror_avatar.cli.import_checks`) before any analysis, warnings on standard error.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click

from mirror_avatar.cli.constrained import constrained_type, ranged, with_range
from mirror_avatar.cli.import_checks import check_table, check_trial
from mirror_avatar.cli.trial_sets import GROUPINGS, read_trial_set
from mirror_avatar.common.constraints import Interval
from mirror_avatar.files.importing import (
    MAX_GAP,
    MAX_GAP_RANGE,
    PLAYING_RANGE_CM,
    POSITION_UNITS,
    RESAMPLE_RANGE,
    TIME_UNITS,
    ColumnMap,
    ImportOptions,
    parse_columns,
)
from mirror_avatar.files.trials import Trial
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.sessions.session import Session


def _parse_columns(
    context: click.Context, parameter: click.Parameter, value: str | None
) -> ColumnMap | None:
    """Read ``--columns`` (a click callback)."""
    return None if value is None else parse_columns(value)


COLUMNS_OPTION = click.option(
    "--columns", callback=_parse_columns, default=None,
    help="The time column, then LABEL=COLUMN for each player's positions, in order, for "
    "instance time=time,human=human,avatar=avatar: the labels name the players.",
)  # fmt: skip
RESAMPLE_OPTION = click.option(
    "--resample", type=constrained_type(RESAMPLE_RANGE), default=None,
    help=with_range("Interpolate irregularly sampled recordings (PCHIP) onto a uniform grid "
                    "at this rate (Hz); steps between samples over --max-gap are refused, not "
                    "bridged.", RESAMPLE_RANGE),
)  # fmt: skip
MAX_GAP_OPTION = click.option(
    "--max-gap", type=constrained_type(MAX_GAP_RANGE), default=MAX_GAP, show_default=True,
    help=with_range("Longest drop-out interpolated: seconds between the positions on either "
                    "side of missing ones (with --resample: the longest step between samples).",
                    MAX_GAP_RANGE),
)  # fmt: skip


@dataclass(frozen=True)
class SessionReading:
    """How to read session files that are not the toolkit's own (`load_session`'s options).

    Parameters
    ----------
    columns
        The time column and each player's position column; None: ``position_0``...
    resample
        Rate (Hz) of the uniform grid irregular recordings are interpolated onto; None: none.
    max_gap
        Longest step between samples (s) interpolated over by ``resample``.
    """

    columns: ColumnMap | None = None
    resample: float | None = None
    max_gap: float = MAX_GAP

    def __post_init__(self) -> None:
        ImportOptions(max_gap=self.max_gap, resample=self.resample)

    def load(self, path: Path) -> Session:
        """Read the session file ``path`` with these options."""
        return load_session(path, self.columns, self.resample, self.max_gap)


DEFAULT_READING = SessionReading()
"""Sessions as the toolkit writes them: ``time``, ``position_0``... sampled uniformly."""


def session_options(command: Callable[..., None]) -> Callable[..., None]:
    """Add ``--columns``, ``--resample`` and ``--max-gap``; the command receives ``reading``."""

    @functools.wraps(command)
    def wrapper(
        *args: Any, columns: ColumnMap | None, resample: float | None, max_gap: float,
        **kwargs: Any,
    ) -> None:  # fmt: skip
        command(*args, reading=SessionReading(columns, resample, max_gap), **kwargs)

    for decorate in (MAX_GAP_OPTION, RESAMPLE_OPTION, COLUMNS_OPTION):
        wrapper = decorate(wrapper)
    return wrapper


def session_note(path: Path, session: Session) -> str | None:
    """Say how a session was read when not as the toolkit writes it: players and resampling."""
    read = session.metadata.get("import")
    if not isinstance(read, dict) or not read:
        return None
    players = ", ".join(f"player {p} {label}" for p, label in enumerate(session.labels))
    parts = [f"{path}: {players}"]
    if "columns" in read:
        parts[0] += f" (--columns {read['columns']})"
    if "resampled_from" in read:
        parts.append(
            f"resampled from {read['resampled_from']:.3g} Hz (mean) to {read['resample']:g} Hz "
            "by PCHIP"
        )
    return "; ".join(parts)


def import_options(command: Callable[..., None]) -> Callable[..., None]:
    """Add the import options to a command, which receives them as ``options``."""

    @functools.wraps(command)
    def wrapper(
        *args: Any,
        time_column: str,
        time_unit: str,
        position_column: str,
        position_unit: str,
        playing_range: float,
        max_gap: float,
        offset: float,
        centre: bool,
        columns: ColumnMap | None,
        resample: float | None,
        **kwargs: Any,
    ) -> None:
        options = ImportOptions(
            time_column, time_unit, position_column, position_unit, playing_range, max_gap,
            offset, centre, columns, resample,
        )  # fmt: skip
        command(*args, options=options, **kwargs)

    decorators = [
        click.option("--time-column", default="time", show_default=True,
                     help="Name of the time column."),
        click.option("--time-unit", type=click.Choice(list(TIME_UNITS)), default="s",
                     show_default=True,
                     help="Unit of time (us: microseconds); epoch (Unix seconds), epoch_ms and "
                     "epoch_us are a clock's stamps, counted from the first."),
        click.option("--position-column", default="position", show_default=True,
                     help="Name of the position column (BIDS-Motion: of the channel)."),
        click.option("--position-unit", type=click.Choice(list(POSITION_UNITS)),
                     default="normalised", show_default=True,
                     help="Unit of position (BIDS-Motion files with channels.tsv name theirs)."),
        click.option("--playing-range", default=PLAYING_RANGE_CM, show_default=True,
                     **ranged("Centimetres of hand travel that make one normalised unit.",
                              Interval(float, 0.0, 10_000.0, "right", "cm"))),
        MAX_GAP_OPTION,
        click.option("--offset", default=0.0, show_default=True,
                     **ranged("Subtract this from every position (in --position-unit): where "
                              "the tracker reads the middle of the playing range.",
                              Interval(float, -1e6, 1e6))),
        click.option("--centre", is_flag=True,
                     help="Move each trial so that the middle of its positions' span is 0."),
        COLUMNS_OPTION,
        RESAMPLE_OPTION,
    ]  # fmt: skip
    for decorate in reversed(decorators):
        wrapper = decorate(wrapper)
    return wrapper


def group_option(
    default: str = "directory",
) -> Callable[[Callable[..., None]], Callable[..., None]]:
    """Make the ``--group-by`` option: how trials are grouped into people (or styles)."""
    return click.option(
        "--group-by",
        default=default,
        show_default=True,
        help=f"Group trials by {', '.join(GROUPINGS)} (see the user guide, Your data). A "
        "map's column file holds paths relative to the map file's folder or as given on the "
        "command line (a bare file name only while it names one file).",
    )


def read_and_report(paths: Sequence[Path], group_by: str, options: ImportOptions) -> list[Trial]:
    """Read the paths' trials, print their groups and the files skipped, and return them."""
    found = read_trial_set(paths, group_by, options)
    for note in found.notes:
        click.echo(note)
    for line in found.summary():
        click.echo(line)
    filled = sum(t.metadata.get("import", {}).get("interpolated_samples", 0) for t in found.trials)
    if filled:
        click.echo(f"{filled} missing sample(s) interpolated (gaps up to {options.max_gap:g} s)")
    if options.resample is not None:
        rates = [
            t.metadata["resampled_from"] for t in found.trials if "resampled_from" in t.metadata
        ]
        if rates:
            low, high = f"{min(rates):.3g}", f"{max(rates):.3g}"
            span = low if low == high else f"{low} to {high}"
            click.echo(
                f"{len(rates)} trial(s) resampled by PCHIP to {options.resample:g} Hz from "
                f"{span} Hz (mean rate as recorded)"
            )
    for line in check_table([check_trial(trial) for trial in found.trials]):
        click.echo(line, err=line.startswith("warning:"))
    return found.trials
