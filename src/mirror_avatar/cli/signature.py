"""``mirror-avatar signature``: motor-signature analysis of trial files, as JSON and figures."""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import click

from mirror_avatar.atomic import write_atomic_json
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.errors import InputError
from mirror_avatar.figures import plot_ims, plot_similarity_space, plot_skew_kurtosis
from mirror_avatar.report import render_png
from mirror_avatar.signature import analyse_signatures
from mirror_avatar.trials import Trial

GROUP_BY = ("directory", "file", "none")


@click.command()
@click.argument("paths", nargs=-1, type=click.Path(path_type=Path))
@click.option(
    "--out",
    "out_dir",
    required=True,
    type=click.Path(path_type=Path),
    help="Directory for signature.json, ims.png, similarity.png and strokes.png.",
)
@click.option(
    "--group-by",
    type=click.Choice(GROUP_BY),
    default="directory",
    show_default=True,
    help="Group trials by the directory they are in, by file, or not at all.",
)
@click.option(
    "--level",
    type=float,
    default=0.7,
    show_default=True,
    help="Probability of the confidence ellipses.",
)
@click.option(
    "--rate",
    type=float,
    default=100.0,
    show_default=True,
    help="Rate (Hz) trials are resampled to before the analysis.",
)
@click.option(
    "--bundled",
    is_flag=True,
    help="Analyse the bundled Zhai 2017 trials (grouped by style) as well.",
)
def signature(
    paths: tuple[Path, ...], out_dir: Path, group_by: str, level: float, rate: float, bundled: bool
) -> None:  # fmt: skip
    """Compare the motor signatures of the trials in FILE_OR_DIR... (CSV, MAT, ...)."""
    if not 0.0 < level < 1.0:
        raise InputError("--level", f"must be between 0 and 1, got {level}")
    if not rate > 0.0:
        raise InputError("--rate", f"must be positive, got {rate}")
    if not paths and not bundled:
        raise InputError(None, "give trial files or directories, or --bundled")
    trials = (read_grouped(paths, group_by) if paths else []) + (load_zhai2017() if bundled else [])
    analysis = analyse_signatures(trials, level=level, rate=rate)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_atomic_json(out_dir / "signature.json", analysis.to_json_dict())
    figures = {
        "ims.png": plot_ims(
            dict(zip(analysis.group_names, analysis.group_ims, strict=True)), analysis.bins
        ),
        "similarity.png": plot_similarity_space(
            analysis.points_by_group(),
            analysis.ellipses,
            labels={
                g: [analysis.labels[i] for i in analysis.members(g)] for g in analysis.group_names
            },
        ),
        "strokes.png": plot_skew_kurtosis(analysis.strokes_by_group(), analysis.stroke_ellipses),
    }
    for name, figure in figures.items():
        (out_dir / name).write_bytes(render_png(figure))
    click.echo(f"{len(trials)} trials in {len(analysis.group_names)} groups -> {out_dir}")


def read_grouped(paths: Sequence[Path], group_by: str) -> list[Trial]:
    """Read the trials of each path and set their group.

    ``directory``: the group the reader gave (the trial's directory), or else the directory a
    path is (for a directory) or is in (for a file); ``file``:
    the file's stem for a file argument, the trial's label for trials read from a directory;
    ``none``: one group ``"all"``.
    """
    read_trials = importlib.import_module("mirror_avatar.trial_io").read_trials
    trials = []
    for path in paths:
        for trial in read_trials([path]):
            trials.append(replace(trial, group=_group_of(trial, path, group_by)))
    return trials


def _group_of(trial: Trial, path: Path, group_by: str) -> str:
    if group_by == "none":
        return "all"
    if group_by == "directory":
        return trial.group or (path if path.is_dir() else path.resolve().parent).name
    return trial.label if path.is_dir() else path.stem
