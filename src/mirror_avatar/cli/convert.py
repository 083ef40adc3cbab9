"""``mirror-avatar convert``: a researcher's recordings as exchange-format trial CSVs."""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path

import click

from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.cli.reading import group_option, import_options, read_and_report
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import write_atomic_json
from mirror_avatar.files.importing import ImportOptions
from mirror_avatar.files.trial_io import write_csv_trial
from mirror_avatar.files.trials import Trial

UNSAFE = re.compile(r"[^A-Za-z0-9_.-]+")
"""Characters replaced in folder and file names written."""


@click.command()
@click.argument("paths", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--out",
    "out_dir",
    required=True,
    type=click.Path(path_type=Path),
    help="Folder for one sub-folder of CSV trials per group, and convert.json.",
)
@group_option()
@import_options
def convert(paths: tuple[Path, ...], out_dir: Path, group_by: str, options: ImportOptions) -> None:
    """Convert trial files (CSV, Parquet, BIDS-Motion, MAT) to ``time,position`` CSVs.

    Columns and units are read as the options say and short drop-outs interpolated; each group
    (--group-by) gets a folder OUT/GROUP of ``<trial>.csv`` files in seconds and normalised
    units, named by each trial's identity (its path below the folders given, ``/`` written
    as ``_``; a BIDS file's entities; with --columns, ``-LABEL`` per player), ready for every
    other command; convert.json records the sources and options. Names never start with a dot
    (a hidden source folder gives a visible output folder), and the last line says where the
    files went. Every name is checked before anything is written.
    """
    check_output_dir(out_dir)
    trials = read_and_report(paths, group_by, options)
    targets = [_target(out_dir, trial) for trial in trials]
    _check_targets(targets)
    check_output_dir(out_dir, files=[*(t.relative_to(out_dir) for t in targets), "convert.json"])
    written: list[dict[str, object]] = []
    for trial, target in zip(trials, targets, strict=True):
        target.parent.mkdir(parents=True, exist_ok=True)
        write_csv_trial(trial, target)
        written.append(
            {
                "file": target.relative_to(out_dir).as_posix(),
                "trial": trial.label,
                "source": trial.metadata.get("source"),
                "group": trial.group,
                "interpolated_samples": trial.metadata["import"]["interpolated_samples"]
                if "import" in trial.metadata
                else 0,
            }
        )
    manifest = {"options": options.describe(), "group_by": group_by, "trials": written}
    write_atomic_json(out_dir / "convert.json", manifest)
    click.echo(_where(out_dir, targets))


def _where(out_dir: Path, targets: list[Path]) -> str:
    """Say in one line where the trials went: the folder and each group's sub-folder."""
    folders = Counter(target.parent.name for target in targets)
    shown = ", ".join(f"{name}/ ({count})" for name, count in folders.items())
    return (
        f"wrote {len(targets)} trial(s) to {out_dir.resolve()}: {shown}; sources and options "
        "in convert.json"
    )


def safe_name(text: str, fallback: str) -> str:
    """Make ``text`` a visible file or folder name: unsafe characters as ``_``, no leading dot.

    ``fallback`` is used when nothing is left (``.``, ``..``, an empty group).
    """
    return UNSAFE.sub("_", text).lstrip(".") or fallback


def _target(out_dir: Path, trial: Trial) -> Path:
    """Return where ``trial`` is written: OUT/GROUP/<its identity, one file name>.csv."""
    folder = out_dir / safe_name(trial.group, "trials")
    return folder / f"{safe_name(trial.label, 'trial')}.csv"


def _check_targets(targets: list[Path]) -> None:
    """Refuse two trials written to one file."""
    for target, count in Counter(targets).items():
        if count > 1:
            raise InputError(
                target,
                f"{count} trials of one group would share this name (trials whose paths differ "
                "only in characters other than letters, digits, '_', '.' and '-'); rename them",
            )
