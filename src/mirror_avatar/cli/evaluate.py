"""``mirror-avatar evaluate``: the coordination metrics of saved sessions, or folders of them."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click
import pandas as pd

from mirror_avatar.atomic import json_safe, write_atomic_text
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.cli.simulate import format_metrics
from mirror_avatar.errors import InputError
from mirror_avatar.figures import plot_progress, plot_session
from mirror_avatar.lab.bids import read_bids_session
from mirror_avatar.metrics import TRIM, session_metrics
from mirror_avatar.metrics.progress import progress_table
from mirror_avatar.report import Section, write_report
from mirror_avatar.session import Session, load_session

SESSION_FILES = (".csv", ".parquet")
SUMMARY_KEYS = (
    "phase_locking", "rmse", "mean_relative_phase", "time_lag", "group_synchronisation",
    "kuramoto_order", "mean_phase_locking", "mean_rmse",
)  # fmt: skip
"""The columns of the table of several sessions (those that apply to each)."""


def find_sessions(paths: tuple[Path, ...]) -> tuple[list[tuple[Path, Session]], list[str]]:
    """Read the sessions among ``paths`` (files, or folders searched recursively).

    In folders, files that are not sessions (solo trials, other tables) are skipped with a note;
    a file named explicitly must be a session.
    """
    found, notes = [], []
    for path in paths:
        if not path.is_dir():
            found.append((path, read_session(path)))
            continue
        before = len(found)
        for file in sorted(p for p in path.rglob("*") if p.suffix.lower() in SESSION_FILES):
            if file.suffix.lower() == ".csv" and file.with_suffix(".parquet").is_file():
                notes.append(f"skipped {file}: the same session as {file.with_suffix('.parquet')}")
                continue
            try:
                found.append((file, load_session(file)))
            except InputError as error:
                notes.append(f"skipped {file}: {error.problem}")
        if len(found) == before:
            raise InputError(path, "no session files in it (time, position_0, ... columns)")
    return found, notes


def read_session(path: Path) -> Session:
    """Read one session file: a lab BIDS-Motion ``_motion.tsv``, or what `load_session` reads."""
    if path.name.endswith("_motion.tsv"):
        return read_bids_session(path)
    return load_session(path)


def summary_row(path: Path, session: Session, metrics: dict[str, Any]) -> dict[str, Any]:
    """One row of the table of sessions: the file, its players and the metrics that apply.

    A cyber player's ``emd_target_<i>`` (its IMS against its target's) gets a column too.
    """
    row: dict[str, Any] = {"session": str(path), "players": session.n_players,
                           "seconds": round(session.duration, 3)}  # fmt: skip
    targets = {key: value for key, value in metrics.items() if key.startswith("emd_target_")}
    return row | {key: metrics[key] for key in SUMMARY_KEYS if key in metrics} | targets


@click.command()
@click.argument("paths", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--trim", type=float, default=TRIM, show_default=True, help="Seconds left out of the metrics."
)
@click.option(
    "--json", "as_json", is_flag=True, help="Print the metrics as JSON (one object per file)."
)
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    default=None,
    help="Also write sessions.csv, report.html (with figures) and metrics.json here.",
)
@click.option(
    "--progress",
    is_flag=True,
    help="Also follow player 0 through the sessions in the order given (folders: by file "
    "name, which for live trials is by time): drift of their IMS from the first session, EMD "
    "to the partner, CV and RMS.",
)
def evaluate(
    paths: tuple[Path, ...], trim: float, as_json: bool, out_dir: Path | None, progress: bool
) -> None:
    """Print the coordination metrics of saved sessions (.parquet or .csv, or folders of them).

    Any session the toolkit writes (simulations, groups, live trials) or a plain CSV with
    ``time, position_0, position_1, ...``. For two players, relative phase and time lag are
    player 0 minus player 1 (positive when player 0 is ahead); for a group, its synchronisation
    and each player against the mean of its neighbours. Several sessions give one table.
    """
    if out_dir is not None:
        check_output_dir(out_dir)
    sessions, notes = find_sessions(paths)
    for note in notes:
        click.echo(note)
    results = [(path, session, session_metrics(session, trim=trim)) for path, session in sessions]
    rows = pd.DataFrame([summary_row(path, s, m) for path, s, m in results])
    if as_json:
        shown = results[0][2] if len(results) == 1 else {str(p): m for p, _, m in results}
        click.echo(json.dumps(json_safe(shown), indent=2))
    elif len(results) == 1:
        click.echo(format_metrics(results[0][2]))
    else:
        click.echo(rows.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    extra = []
    if progress:
        names = [f"{path.parent.name}/{path.name}" for path, _, _ in results]
        table = progress_table([(n, s) for n, (_, s, _) in zip(names, results, strict=True)], trim)
        click.echo("progress of player 0 across the sessions:")
        click.echo(table.to_string(float_format=lambda v: f"{v:.4f}"))
        extra.append(progress_section(table))
    if out_dir is not None:
        write_evaluation(out_dir, results, rows, trim, extra)
        click.echo(f"wrote {out_dir.resolve()}")


def progress_section(table: pd.DataFrame) -> Section:
    """Make the report section of a `progress_table`: the table and two figures."""
    return Section(
        key="progress",
        title="Progress of player 0 across the sessions",
        text=["Sessions in the order given. EMD to first session: how far player 0's velocity "
              "IMS has moved from their first session's; CV and RMS: their coordination."],
        tables={"Per session": table},
        figures={
            "Player 0's IMS against their first session's, and against the partner's": (
                plot_progress(table, ["EMD to first session", "EMD to partner"], "Motion")
            ),
            "Coordination (CV 0-1, RMS in units)": (
                plot_progress(table, ["CV", "RMS"], "Coordination")
            ),
        },
        metrics={"progress": table.reset_index().to_dict(orient="records")},
    )  # fmt: skip


def write_evaluation(
    out_dir: Path, results: list[tuple[Path, Session, dict[str, Any]]], rows: pd.DataFrame,
    trim: float, extra: list[Section] | None = None,
) -> None:  # fmt: skip
    """Write the table (CSV), every session's metrics (JSON) and an HTML page with figures."""
    out_dir.mkdir(parents=True, exist_ok=True)
    write_atomic_text(out_dir / "sessions.csv", rows.to_csv(index=False))
    figures = {
        f"{path.name}: {name.replace('_', ' ')}": figure
        for path, session, _ in results
        for name, figure in plot_session(session, trim).items()
    }
    section = Section(
        key="sessions",
        title=f"{len(results)} session(s)",
        text=[f"Metrics leave out the first {trim:g} s of each session."],
        tables={"Sessions": rows.set_index("session")},
        figures=figures,
        metrics={"trim": trim} | {str(path): metrics for path, _, metrics in results},
    )
    write_report([section, *(extra or [])], out_dir, title="mirror-avatar: sessions evaluated")
