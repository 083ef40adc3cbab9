"""``mirror-avatar benchmark``: followers of any SPEC follow recorded leaders, beside humans.

The followers are SPECs (`mirror_avatar.specs`: partners from the literature, personal avatars,
trained policies, virtual trainers); the leaders are recorded trials (``--leader``) or the
leaders the lab's own human followers followed (``--humans``), who are then scored too and are
the reference of the default ranking (`mirror_avatar.experiments.benchmark_ranking`). Zhai et
al.'s published Table 4 is written apart from our tables
(`mirror_avatar.experiments.published_partners`).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import click
import pandas as pd
from matplotlib.figure import Figure

from mirror_avatar.cli.benchmark_humans import read_human_followers
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.cli.reading import SessionReading, import_options
from mirror_avatar.cli.trial_sets import read_trial_set
from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.experiments.benchmark_ranking import (
    HUMANS,
    NO_HUMANS_DEFAULT,
    Ranking,
    check_human_count,
    parse_criterion,
    rank,
)
from mirror_avatar.experiments.partner_benchmark import (
    HUMAN,
    MODELS,
    PUBLISHED_ADAPTIVE_BOUNDS,
    SCORES,
    TRIM,
    BenchmarkResult,
    check_followers,
    run_benchmark,
)
from mirror_avatar.experiments.published_partners import (
    CAPTION,
    CV_NOTE,
    TABLE4,
    published_table,
)
from mirror_avatar.figures.sessions import plot_positions
from mirror_avatar.files.atomic import (
    csv_text,
    json_safe,
    write_atomic_bytes,
    write_atomic_json,
    write_atomic_text,
)
from mirror_avatar.files.importing import ImportOptions
from mirror_avatar.files.trials import DEFAULT_RATE, Trial
from mirror_avatar.report import Section, render_png, render_report
from mirror_avatar.sessions.session import Session
from mirror_avatar.specs import MODEL_PARTNERS

BUNDLED = "bundled"
"""The --leader value naming the bundled recordings (`mirror_avatar.datasets.load_zhai2017`)."""

FIGURE_SECONDS = 20.0
"""Length of each follower's figure (s), from the end of the trimmed start."""

PUBLISHED_FILE = "zhai2017_table4.csv"
"""Zhai et al.'s Table 4 as published, written beside (not into) our tables."""


def read_leaders(paths: tuple[str, ...], options: ImportOptions) -> list[Trial]:
    """Read the trials of ``paths`` (files, folders, or ``bundled``), resampled to 100 Hz."""
    trials: list[Trial] = []
    files = [path for path in paths if path != BUNDLED]
    if BUNDLED in paths:
        trials += load_zhai2017()
    if files:
        trials += read_trial_set(files, options=options).trials
    return [trial.resampled(DEFAULT_RATE) for trial in trials]


_PARAMETER = re.compile(r"[A-Za-z_]\w*=")


def split_specs(values: tuple[str, ...]) -> list[str]:
    """Split ``--models`` values at commas, keeping a partner's ``key=value`` items with it.

    ``adaptive:cp=30,delta=0.2,rpc`` gives ``adaptive:cp=30,delta=0.2`` and ``rpc``: an item
    ``key=value`` after a partner spec with parameters (``NAME:...``) belongs to it.
    """
    specs: list[str] = []
    for value in values:
        for item in (part.strip() for part in value.split(",")):
            partner = specs and specs[-1].partition(":")[0] in MODEL_PARTNERS and ":" in specs[-1]
            if partner and _PARAMETER.match(item):
                specs[-1] += f",{item}"
            elif item:
                specs.append(item)
    return specs


