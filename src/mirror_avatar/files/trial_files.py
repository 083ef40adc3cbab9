"""One trial file of any supported format, read or written by its name.

CSV, Parquet and MATLAB files are read by `mirror_avatar.files.trial_io`, BIDS-Motion recordings by
`mirror_avatar.files.bids.reading`; folders of files by
`mirror_avatar.cli.trial_sets.read_trial_set`.
"""

from __future__ import annotations

from pathlib import Path

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.bids.names import MOTION_SUFFIX
from mirror_avatar.files.bids.reading import read_bids_motion
from mirror_avatar.files.bids.writing import write_bids_motion
from mirror_avatar.files.importing import DEFAULT_IMPORT, ImportOptions
from mirror_avatar.files.trial_io import (
    MAX_MAT_TRIALS,
    only_trial,
    read_csv_trials,
    read_mat_struct,
    read_parquet_trials,
    write_csv_trial,
    write_parquet_trial,
)
from mirror_avatar.files.trials import Trial

MAT_DURATION = 60.0
"""Seconds spanned by each trial of a ``.mat`` file read through `read_trial` (**choice**)."""

SUPPORTED = (".csv", ".mat", ".parquet", MOTION_SUFFIX)
"""How the names of trial files end."""


def read_trial(path: str | Path, options: ImportOptions = DEFAULT_IMPORT) -> Trial:
    """Read one trial by extension; a ``.mat`` file must hold exactly one trial.

    A MATLAB file of more is refused from its header, before its trials are read.
    """
    return only_trial(read_trial_file(path, options, max_trials=1), path)


def read_trial_file(
    path: str | Path, options: ImportOptions = DEFAULT_IMPORT, max_trials: int = MAX_MAT_TRIALS
) -> list[Trial]:
    """Read the trials of one file by its extension (a ``.mat`` file may hold ``max_trials``).

    Folders of files are read by `mirror_avatar.cli.trial_sets.read_trial_set`.
    """
    path = Path(path)
    suffix = MOTION_SUFFIX if path.name.endswith(MOTION_SUFFIX) else path.suffix.lower()
    if suffix not in SUPPORTED:
        raise InputError(
            path,
            f"unknown extension {suffix!r}; trial files are {', '.join(SUPPORTED)}"
            + (" (a folder name? it does not exist)" if not (suffix or path.exists()) else ""),
        )
    if suffix == ".csv":
        return read_csv_trials(path, options)
    if suffix == ".parquet":
        return read_parquet_trials(path, options)
    if suffix == MOTION_SUFFIX:
        return [read_bids_motion(path, options)]
    return read_mat_struct(path, MAT_DURATION, max_trials=max_trials)


def write_trial(trial: Trial, path: str | Path) -> None:
    """Write one trial by extension (``.csv``, ``.parquet`` or ``_motion.tsv``)."""
    suffix = Path(path).suffix.lower()
    if Path(path).name.endswith(MOTION_SUFFIX):
        write_bids_motion(trial, path)
    elif suffix == ".parquet":
        write_parquet_trial(trial, path)
    elif suffix == ".csv":
        write_csv_trial(trial, path)
    else:
        raise InputError(path, "can only write .csv, .parquet or _motion.tsv")
