"""``mirror-avatar study``: a study's results, from the lab's run folders or its BIDS export."""

from __future__ import annotations

from pathlib import Path

import click

from mirror_avatar.analysis.outcomes import read_study_outcomes
from mirror_avatar.analysis.table import (
    SURROGATES,
    TABLE_FILES,
    table_dictionary,
    write_study_table,
)
from mirror_avatar.analysis.table_sources import study_rows
from mirror_avatar.analysis.trials import study_sources
from mirror_avatar.cli.constrained import JOBS, TRIM_RANGE, ranged
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.cli.study_plan import plan
from mirror_avatar.cli.study_power import power
from mirror_avatar.cli.study_report import report
from mirror_avatar.common.errors import InputError
from mirror_avatar.metrics import TRIM
from mirror_avatar.metrics.measures import CONSTRAINTS as MEASURE_CONSTRAINTS


@click.group()
def study() -> None:
    """Gather a study's results: one table of every trial, the statistics a paper reports."""


@study.command()
@click.argument("paths", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--out", "out_dir", type=click.Path(path_type=Path), required=True,
    help="Write study.csv, study.parquet and the data dictionary study.json here.",
)  # fmt: skip
@click.option(
    "--trim", default=TRIM, show_default=True,
    **ranged("Seconds left out at the start of each trial's measures (as evaluate).", TRIM_RANGE),
)  # fmt: skip
@click.option(
    "--surrogates", default=SURROGATES, show_default=True,
    **ranged("Circular-shift surrogates per trial for the measures' p-values (0: none), drawn "
             "from each trial's recorded seed.", MEASURE_CONSTRAINTS["n_surrogates"]),
)  # fmt: skip
@click.option(
    "--jobs", default=1, show_default=True,
    **ranged("Worker processes measuring the run folders (each its own copy of the package in "
             "memory); the table is the same whatever their number.", JOBS),
)  # fmt: skip
def table(paths: tuple[Path, ...], out_dir: Path, trim: float, surrogates: int, jobs: int) -> None:
    """Write one long table of a study: a row per trial and player.

    PATHS are the lab's run folders (a study participant's OUT/<protocol>-pNNN/, a plain
    session's folder), folders holding them (the lab's --out), a BIDS dataset a lab export wrote
    or one of its sub-* folders (never its sourcedata/). Each row holds the participant, the
    player, the block, condition and trial, the condition's position in the participant's
    order, the partners and their true kind, the delay, occlusion and perturbations, every
    measure of the player's trial, and each answer with, for a person-or-computer question,
    the guess, whether it was right and its confidence; in an online study, the person's panel
    identifiers, the completion code their end page showed and their refusal (a person screened
    out before their first trial has a row of their own). The data dictionary study.json gives
    each column's description, units, levels and role (identifier, design, measure, answer).
    """
    if not trim >= 0:
        raise InputError("--trim", "must be 0 or more seconds")
    check_output_dir(out_dir, files=TABLE_FILES)
    sources = study_sources(paths)
    outcomes = read_study_outcomes(paths)
    found = study_rows(sources, trim, surrogates, outcomes, jobs)
    if not found.trials and not outcomes:
        raise InputError(paths[0], "no lab trial in it (run folders or a lab's BIDS export)")
    if found.trials and not found.measured:
        raise InputError(
            "--trim",
            f"{trim:g} s leaves no trial enough samples to measure (the longest lasts "
            f"{found.longest:.3g} s): give a shorter trim",
        )
    rows = found.table
    write_study_table(rows, table_dictionary(rows, found.questions), out_dir)
    participants = rows["participant"].nunique()
    refused = sum(len(run.refusals) for run in outcomes.values())
    screened = f", {refused} screened out" if refused else ""
    click.echo(
        f"wrote {out_dir.resolve()}: {len(rows)} rows ({found.trials} trials, "
        f"{found.incomplete} of them incomplete, {participants} "
        f"participant{'s' * (participants != 1)}{screened})"
    )


study.add_command(report)
study.add_command(power)
study.add_command(plan)
