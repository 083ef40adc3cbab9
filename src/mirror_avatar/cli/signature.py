"""``mirror-avatar signature``: motor-signature analysis of trial files: a report, JSON, figures."""

from __future__ import annotations

from importlib.metadata import version
from pathlib import Path

import click

from mirror_avatar.cli.constrained import RATE_HZ, SEED, ranged
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.cli.reading import group_option, import_options, read_and_report
from mirror_avatar.common.constraints import Interval
from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.experiments.signature import compute_group_emd
from mirror_avatar.experiments.signature_report import NO_IDENTIFICATION, signature_page
from mirror_avatar.figures.people import plot_emd_heatmap, plot_people_space
from mirror_avatar.figures.signatures import plot_group_comparison, plot_ims, plot_skew_kurtosis
from mirror_avatar.files.atomic import write_atomic_bytes, write_atomic_json, write_atomic_text
from mirror_avatar.files.importing import ImportOptions
from mirror_avatar.files.trials import Trial
from mirror_avatar.report import render_png
from mirror_avatar.signatures.groups import (
    GroupComparison,
    compare_groups,
    place_trials,
    read_group_map,
)
from mirror_avatar.signatures.identification import identify_people
from mirror_avatar.signatures.likeness import trial_velocity
from mirror_avatar.signatures.signature import (
    SignatureAnalysis,
    analyse_signatures,
    distinct_labels,
)

FIGURES = ("ims.png", "similarity.png", "distances.png", "strokes.png")
"""The figures written beside ``signature.json``."""

REPORT = "report.html"
"""The report, leading with the verdict: are the people told apart, and how well."""

GROUP_FILES = ("groups.json", "groups.png")
"""What ``--groups`` adds: the comparison's numbers and its figure."""


@click.command()
@click.argument("paths", nargs=-1, type=click.Path(path_type=Path))
@click.option(
    "--out",
    "out_dir",
    required=True,
    type=click.Path(path_type=Path),
    help="Directory for report.html, signature.json, ims.png, similarity.png, distances.png "
    "and strokes.png.",
)
@group_option()
@click.option(
    "--level",
    default=0.7,
    show_default=True,
    **ranged("Probability of the confidence ellipses.", Interval(float, 0.0, 1.0, "neither")),
)
@click.option(
    "--rate",
    default=100.0,
    show_default=True,
    **ranged("Rate trials are resampled to before the analysis.", RATE_HZ),
)
@click.option(
    "--bundled",
    is_flag=True,
    help="Analyse the bundled Zhai 2017 trials (grouped by style) as well.",
)
@click.option(
    "--groups",
    "groups_path",
    type=click.Path(path_type=Path),
    help="Compare two groups of people: a CSV or TSV table with a column group and a column "
    "person (a --group-by group) or trial (a trial's label; each trial its own person unless a "
    "person column says whose). Writes groups.json and groups.png.",
)
@click.option(
    "--seed",
    default=0,
    show_default=True,
    **ranged("Seed of the label shuffles (identification's chance, --groups permutations).", SEED),
)
@import_options
def signature(
    paths: tuple[Path, ...],
    out_dir: Path,
    group_by: str,
    level: float,
    rate: float,
    bundled: bool,
    groups_path: Path | None,
    seed: int,
    options: ImportOptions,
) -> None:
    """Compare the motor signatures of the trials in FILE_OR_DIR... (CSV, MAT, ...).

    Folders are searched recursively; files in them that are not trials are skipped with a note.
    """
    if not paths and not bundled:
        raise InputError(None, "give trial files or directories, or --bundled")
    group_files = list(GROUP_FILES) if groups_path is not None else []
    check_output_dir(out_dir, files=[REPORT, "signature.json", *FIGURES, *group_files])
    group_map = read_group_map(groups_path) if groups_path is not None else None
    trials = read_and_report(paths, group_by, options) if paths else []
    trials += load_zhai2017() if bundled else []
    if group_map is not None:  # before the signatures: a bad table is said at once
        people, groups = place_trials(trials, distinct_labels(trials), group_map)
    analysis = analyse_signatures(trials, level=level, rate=rate)
    identification = identify_people(analysis.emd, analysis.groups, seed=seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    numbers = analysis.to_json_dict()
    numbers["identification"] = identification.to_json_dict() if identification else None
    write_atomic_json(out_dir / "signature.json", numbers)
    pngs = _figures(analysis)
    table = compute_group_emd(analysis)
    click.echo("mean EMD between the trials of each pair of groups (diagonal: within a group)")
    click.echo(table.to_string(float_format=lambda v: f"{v:.4f}", na_rep="-"))
    for group, ellipse in analysis.ellipses.items():
        if ellipse is None:
            click.echo(
                f"note: group {group!r} has {len(analysis.members(group))} trial(s): no confidence "
                "ellipse in the similarity space (it needs 3)",
                err=True,
            )
    comparison = None
    if group_map is not None:
        if group_map.trials_as_people:
            click.echo(
                f"note: {groups_path} names trials without a person column: each is a person"
            )
        comparison = _compare_groups(trials, analysis, people, groups, group_map.order, seed)
        pngs["groups.png"] = render_png(plot_group_comparison(comparison))
        write_atomic_json(out_dir / "groups.json", comparison.to_json_dict())
    for name, png in pngs.items():
        write_atomic_bytes(out_dir / name, png)
    metadata = {"version": version("mirror-avatar"), "seed": seed, "level": level, "rate": rate}
    page = signature_page(analysis, identification, pngs, comparison, metadata)
    write_atomic_text(out_dir / REPORT, page)
    click.echo(identification.verdict() if identification else NO_IDENTIFICATION)
    click.echo(f"{len(trials)} trials in {len(analysis.group_names)} groups -> {out_dir / REPORT}")


def _figures(analysis: SignatureAnalysis) -> dict[str, bytes]:
    """Render the figures written beside ``signature.json``, file name -> PNG bytes."""
    ims, similarity, distances, strokes = FIGURES
    figures = {
        ims: plot_ims(
            dict(zip(analysis.group_names, analysis.group_ims, strict=True)), analysis.bins
        ),
        similarity: plot_people_space(analysis),
        distances: plot_emd_heatmap(analysis),
        strokes: plot_skew_kurtosis(analysis.strokes_by_group(), analysis.stroke_ellipses),
    }
    return {name: render_png(figure) for name, figure in figures.items()}


def _compare_groups(
    trials: list[Trial],
    analysis: SignatureAnalysis,
    people: list[str],
    groups: list[str],
    order: list[str],
    seed: int,
) -> GroupComparison:
    """Compare the two groups of people and print the verdict."""
    velocities = [trial_velocity(t, analysis.rate) for t in trials]
    comparison = compare_groups(
        analysis.emd, people, groups, order, seed=seed, velocities=velocities, rate=analysis.rate
    )
    for line in comparison.verdict():
        click.echo(line)
    return comparison
