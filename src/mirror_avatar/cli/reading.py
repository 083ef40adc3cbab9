"""Options shared by the commands that read a researcher's trial files, and how they report.

`import_options` adds ``--time-column``, ``--time-unit``, ``--position-column``,
``--position-unit``, ``--playing-range`` and ``--max-gap`` and hands the command one
`mirror_avatar.importing.ImportOptions` (with ``--offset`` and ``--centre`` to move positions);
`group_option` adds ``--group-by``; `read_and_report` reads the paths and prints the groups
found, the files skipped and a table of each trial's checks
(`mirror_avatar.import_checks`) before any analysis, warnings on standard error.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import click

from mirror_avatar.import_checks import check_table, check_trial
from mirror_avatar.importing import (
    MAX_GAP,
    PLAYING_RANGE_CM,
    POSITION_UNITS,
    TIME_UNITS,
    ImportOptions,
)
from mirror_avatar.trial_sets import GROUPINGS, read_trial_set
from mirror_avatar.trials import Trial


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
        **kwargs: Any,
    ) -> None:
        options = ImportOptions(
            time_column, time_unit, position_column, position_unit, playing_range, max_gap,
            offset, centre,
        )  # fmt: skip
        command(*args, options=options, **kwargs)

    decorators = [
        click.option("--time-column", default="time", show_default=True,
                     help="Name of the time column."),
        click.option("--time-unit", type=click.Choice(list(TIME_UNITS)), default="s",
                     show_default=True,
                     help="Unit of time; epoch (Unix seconds) and epoch_ms count from the first."),
        click.option("--position-column", default="position", show_default=True,
                     help="Name of the position column (BIDS-Motion: of the channel)."),
        click.option("--position-unit", type=click.Choice(list(POSITION_UNITS)),
                     default="normalised", show_default=True,
                     help="Unit of position (BIDS-Motion files with channels.tsv name theirs)."),
        click.option("--playing-range", type=float, default=PLAYING_RANGE_CM, show_default=True,
                     help="Centimetres of hand travel that make one normalised unit."),
        click.option("--max-gap", type=float, default=MAX_GAP, show_default=True,
                     help="Longest drop-out interpolated: seconds between the positions on "
                     "either side of missing ones."),
        click.option("--offset", type=float, default=0.0, show_default=True,
                     help="Subtract this from every position (in --position-unit): where the "
                     "tracker reads the middle of the playing range."),
        click.option("--centre", is_flag=True,
                     help="Move each trial so that the middle of its positions' span is 0."),
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
    for line in check_table([check_trial(trial) for trial in found.trials]):
        click.echo(line, err=line.startswith("warning:"))
    return found.trials
