"""``mirror-avatar evaluate``: the coordination metrics of saved sessions, or folders of them."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click
import numpy as np
import pandas as pd

from mirror_avatar.cli.constrained import TRIM_RANGE, constrained_type, with_range
from mirror_avatar.cli.evaluate_report import (
    Evaluated,
    progress_section,
    session_names,
    summary_row,
    verdict,
    write_evaluation,
)
from mirror_avatar.cli.measure_figures import measures_section
from mirror_avatar.cli.measure_options import format_measures, measure_options, options_from
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.cli.reading import (
    DEFAULT_READING,
    SessionReading,
    session_note,
    session_options,
)
from mirror_avatar.cli.simulate import format_metrics
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import json_safe
from mirror_avatar.files.bids.names import MOTION_SUFFIX
from mirror_avatar.files.trial_record import trial_record
from mirror_avatar.metrics import TRIM
from mirror_avatar.metrics.analysis_rate import ANALYSIS_RATE, decimation_factor, session_rate
from mirror_avatar.metrics.jitter import JITTER_BAND
from mirror_avatar.metrics.measuring import measure_sessions
from mirror_avatar.metrics.progress import order_by_start, progress_table
from mirror_avatar.report import REPORT_FILES
from mirror_avatar.sessions.session import Session

SESSION_FILES = (".csv", ".parquet")

MAX_MAGNITUDE = 1e100
"""Largest position (units) or velocity (units/s) a session may hold: the measures square and
sum them, and float64 ends at 1.8e308."""


def find_sessions(
    paths: tuple[Path, ...], reading: SessionReading = DEFAULT_READING
) -> tuple[list[tuple[Path, Session]], list[str]]:
    """Read the sessions among ``paths`` (files, or folders searched recursively).

    Folders are searched for session files and BIDS-Motion recordings (`session_files`): a BIDS
    dataset or one of its subject folders is read from its ``_motion.tsv`` files, a lab
    export's trial once whichever of its people's recordings holds it. In folders, files that
    are not sessions (solo trials, other tables) are skipped with a note; a file named
    explicitly must be a session. Files read with ``reading``'s column map or resampling get
    a note saying so (`session_note`).
    """
    found, notes = [], []
    for path in paths:
        if not path.is_dir():
            found.append((path, reading.load(path)))
            notes += [note] if (note := session_note(path, found[-1][1])) else []
            continue
        before, refused = len(found), []
        trials: dict[tuple[str, int], Path] = {}
        for file in session_files(path):
            if file.suffix.lower() == ".csv" and file.with_suffix(".parquet").is_file():
                notes.append(f"skipped {file}: the same session as {file.with_suffix('.parquet')}")
                continue
            try:
                session = reading.load(file)
                notes += [note] if (note := session_note(file, session)) else []
            except InputError as error:
                notes.append(f"skipped {file}: {error.problem}")
                refused.append(f"{file.relative_to(path)}: {error.problem}")
                continue
            trial = _exported_trial(session)
            if trial in trials:
                notes.append(f"skipped {file}: the same lab trial as {trials[trial]}")
                continue
            if trial is not None:
                trials[trial] = file
            found.append((file, session))
        if len(found) == before:
            raise InputError(path, _no_sessions(refused))
    return found, notes


def _no_sessions(refused: list[str], shown: int = 3) -> str:
    """Say why a folder gave no session: it has no session files, or each was refused (why)."""
    if not refused:
        return (
            "no session files in it (time, position_0, ... columns, or BIDS-Motion "
            "_motion.tsv files; sourcedata/ is read only when named)"
        )
    more = f"; and {len(refused) - shown} more" if len(refused) > shown else ""
    files = "file was" if len(refused) == 1 else f"{len(refused)} files were"
    return f"no session read: its {files} refused ({'; '.join(refused[:shown])}{more})"


def check_session(path: Path, session: Session, trim: float) -> str | None:
    """Check a session's magnitudes and trim; note the rate it is analysed at, if not its own.

    Raises
    ------
    InputError
        A position or velocity beyond `MAX_MAGNITUDE`, or a ``trim`` (s) that leaves fewer
        than two samples, naming the file.
    """
    if np.count_nonzero(session.times >= session.times[0] + trim) < 2:
        raise InputError(
            path, f"--trim {trim:g} s leaves fewer than two samples of its {session.duration:g} s"
        )
    for name, channel in (("positions", session.positions), ("velocities", session.velocities)):
        largest = float(np.max(np.abs(channel)))
        if largest > MAX_MAGNITUDE:
            raise InputError(
                path, f"{name} reach {largest:g}, beyond the {MAX_MAGNITUDE:g} the measures can "
                "square and sum: give the file in smaller units"
            )  # fmt: skip
    rate = session_rate(session)
    q = decimation_factor(rate)
    _check_rate(path, session, rate / q)
    if q == 1:
        return None
    return (
        f"{path}: sampled at {rate:g} Hz, analysed at {rate / q:g} Hz (every {q}th sample after "
        f"an anti-aliasing filter; the measures need at most {ANALYSIS_RATE:g} Hz)"
    )


def _check_rate(path: Path, session: Session, rate: float) -> None:
    """Refuse a session analysed at a rate (Hz) too low for the jitter band (and co-confidence)."""
    lowest = 2 * JITTER_BAND[1]
    if rate > lowest * (1 + 1e-6):  # a grid's mean rate is not exact
        return
    low, high = JITTER_BAND
    need = f"the measures need more than {lowest:g} Hz (the jitter band, {low:g}-{high:g} Hz)"
    if "import" in session.metadata and "resample" in session.metadata["import"]:
        raise InputError(path, f"--resample {rate:g} Hz is too slow: {need}")
    raise InputError(path, f"sampled at {rate:g} Hz: {need}; it cannot be measured")


def session_files(folder: Path) -> list[Path]:
    """List a folder's session files and BIDS-Motion recordings, sorted, outside ``sourcedata/``.

    A BIDS dataset's ``sourcedata/`` (the lab's own trial files, copied by the export) is read
    only when named: ``evaluate bids/sourcedata``.
    """
    return sorted(
        p
        for p in folder.rglob("*")
        if (p.suffix.lower() in SESSION_FILES or p.name.endswith(MOTION_SUFFIX))
        and "sourcedata" not in p.relative_to(folder).parts[:-1]
    )


def _exported_trial(session: Session) -> tuple[str, int] | None:
    """Return the session id and trial of a lab export's recording (its record), else None."""
    if "bids" not in session.metadata or "lab" not in session.metadata:
        return None
    record = trial_record(session.metadata, session.metadata["bids"]["path"])
    return record.session_id, record.trial


