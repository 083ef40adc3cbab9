"""What ``mirror-avatar evaluate --out`` writes: the table of sessions, the metrics and the report.

``sessions.csv`` and ``metrics.json`` keep the measures' raw keys; ``report.html`` leads with
its verdict (is each session coordinated beyond chance) and names every column in words with
its unit, from `mirror_avatar.metrics.registry`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from mirror_avatar.cli.reading import session_note
from mirror_avatar.cli.trial_sets import common_root
from mirror_avatar.figures.learning import plot_progress
from mirror_avatar.figures.sessions import plot_session
from mirror_avatar.files.atomic import csv_text, write_atomic_files
from mirror_avatar.metrics import registry
from mirror_avatar.metrics.measures import Measures
from mirror_avatar.report import Section, report_texts
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.permutations import p_text

ALPHA = 0.05
"""A session whose deciding measure has a p-value below this beats its surrogates (METHODS
section 12: a p-value of 0.05 or more does not); fewer than 1 / ALPHA surrogates can never."""

BREAK = "\u200b"
"""A zero-width space: where a long session name may wrap in the report's tables."""


@dataclass
class Evaluated:
    """A session as ``evaluate`` read it, trimmed once, with its metrics and measures.

    Attributes
    ----------
    path
        The file it was read from.
    seconds
        Its duration as read, before the trim (s).
    session
        The session analysed: at the analysis rate, its first ``--trim`` seconds left out.
    metrics, measures
        Its `mirror_avatar.metrics.session_metrics` and
        `mirror_avatar.metrics.measures.session_measures`.
    """

    path: Path
    seconds: float
    session: Session
    metrics: dict[str, Any]
    measures: Measures

    @property
    def values(self) -> dict[str, Any]:
        """Every metric and measure, as ``metrics.json`` holds them."""
        return self.metrics | self.measures.values


def session_names(paths: list[Path]) -> list[str]:
    """Name sessions by their paths below the folder they share (one file: its name).

    Never by the file name alone: ``p1/session.parquet`` and ``p2/session.parquet`` stay apart.
    """
    root = common_root(paths)
    return [Path(os.path.abspath(path)).relative_to(root).as_posix() for path in paths]


def summary_row(found: Evaluated) -> dict[str, Any]:
    """One row of ``sessions.csv``: the file, its players, the headline metrics, every measure.

    A cyber player's ``emd_target_<i>`` (its IMS against its target's) gets a column too;
    the measures that fit a cell follow (numbers, the leader).
    """
    metrics = found.metrics
    row: dict[str, Any] = {"session": str(found.path), "players": found.session.n_players,
                           "seconds": round(found.seconds, 3)}  # fmt: skip
    targets = {key: value for key, value in metrics.items() if key.startswith("emd_target_")}
    headline = {key: metrics[key] for key in registry.HEADLINE if key in metrics}
    return row | headline | targets | scalar_measures(found.measures.values)


def scalar_measures(values: dict[str, Any]) -> dict[str, Any]:
    """Keep the measures that fit a table cell (numbers, the leader), for the table of sessions."""
    return {k: v for k, v in values.items() if isinstance(v, int | float | str)}


def _rank(key: str) -> tuple[int, str]:
    """Order keys as the registry orders their measures (unknown keys last)."""
    found = registry.find(key)
    rank = len(registry.MEASURES) if found is None else registry.MEASURES.index(found[0])
    return rank, key


def deciding_measure(values: dict[str, Any]) -> str | None:
    """Return the key of the measure that decides a session's verdict, or None if none can.

    The first headline measure tested against surrogates that has a p-value (a pair's CV, a
    group's synchronisation).
    """
    present = (key for key in registry.HEADLINE if key in values)
    tested = (key for key in present if registry.measure(key).greater is not None)
    return next((key for key in tested if registry.p_value_key(key) in values), None)


