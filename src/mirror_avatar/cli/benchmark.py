"""``mirror-avatar benchmark``: the partners from the literature follow recorded leaders."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import click
import pandas as pd
from matplotlib.figure import Figure

from mirror_avatar.atomic import json_safe, write_atomic_bytes, write_atomic_json, write_atomic_text
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.cli.reading import import_options
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.experiments.partner_benchmark import (
    HUMAN,
    MODELS,
    PUBLISHED,
    PUBLISHED_ADAPTIVE_BOUNDS,
    TRIM,
    BenchmarkResult,
    check_models,
    run_benchmark,
)
from mirror_avatar.figures import plot_positions
from mirror_avatar.importing import ImportOptions
from mirror_avatar.report import Section, render_png, render_report
from mirror_avatar.session import Session
from mirror_avatar.trial_sets import read_trial_set
from mirror_avatar.trials import DEFAULT_RATE, Trial

BUNDLED = "bundled"
"""The --leader value naming the bundled recordings (`mirror_avatar.datasets.load_zhai2017`)."""

FIGURE_SECONDS = 20.0
"""Length of each model's figure (s), from the end of the trimmed start."""


def read_leaders(paths: tuple[str, ...], options: ImportOptions) -> list[Trial]:
    """Read the trials of ``paths`` (files, folders, or ``bundled``), resampled to 100 Hz."""
    trials: list[Trial] = []
    files = [path for path in paths if path != BUNDLED]
    if BUNDLED in paths:
        trials += load_zhai2017()
    if files:
        trials += read_trial_set(files, options=options).trials
    return [trial.resampled(DEFAULT_RATE) for trial in trials]


@click.command()
@click.option(
    "--leader",
    "leader_paths",
    multiple=True,
    required=True,
    help="Recorded leaders: trial files, folders of them, or 'bundled'; repeatable.",
)
@click.option(
    "--human",
    "human_paths",
    multiple=True,
    help="Recorded human followers, one per leader trial in the same order; repeatable.",
)
@click.option(
    "--models",
    default=",".join(MODELS),
    show_default=True,
    help="Comma-separated models (a partner may carry parameters: adaptive:cp=30).",
)
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    required=True,
    help="Output folder (table.csv, results.json, report.html, PNGs).",
)
@import_options
def benchmark(
    leader_paths: tuple[str, ...],
    human_paths: tuple[str, ...],
    models: str,
    out_dir: Path,
    options: ImportOptions,
) -> None:
    """Let each model follow each recorded leader and compare them as Zhai et al.'s Table 4.

    Scores (the first second dropped): RMS and relative position error, CV, time lag and the
    EMD of the velocity distributions to the leader's, and the largest errors; Zhai et al.'s
    published relative position errors beside them.
    """
    check_output_dir(out_dir)
    names = check_models([name.strip() for name in models.split(",") if name.strip()])
    leaders = read_leaders(leader_paths, options)
    humans = read_leaders(human_paths, options) if human_paths else []
    result = run_benchmark(leaders, names, humans)
    write_benchmark(result, out_dir, {"leaders": list(leader_paths), "humans": list(human_paths)})
    table = result.summary()
    click.echo(table.to_string(float_format=lambda value: f"{value:.4f}"))
    click.echo(
        f"ranking (RPE nearest the human followers' {result.human_rpe():.4g} first): "
        f"{', '.join(result.ranking())}"
    )
    click.echo(f"wrote {out_dir.resolve()}")


def write_benchmark(result: BenchmarkResult, out_dir: Path, inputs: dict[str, Any]) -> None:
    """Write table.csv, trials.csv, results.json, one PNG per follower and report.html."""
    out_dir.mkdir(parents=True, exist_ok=True)
    table = result.summary()
    write_atomic_text(out_dir / "table.csv", table.to_csv(index_label="follower"))
    write_atomic_text(out_dir / "trials.csv", result.trials.to_csv(index=False))
    results = {
        "inputs": inputs,
        "trim_s": TRIM,
        "summary": json_safe(table.to_dict(orient="index")),
        "trials": json_safe(result.trials.to_dict(orient="records")),
        "ranking_by_rpe_nearest_human": result.ranking(),
        "published": PUBLISHED | {"adaptive_bounds": PUBLISHED_ADAPTIVE_BOUNDS},
    }
    write_atomic_json(out_dir / "results.json", results)
    for name, session in result.sessions.items():
        write_atomic_bytes(out_dir / f"{_file_name(name)}.png", render_png(_figure(name, session)))
    figures = {name: _figure(name, session) for name, session in result.sessions.items()}
    write_atomic_text(out_dir / "report.html", render_report([_section(result, figures)], TITLE))


