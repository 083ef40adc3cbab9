"""``mirror-avatar reproduce``: run every experiment and write the HTML report."""

from __future__ import annotations

import shlex
import time
from datetime import UTC, datetime
from importlib.metadata import version
from pathlib import Path

import click

from mirror_avatar.cli.cluster import scheduler_option
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.cli.reading import group_option, import_options, read_and_report
from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.experiments import AGENT_EXPERIMENTS, EXPERIMENTS, SWEEPS
from mirror_avatar.experiments.verdicts import describe_mode, section_verdict
from mirror_avatar.files.importing import ImportOptions
from mirror_avatar.learning.acceleration_player import Agent
from mirror_avatar.report import REPORT_FILES, write_report
from mirror_avatar.training.agents import AGENTS


@click.command()
@click.option(
    "--out",
    "out_dir",
    required=True,
    type=click.Path(path_type=Path),
    help="Directory for report.html and metrics.json.",
)
@click.option("--quick", is_flag=True, help="Smaller runs, for a check in a few minutes.")
@click.option(
    "--full",
    is_flag=True,
    help=f"Also run the long sweeps ({', '.join(sorted(SWEEPS))}) at full size: tens of "
    "minutes more.",
)
@click.option(
    "--seed",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="Seed of every random choice, recorded in metrics.json.",
)
@click.option(
    "--data",
    "data",
    multiple=True,
    type=click.Path(path_type=Path),
    help="Trial file or directory to use instead of the bundled data (repeatable).",
)
@click.option(
    "--agent",
    type=click.Choice(AGENTS),
    default="tabular",
    show_default=True,
    help="The cyber players of the dyad and group experiments: the paper's Q-table or a DQN.",
)
@scheduler_option("training sessions")
@group_option()
@import_options
def reproduce(
    out_dir: Path,
    quick: bool,
    full: bool,
    seed: int,
    data: tuple[Path, ...],
    agent: Agent,
    scheduler: str | None,
    group_by: str,
    options: ImportOptions,
) -> None:
    """Run the paper's validations on the bundled (or given) data and write the report.

    Trials given with --data are grouped by --group-by (default: the folder they are in). The
    long sweeps run at their quick size unless --full is given.
    """
    if quick and full:
        raise InputError("--full", "give --quick or --full, not both")
    check_output_dir(out_dir, files=REPORT_FILES)
    trials = read_and_report(data, group_by, options) if data else load_zhai2017()
    started = time.perf_counter()
    sections, timings = [], {}
    for number, (name, run) in enumerate(EXPERIMENTS, start=1):
        click.echo(f"reproduce: {name} ({number}/{len(EXPERIMENTS)}) ...", err=True)
        begun = time.perf_counter()
        choice = {"agent": agent, "scheduler": scheduler} if name in AGENT_EXPERIMENTS else {}
        small = quick or (name in SWEEPS and not full)
        section = run(trials, quick=small, seed=seed, **choice)
        section.verdict = section.verdict or section_verdict(name, section.metrics)
        sections.append(section)
        timings[name] = round(time.perf_counter() - begun, 3)
        click.echo(f"reproduce: {name} done in {timings[name]:.0f} s", err=True)
    mode = describe_mode(quick, full, agent)
    metadata = {
        "version": version("mirror-avatar"),
        "command": _command_line(out_dir, quick, full, seed, data, agent),
        "mode": mode,
        "seed": seed,
        "agent": agent,
        "quick": quick,
        "sweeps": "full" if full else "quick",
        "data": [str(path) for path in data] or "bundled zhai2017",
        "n_trials": len(trials),
        "date": datetime.now(UTC).isoformat(timespec="seconds"),
        "wall_time_s": round(time.perf_counter() - started, 3),
        "experiment_time_s": timings,
    }
    path = write_report(
        sections,
        out_dir,
        title="mirror-avatar: reproduction report",
        metadata=metadata,
        lead=mode,
        json_only=("mode", "quick", "sweeps"),
    )
    click.echo(str(path))


def _command_line(
    out_dir: Path, quick: bool, full: bool, seed: int, data: tuple[Path, ...], agent: str
) -> str:
    words = ["mirror-avatar", "reproduce", "--out", str(out_dir), "--seed", str(seed)]
    words += ["--quick"] * quick + ["--full"] * full + ["--agent", agent] * (agent != "tabular")
    for path in data:
        words += ["--data", str(path)]
    return shlex.join(words)