def _surrogates(values: dict[str, Any]) -> tuple[int, str]:
    """Return how many surrogates a session drew, and their kind."""
    drawn = values.get("surrogates", {})
    return int(drawn.get("n", 0)), str(drawn.get("kind", ""))


def _too_few(n: int) -> bool:
    """Whether ``n`` surrogates cannot give a p-value below `ALPHA` (the smallest: 1/(n+1))."""
    return 1.0 / (n + 1) >= ALPHA


def session_verdict(values: dict[str, Any]) -> str:
    """Say in words whether a session is coordinated beyond chance."""
    key = deciding_measure(values)
    if key is None or not math.isfinite(values[registry.p_value_key(key)]):
        return "not tested"
    if _too_few(_surrogates(values)[0]):
        return "too few surrogates"
    p = values[registry.p_value_key(key)]
    return "coordinated beyond chance" if p < ALPHA else "not beyond chance"


def verdict(results: list[Evaluated]) -> str:
    """Write the report's first line: how many sessions beat their surrogates, and which."""
    names = session_names([found.path for found in results])
    verdicts = [session_verdict(found.values) for found in results]
    beyond = [n for n, v in zip(names, verdicts, strict=True) if v == "coordinated beyond chance"]
    tested = [v for v in verdicts if v != "not tested"]
    n, kind = max(_surrogates(found.values) for found in results)
    if not tested or n == 0:
        return (f"No verdict on chance: no session of {len(results)} was tested against "
                "surrogates (none drawn, too short, or players that do not move).")  # fmt: skip
    if _too_few(n):
        return (f"No verdict on chance: {n} surrogates cannot give a p-value below {ALPHA:g} "
                f"(the smallest is 1/{n + 1} = {1 / (n + 1):.3g}); run with "
                "--surrogates 99.")  # fmt: skip
    deciding = {key for found in results if (key := deciding_measure(found.values))}
    measures = " or ".join(registry.label(key) for key in sorted(deciding))
    against = f"{measures}, p < {ALPHA:g} against {n} {kind} surrogates"
    if len(results) == 1:
        values = results[0].values
        key = deciding_measure(values)
        assert key is not None
        p = p_text(values[registry.p_value_key(key)], n)
        return (f"{names[0]}: {verdicts[0]} ({registry.label(key)} {values[key]:.2f}, {p} "
                f"against {n} {kind} surrogates).")  # fmt: skip
    if not beyond:
        return f"None of the {len(tested)} sessions tested beats chance ({against})."
    shown = ", ".join(beyond[:5]) + (", ..." if len(beyond) > 5 else "")
    return (f"{len(beyond)} of the {len(tested)} sessions tested are coordinated beyond chance "
            f"({against}): {shown}.")  # fmt: skip


def _cell(key: str, values: dict[str, Any], n: int, labels: Sequence[str]) -> str:
    """Write one measure of one session for the report, with its p-value when tested.

    The leader is named by its label as well as its index (``labels``: the players').
    """
    value = values.get(key)
    if value is None:
        return "-"
    if key == "leader" and isinstance(value, int):
        named = f"player {value}"
        return named if labels[value] == named else f"{named} ({labels[value]})"
    if isinstance(value, float) and not math.isfinite(value):
        return registry.measure(key).missing
    shown = f"{value:.3g}" if isinstance(value, float) else str(value)
    p = values.get(registry.p_value_key(key))
    return shown if p is None else f"{shown} ({p_text(p, n)})"


def _wrappable(name: str) -> str:
    return name.replace("/", "/" + BREAK).replace("_", "_" + BREAK)


def glance_tables(results: list[Evaluated]) -> dict[str, pd.DataFrame]:
    """Each session at a glance, in words: verdict, length and headline metrics.

    One table per number of players (caption -> table), so that a pair's columns and a group's
    do not make one table too wide to read.
    """
    names = session_names([found.path for found in results])
    rows: dict[int, list[dict[str, Any]]] = {}
    for number, (name, found) in enumerate(zip(names, results, strict=True), start=1):
        values = found.values
        n = _surrogates(values)[0]
        row = {"": f"{number}: {_wrappable(name)}", "verdict": session_verdict(values),
               "length (s)": f"{found.seconds:.1f}"}  # fmt: skip
        shown = [key for key in registry.HEADLINE if key in found.metrics]
        labels = found.session.labels
        row |= {registry.heading(key): _cell(key, values, n, labels) for key in shown}
        rows.setdefault(found.session.n_players, []).append(row)
    return {_players(size): _table(rows[size]) for size in sorted(rows)}