def _figure(name: str, session: Session) -> Figure:
    """Draw the leader and the follower over `FIGURE_SECONDS` after the trimmed start."""
    kept = session.trimmed(TRIM)
    show = kept.times <= kept.times[0] + FIGURE_SECONDS
    return plot_positions(
        kept.times[show],
        {"leader": kept.positions[0][show], name: kept.positions[1][show]},
        title=f"{name} following {session.labels[0]}",
    )


TITLE = "Partners following recorded leaders"


def _file_name(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name)


def _section(result: BenchmarkResult, figures: dict[str, Figure]) -> Section:
    table = result.summary()
    scored = table[table["trials"] > 0]
    recorded = HUMAN in scored.index
    human = "the recorded human followers'" if recorded else "Zhai et al.'s human benchmark,"
    rpe = scored["rpe"].drop(index=HUMAN, errors="ignore")
    published = PUBLISHED["rpe"]
    theirs = sorted((value, name) for name, value in published.items() if name != HUMAN)
    text = [
        f"Ranking by RPE nearest {human} {result.human_rpe():.4g}: "
        + ", ".join(f"{name} {rpe[name]:.3g}" for name in result.ranking())
        + ". Smallest RPE first, ours: "
        + ", ".join(f"{name} {value:.3g}" for name, value in rpe.sort_values().items())
        + "; Zhai et al.'s: "
        + ", ".join(f"{PUBLISHED_NAMES.get(name, name)} {value:g}" for value, name in theirs)
        + f" (human {published[HUMAN]:g}).",
        "Each model follows each recorded leader (replayed as recorded); the first "
        f"{TRIM:g} s of every trial are dropped. RPE, relative position error (Zhai et al. "
        "2017): the mean over the samples of (x_leader - x_follower) sgn(v_leader) where both "
        "move the same way, else |x_leader - x_follower|; positive when the follower is behind "
        "(units). CV: phase locking of the relative phase (1 = locked). Time lag: leader ahead "
        "when positive (s). EMD: normalised earth mover's distance between the follower's and "
        "the leader's velocity distributions.",
        "Beside ours, Zhai et al.'s Table 4: five people and their four models following one "
        "prerecorded reference signal (ours follow every leader given). OPC is their "
        "optimal-control player, our vt; JKE their Jirsa-Kelso excitator. Their adaptive "
        "player kept the position error under 0.2 and the velocity error under 0.62 where the "
        "RPC reached 0.8 and 3 (our largest errors: max |e|, max |e_v|). The human row holds "
        + (
            "the recorded human followers."
            if recorded
            else "no recording of ours (none given: --human), only Zhai et al.'s values."
        ),
    ]
    captions = {f"{name} following the first leader": figure for name, figure in figures.items()}
    return Section(
        key="benchmark",
        title="Benchmark",
        text=text,
        tables={
            "Ours beside Zhai et al.'s Table 4": beside_published(table),
            "Mean over trials": _readable(scored.drop(columns=PUBLISHED_COLUMNS)),
            "Mean by leader group": _readable(result.by_group()),
            "Every trial": _readable(result.trials.set_index(["follower", "trial", "group"])),
        },
        figures=captions,
        metrics=json.loads(json.dumps(json_safe(table.to_dict(orient="index")))),
    )


PUBLISHED_NAMES = {"vt": "vt (OPC)", "excitator": "excitator (JKE)", HUMAN: "human (HP)"}
"""Zhai et al.'s names of our followers, shown beside ours."""

PUBLISHED_COLUMNS = [f"published_{key}" for key in PUBLISHED]
"""The summary's columns of Zhai et al.'s values."""


def beside_published(table: pd.DataFrame) -> pd.DataFrame:
    """RPE, CV and time lag of each follower, ours beside Zhai et al.'s, with the trial count."""
    columns = {"trials": "trials"}
    for key in PUBLISHED:
        heading = REPORT_COLUMNS[key]
        columns |= {key: f"{heading}, ours", f"published_{key}": f"{heading}, Zhai et al."}
    beside = table[list(columns)].copy()
    for key in PUBLISHED:  # as printed in the paper, not rounded to the report's digits
        beside[f"published_{key}"] = [_as_printed(value) for value in beside[f"published_{key}"]]
    beside = beside.rename(columns=columns)
    return beside.rename(index=lambda name: PUBLISHED_NAMES.get(name, name))


def _as_printed(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:g}"


REPORT_COLUMNS = {
    "rms": "RMS",
    "rpe": "RPE",
    "cv": "CV",
    "time_lag": "lag (s)",
    "emd": "EMD",
    "max_position_error": "max |e|",
    "max_velocity_error": "max |e_v|",
    "rms_velocity_error": "RMS e_v",
}
"""Column headings of the report's tables (the CSV and JSON keep the score names)."""


def _readable(table: pd.DataFrame) -> pd.DataFrame:
    return table.rename(columns=REPORT_COLUMNS)