@click.command()
@click.argument("paths", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--trim", type=constrained_type(TRIM_RANGE), default=TRIM, show_default=True,
    help=with_range("Seconds left out of the metrics.", TRIM_RANGE),
)  # fmt: skip
@click.option(
    "--json", "as_json", is_flag=True, help="Print the metrics as JSON (one object per file)."
)
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    default=None,
    help="Also write sessions.csv, report.html (with figures) and metrics.json here, all "
    "together: if one cannot be written, none is.",
)
@click.option(
    "--progress",
    is_flag=True,
    help="Also follow player 0 through the sessions in the order they were played (by the start "
    "time each recorded; in the order given when one has none, which the output says): drift "
    "of their IMS from the first session, EMD to the partner, CV and RMS.",
)
@session_options
@measure_options
def evaluate(
    paths: tuple[Path, ...], trim: float, as_json: bool, out_dir: Path | None, progress: bool,
    reading: SessionReading, **measure_kwargs: Any,
) -> None:  # fmt: skip
    """Print the coordination metrics of saved sessions (.parquet or .csv, or folders of them).

    Any session the toolkit writes (simulations, groups, live trials) or a plain CSV with
    ``time, position_0, position_1, ...``; a BIDS-Motion dataset or subject folder from its
    _motion.tsv files (a lab export's trial once; another tool's recording as one player per
    tracked point with a POS channel; sourcedata/ only when named). Other columns are named
    with --columns (labels from the names), irregular recordings put on a uniform grid with
    --resample. For two players, relative phase and time lag are player 0 minus player 1
    (positive when player 0 is ahead); for a group, its synchronisation and each player
    against the mean of its neighbours. Several sessions give one table.
    The field's measures (co-confidence, jitter, synchrony episodes, leadership, transfer
    entropy) follow, each coordination measure with a p-value against surrogates. Sessions
    sampled faster than 100 Hz are analysed at 100 Hz (or the rate below it that a whole
    factor gives), after an anti-aliasing filter.
    """
    options = options_from(measure_kwargs)
    if out_dir is not None:
        check_output_dir(out_dir, files=["sessions.csv", *REPORT_FILES])
    found_sessions, notes = find_sessions(paths, reading)
    for path, session in found_sessions:
        notes += [note] if (note := check_session(path, session, trim)) else []
    for note in notes:
        click.echo(note)
    measured, weak_null = measure_sessions(
        [session for _, session in found_sessions], options, trim
    )
    results = [
        Evaluated(path, session.duration, m.session, m.metrics, m.measures)
        for (path, session), m in zip(found_sessions, measured, strict=True)
    ]
    measures = [m.measures for m in measured]
    for found in results:
        for note in found.measures.notes:
            click.echo(f"{found.path}: {note}")
    rows = pd.DataFrame([summary_row(found) for found in results])
    if as_json:
        one = len(results) == 1
        shown = results[0].values if one else {str(f.path): f.values for f in results}
        click.echo(json.dumps(json_safe(shown), indent=2))
    elif len(results) == 1:
        click.echo(format_metrics(results[0].values))
        if text := format_measures(measures[0].values, options):
            click.echo(text)
    else:
        click.echo(rows.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    if weak_null is not None:
        click.echo(f"weak-null test of synchrony over the sessions: {weak_null}")
    if not as_json:
        click.echo(verdict(results))
    extra = []
    if progress:
        ordered, untimed = order_by_start([(found, found.session) for found in results])
        order = _order_note([found.path for found in untimed])
        names = session_names([found.path for found, _ in ordered])
        played = [(name, found.session) for name, (found, _) in zip(names, ordered, strict=True)]
        table = progress_table(played, 0.0, metrics=[found.metrics for found, _ in ordered])
        click.echo(f"progress of player 0 across the sessions ({order}):")
        click.echo(table.to_string(float_format=lambda v: f"{v:.4f}"))
        extra.append(progress_section(table, order))
    if out_dir is not None:
        sessions = [(found.path, found.session) for found in results]
        extra.append(measures_section(sessions, measures, weak_null, options))
        write_evaluation(out_dir, results, rows, trim, extra)
        click.echo(f"wrote {out_dir.resolve()}")


def _order_note(untimed: list[Path]) -> str:
    """Say how the sessions were ordered (`order_by_start`'s ``untimed``)."""
    if not untimed:
        return "ordered by the start time each recorded"
    shown = ", ".join(path.name for path in untimed[:3]) + (", ..." if len(untimed) > 3 else "")
    return f"in the order given: {len(untimed)} record no start time ({shown})"