def _players(size: int) -> str:
    return {1: "One player", 2: "Pairs"}.get(size, f"Groups of {size}")


def _table(rows: list[dict[str, Any]]) -> pd.DataFrame:
    """Make a table of rows whose first cell names the row; its corner says ``session``."""
    table = pd.DataFrame(rows).set_index("").fillna("-")
    table.index.name = None
    table.columns.name = "session"
    return table


def measures_table(results: list[Evaluated]) -> pd.DataFrame:
    """Every measure of every session, in words with units.

    A row per measure (in the registry's order), the figure of each session that draws it, and
    a column per session (numbered as in `glance_tables`); a tested measure's cell holds its
    p-value too.
    """
    columns, keys = {}, []
    for number, found in enumerate(results, start=1):
        values = found.values
        n = _surrogates(values)[0]
        shown = [k for k in scalar_measures(values) if registry.find(k) is not None]
        keys += shown
        labels = found.session.labels
        columns[str(number)] = {key: _cell(key, values, n, labels) for key in shown}
    order = sorted(set(keys), key=_rank)
    table = pd.DataFrame(columns).reindex(order).fillna("-")
    table.insert(0, "figure", [registry.measure(key).figure or "-" for key in order])
    table.index = pd.Index([registry.heading(key) for key in order])
    table.columns.name = "measure / session"
    return table


def progress_section(table: pd.DataFrame, order: str) -> Section:
    """Make the report section of a `progress_table`: the table and two figures.

    ``order`` says how the sessions were ordered.
    """
    return Section(
        key="progress",
        title="Progress of player 0 across the sessions",
        text=[f"Sessions {order}. EMD to first session: how far player 0's velocity "
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
    out_dir: Path, results: list[Evaluated], rows: pd.DataFrame, trim: float,
    extra: list[Section] | None = None,
) -> None:  # fmt: skip
    """Write the table (CSV), every session's metrics (JSON) and an HTML page with figures.

    The page leads with the `verdict` and shows `glance_tables` and `measures_table`; the CSV
    and JSON keep the raw keys. A session read with --columns or --resample says so
    (`session_note`). The three files are rendered first, then written together
    (`mirror_avatar.files.atomic.write_atomic_files`): a failure leaves none of them changed.
    """
    names = session_names([found.path for found in results])
    read = [note for found in results if (note := session_note(found.path, found.session))]
    figures = {
        f"{shown}: {name.replace('_', ' ')}": figure
        for shown, found in zip(names, results, strict=True)
        for name, figure in plot_session(found.session).items()
    }
    section = Section(
        key="sessions",
        title=f"{len(results)} session(s)",
        text=[f"Metrics leave out the first {trim:g} s of each session. A session is "
              f"coordinated beyond chance when its CV (a group: its synchronisation) beats "
              f"its surrogates at p < {ALPHA:g}. The same numbers, under their raw names, are "
              "in sessions.csv and metrics.json.", *read],  # fmt: skip
        tables=glance_tables(results)
        | {"Every measure (columns: the sessions numbered above)": measures_table(results)},
        figures=figures,
        metrics={"trim": trim} | {str(found.path): found.values for found in results},
    )  # fmt: skip
    texts = report_texts(
        [section, *(extra or [])], title="mirror-avatar: sessions evaluated", lead=verdict(results)
    )
    out_dir.mkdir(parents=True, exist_ok=True)
    write_atomic_files(out_dir, {"sessions.csv": csv_text(rows, index=False)} | texts)