@click.command()
@click.option(
    "--leader",
    "leader_paths",
    multiple=True,
    help="Recorded leaders: trial files, folders of them, or 'bundled'; repeatable. Not with "
    "--humans, whose recordings hold their leaders.",
)
@click.option(
    "--humans",
    "human_paths",
    multiple=True,
    help="The lab's recorded human followers: sessions of a leader and a person following "
    "(session files, lab runs, BIDS-Motion exports, folders of them; a table of the two "
    "players' positions with --columns, leader first); repeatable. The followers follow "
    "these leaders.",
)
@click.option(
    "--models",
    "model_specs",
    multiple=True,
    help="The followers: SPECs (a partner from the literature with parameters as "
    "adaptive:cp=30, a personal avatar or policy .npz, bundled:slow, vt), comma-separated or "
    f"repeated. Default: {','.join(MODELS)}.",
)
@click.option(
    "--rank-by",
    "rank_by",
    default=None,
    help=f"'{HUMANS}' (closeness to the recorded humans; default with --humans), "
    f"'{HUMANS}:MEASURE,...', or one measure nearest its ideal (default without --humans: "
    f"{NO_HUMANS_DEFAULT}). Measures: {', '.join(SCORES)}.",
)
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    required=True,
    help="Output folder (table.csv, ranking.csv, trials.csv, zhai2017_table4.csv, "
    "results.json, report.html, PNGs).",
)
@import_options
def benchmark(
    leader_paths: tuple[str, ...],
    human_paths: tuple[str, ...],
    model_specs: tuple[str, ...],
    rank_by: str | None,
    out_dir: Path,
    options: ImportOptions,
) -> None:
    """Let each follower follow each recorded leader, and rank them.

    Scores (the first second dropped): RMS and relative position error, phase locking R, time
    lag, the EMD of the velocity distributions to the leader's, the amplitude ratio and the
    velocity errors. With --humans, the lab's human followers are scored on the same leaders
    and the followers are ranked by closeness to them. Zhai et al.'s published Table 4 is
    written apart, in their own definitions.
    """
    if bool(leader_paths) == bool(human_paths):
        raise InputError(
            "--leader", "give recorded leaders (--leader) or recorded human followers "
            "(--humans, whose recordings hold their leaders), one of the two",
        )  # fmt: skip
    criterion, measures = parse_criterion(
        rank_by or _default_criterion(human_paths), bool(human_paths)
    )
    check_output_dir(out_dir)
    followers = check_followers(split_specs(model_specs) or list(MODELS))
    if human_paths:
        read = read_human_followers(human_paths, _session_reading(options))
        for note in read.notes:
            click.echo(note)
        leaders, humans = read.leaders, read.followers
        if criterion == HUMANS:
            check_human_count(len(humans))
    else:
        leaders, humans = read_leaders(leader_paths, options), []
    result = run_benchmark(leaders, followers, humans)
    ranking = rank(result, criterion, measures)
    inputs = {"leaders": list(leader_paths), "humans": list(human_paths), "followers": followers}
    write_benchmark(result, ranking, out_dir, inputs)
    click.echo(result.summary().to_string(float_format=lambda value: f"{value:.4f}"))
    click.echo(f"ranking ({ranking.describe()}): {', '.join(ranking.order())}")
    click.echo(
        f"Zhai et al.'s published Table 4, in their own definitions: {PUBLISHED_FILE} and the "
        "report, apart from ours"
    )
    click.echo(f"wrote {out_dir.resolve()}")


def _default_criterion(human_paths: tuple[str, ...]) -> str:
    return HUMANS if human_paths else NO_HUMANS_DEFAULT


def _session_reading(options: ImportOptions) -> SessionReading:
    """Return the session options of ``options`` (``--columns``, ``--resample``, ``--max-gap``)."""
    return SessionReading(options.columns, options.resample, options.max_gap)


def write_benchmark(
    result: BenchmarkResult, ranking: Ranking, out_dir: Path, inputs: dict[str, Any]
) -> None:
    """Write the tables, results.json, one PNG per follower and report.html."""
    out_dir.mkdir(parents=True, exist_ok=True)
    table = result.summary()
    write_atomic_text(out_dir / "table.csv", csv_text(table, index_label="follower"))
    write_atomic_text(out_dir / "ranking.csv", csv_text(ranking.table, index_label="follower"))
    write_atomic_text(out_dir / "trials.csv", csv_text(result.trials, index=False))
    write_atomic_text(out_dir / PUBLISHED_FILE, published_table().to_csv())
    results = {
        "inputs": inputs,
        "trim_s": TRIM,
        "summary": json_safe(table.to_dict(orient="index")),
        "trials": json_safe(result.trials.to_dict(orient="records")),
        "ranking": _ranking_record(ranking),
        "published_zhai2017": {
            "caption": CAPTION,
            "table4": TABLE4,
            "cv_note": CV_NOTE,
            "adaptive_bounds": PUBLISHED_ADAPTIVE_BOUNDS,
        },
    }
    write_atomic_json(out_dir / "results.json", results)
    figures = {name: _figure(name, session) for name, session in result.sessions.items()}
    for name, session in result.sessions.items():
        write_atomic_bytes(out_dir / f"{_file_name(name)}.png", render_png(_figure(name, session)))
    sections = [_section(result, ranking, figures), _published_section()]
    write_atomic_text(out_dir / "report.html", render_report(sections, TITLE))


