"""``mirror-avatar study report``: the statistics a paper reports, from a study table."""

from __future__ import annotations

from pathlib import Path

import click

from mirror_avatar.analysis.plan import read_plan
from mirror_avatar.analysis.statistics import BOOTSTRAP_RESAMPLES, RESAMPLES
from mirror_avatar.analysis.study_file import read_study_table
from mirror_avatar.analysis.study_report import (
    STUDY_REPORT_FILES,
    analyse_study,
    plan_lines,
    write_study_report,
)
from mirror_avatar.cli.constrained import SEED, ranged
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.lab.design.protocol import load_protocol


@click.command()
@click.argument("table", type=click.Path(path_type=Path))
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    required=True,
    help="Folder for report.html, results.json, conditions.csv and contrasts.csv.",
)
@click.option(
    "--seed", default=0, show_default=True, **ranged("Seed of the bootstrap's resamples.", SEED)
)
@click.option(
    "--reference",
    default=None,
    help="The condition every other is compared with [default: the first condition].",
)
@click.option(
    "--resamples",
    default=BOOTSTRAP_RESAMPLES,
    show_default=True,
    **ranged("Bootstrap resamples of the participants' means.", RESAMPLES),
)
@click.option(
    "--protocol",
    "protocol_file",
    type=click.Path(path_type=Path),
    default=None,
    help="The study's protocol: its conditions' order and its [analysis], the hypothesis tested "
    "first [default: none; every comparison exploratory].",
)
@click.option(
    "--plan",
    "plan_file",
    type=click.Path(path_type=Path),
    default=None,
    help="The registered plan (plan.json `study plan` wrote): the report says where the "
    "analysis it runs differs from it [default: none].",
)
def report(
    table: Path,
    out_dir: Path,
    seed: int,
    reference: str | None,
    resamples: int,
    protocol_file: Path | None,
    plan_file: Path | None,
) -> None:
    """Statistics of a study table (a folder holding study.csv, or the table itself).

    With --protocol, the protocol's declared hypothesis ([analysis]) is tested first: a paired
    t-test of the participants' means of each primary measure, one-sided as declared, against
    the smallest effect of interest; every other comparison is exploratory, its p-value adjusted
    by Benjamini-Hochberg across measures. Per condition and measure (and each answer given as
    a number, a rating), the mean over
    participants with a 95 % bootstrap CI; each condition against the reference within
    participants (linear mixed model, random intercept per participant, the condition's
    position in the order as a covariate) with effect sizes and paired tests; the "person or
    avatar?" answers against chance, with d', criterion and confidence. Writes an HTML report
    with a line per comparison in plain words and a methods paragraph to cite, and
    results.json with every number. With --plan, the primary measures, direction, contrast,
    smallest effect, alpha and models run are checked against the registered plan, and every
    difference is said in the report and on stderr.
    """
    check_output_dir(out_dir, files=STUDY_REPORT_FILES)
    protocol = None if protocol_file is None else load_protocol(protocol_file)
    plan = None if plan_file is None else read_plan(plan_file)
    analysis = analyse_study(read_study_table(table), seed=seed, reference=reference,
                             resamples=resamples, protocol=protocol, plan=plan)  # fmt: skip
    for line in plan_lines(analysis.deviations):
        click.echo(line, err=True)
    click.echo(analysis.verdict())
    for line in analysis.hypothesis_sentences() + analysis.sentences():
        click.echo(f"  {line}")
    path = write_study_report(analysis, out_dir)
    click.echo(f"wrote {path.resolve()}")