def _ranking_record(ranking: Ranking) -> dict[str, Any]:
    return {
        "criterion": ranking.criterion,
        "measures": list(ranking.measures),
        "description": ranking.describe(),
        "order": ranking.order(),
        "table": json_safe(ranking.table.to_dict(orient="index")),
        "humans": json_safe(ranking.humans.to_dict(orient="index")),
    }


def _figure(name: str, session: Session) -> Figure:
    """Draw the leader and the follower over `FIGURE_SECONDS` after the trimmed start."""
    kept = session.trimmed(TRIM)
    show = kept.times <= kept.times[0] + FIGURE_SECONDS
    return plot_positions(
        kept.times[show],
        {"leader": kept.positions[0][show], name: kept.positions[1][show]},
        title=f"{name} following {session.labels[0]}",
    )


TITLE = "Followers following recorded leaders"


def _file_name(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name)


def _section(result: BenchmarkResult, ranking: Ranking, figures: dict[str, Figure]) -> Section:
    table = result.summary()
    recorded = HUMAN in table.index
    text = [
        f"Ranking, {ranking.describe()}: "
        + ", ".join(f"{name} {row['distance']:.3g}" for name, row in ranking.table.iterrows())
        + ".",
        "Each follower follows each recorded leader (replayed as recorded); the first "
        f"{TRIM:g} s of every trial are dropped. RMS: root mean square position error (units). "
        "RPE, relative position error (Zhai et al. 2017, section 6.2): the mean over the "
        "samples of (x_leader - x_follower) sgn(v_leader) where both move the same way, else "
        "|x_leader - x_follower|; positive when the follower is behind (units). R: phase "
        "locking of the relative phase, |mean exp(i dphi)| (1 = locked). Time lag: leader ahead "
        "when positive (s). EMD: normalised earth mover's distance between the follower's and "
        "the leader's velocity distributions. Amplitude: the standard deviation of the "
        "follower's positions over the leader's (1 = the leader's). Velocity errors in units/s.",
        (
            "The human row holds the lab's recorded human followers, on the same leaders."
            if recorded
            else "No human follower was recorded (--humans): there is no human row."
        ),
    ]
    captions = {f"{name} following the first leader": figure for name, figure in figures.items()}
    return Section(
        key="benchmark",
        title="Benchmark",
        text=text,
        tables={
            f"Ranking ({ranking.criterion})": _readable(ranking.table),
            "Mean over trials": _readable(table),
            "Mean by leader group": _readable(result.by_group()),
            "Every trial": _readable(result.trials.set_index(["follower", "trial", "group"])),
        }
        | (
            {"The human followers' mean and spread": _readable(ranking.humans)}
            if not ranking.humans.empty
            else {}
        ),
        figures=captions,
        metrics=json.loads(json.dumps(json_safe(table.to_dict(orient="index")))),
    )


def _published_section() -> Section:
    """Zhai et al.'s Table 4 in a section of its own, in their definitions."""
    return Section(
        key="published_zhai2017",
        title="Published: Zhai et al. (2017), Table 4 (theirs, not ours)",
        text=[
            CV_NOTE,
            "Their adaptive player kept the position error under "
            f"{PUBLISHED_ADAPTIVE_BOUNDS['position']:g} units and the velocity error under "
            f"{PUBLISHED_ADAPTIVE_BOUNDS['velocity']:g} units/s where the RPC reached 0.8 and 3.",
        ],
        tables={CAPTION: published_table().map(_as_printed)},
        metrics={"table4": TABLE4},
    )


def _as_printed(value: Any) -> str:
    """Show a value of Table 4 with the paper's four decimals."""
    return f"{value:.4f}" if isinstance(value, float) else str(value)


REPORT_COLUMNS = {
    "rms": "RMS",
    "rpe": "RPE",
    "phase_locking": "R",
    "time_lag": "lag (s)",
    "emd": "EMD",
    "amplitude_ratio": "amplitude",
    "max_position_error": "max |e|",
    "max_velocity_error": "max |e_v|",
    "rms_velocity_error": "RMS e_v",
}
"""Column headings of the report's tables (the CSV and JSON keep the score names)."""


def _readable(table: pd.DataFrame) -> pd.DataFrame:
    z = {f"z_{key}": f"z {heading}" for key, heading in REPORT_COLUMNS.items()}
    return table.rename(columns=REPORT_COLUMNS | z)
