"""Figures of the field's measures (`mirror_avatar.metrics.measures`), one function per figure.

A session's timeline with its co-confidence segments shaded, leadership over time, and each
tested measure against its surrogate distribution. Like `mirror_avatar.figures`, each function
builds a `matplotlib.figure.Figure` on the Agg canvas and never touches pyplot's state.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from textwrap import fill

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from mirror_avatar.metrics import registry
from mirror_avatar.metrics.measures import MeasureOptions, Measures
from mirror_avatar.metrics.surrogates import WeakNull
from mirror_avatar.report import Section
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.permutations import p_text

WIDE = (7.2, 4.8)


def _figure(size: tuple[float, float] = WIDE) -> Figure:
    figure = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def plot_timeline(session: Session, measures: Measures) -> Figure:
    """Positions of a pair over time with its CC segments shaded, and each player's jitter index.

    Parameters
    ----------
    session
        The session the measures were computed on (already trimmed), two players.
    measures
        Its `session_measures` (``details``: ``co_confidence`` and ``jitter``).
    """
    figure = _figure()
    top, bottom = figure.subplots(2, 1, sharex=True, height_ratios=(2, 1))
    t, start = session.times, measures.details["start"]
    for k, x in enumerate(session.positions):
        top.plot(t, x, color=f"C{k}", lw=1.0, label=f"{k}: {session.labels[k]}")
    cc = measures.details.get("co_confidence")
    for segment in () if cc is None else cc.segments:
        for axes in (top, bottom):
            axes.axvspan(start + segment.start, start + segment.end, color="0.85", lw=0)
    for k, index in enumerate(measures.details["jitter"]):
        bottom.plot(t, index, color=f"C{k}", lw=0.8)
    rate = measures.values.get("co_confidence_rate", float("nan"))
    top.set(ylabel="position (units)", title=f"Timeline: CC segments shaded (CC rate {rate:.2f})")
    top.legend(frameon=False, fontsize="small")
    bottom.set(xlabel="time (s)", ylabel="jitter index")
    return figure


def plot_leadership(measures: Measures) -> Figure:
    """Windowed lagged cross-correlation over time, with each window's picked peak.

    Colour: correlation of player 0's window with player 1's shifted by the lag (positive lag:
    player 0 leads); dots: the peak nearest lag zero (Boker et al. 2002).
    """
    lead = measures.details["leadership"]
    start = measures.details["start"]
    figure = _figure()
    axes = figure.add_subplot()
    step = lead.times[1] - lead.times[0] if lead.times.size > 1 else 1.0
    extent = (
        start + lead.times[0] - step / 2, start + lead.times[-1] + step / 2,
        lead.lags[0], lead.lags[-1],
    )  # fmt: skip
    image = axes.imshow(
        lead.correlations.T, origin="lower", aspect="auto", extent=extent, cmap="RdBu_r",
        vmin=-1, vmax=1,
    )  # fmt: skip
    axes.plot(start + lead.times, lead.peak_lags, "k.", ms=4, label="picked peak")
    axes.axhline(0.0, color="0.3", lw=0.6)
    figure.colorbar(image, ax=axes, label="correlation")
    leader = measures.values.get("leader", "none")
    axes.set(
        xlabel="time (s)", ylabel="lag (s; > 0: player 0 leads)",
        title=f"Leadership over time (session leader: {leader})",
    )  # fmt: skip
    axes.legend(frameon=False, loc="upper right")
    return figure


def plot_surrogates(measures: Measures) -> Figure:
    """Each tested measure's surrogate distribution, the observed value as a line, its p-value."""
    names = list(measures.null)
    columns = 4
    rows = max(1, -(-len(names) // columns))
    figure = _figure((9.6, 2.2 * rows))
    grid = figure.subplots(rows, columns, squeeze=False)
    for axes, name in zip(grid.ravel(), names, strict=False):
        null = measures.null[name][np.isfinite(measures.null[name])]
        axes.hist(null, bins=20, color="0.6")
        axes.axvline(measures.values[name], color="C3", lw=1.5)
        p = measures.values.get(registry.p_value_key(name), float("nan"))
        title = f"{fill(registry.label(name), 30)}\n{p_text(p, null.size)}"
        axes.set_title(title, fontsize="small")
        axes.tick_params(labelsize="x-small")
    for axes in grid.ravel()[len(names) :]:
        axes.set_axis_off()
    figure.suptitle("Measures (red) against their surrogates (grey)")
    return figure


def plot_measures(session: Session, measures: Measures) -> dict[str, Figure]:
    """Draw the figures that apply to a session.

    ``timeline`` and ``leadership`` for a pair, ``surrogates`` when surrogates were drawn.
    """
    figures = {}
    if "co_confidence" in measures.details:
        figures["timeline"] = plot_timeline(session, measures)
    if "leadership" in measures.details:
        figures["leadership"] = plot_leadership(measures)
    if measures.null:
        figures["surrogates"] = plot_surrogates(measures)
    return figures


def _surrogates_text(options: MeasureOptions) -> str:
    """Say what the p-values were tested against: how many surrogates, which seed, the floor."""
    if options.n_surrogates == 0:
        return "No surrogates were drawn (--surrogates 0): the measures have no p-values."
    return (
        f"Every coordination measure is tested against {options.n_surrogates} "
        f"{options.surrogates} surrogates (--surrogate-seed {options.seed}: session k draws "
        "from child k of it, a session that records its seed, as lab trials and simulations "
        "do, from that seed); a p-value at or above 0.05 means the measure does not beat its "
        f"surrogates, and the smallest p-value {options.n_surrogates} surrogates can give is "
        f"written {p_text(0.0, options.n_surrogates)}."
    )


def measures_section(
    sessions: Sequence[tuple[Path, Session]], measures: Sequence[Measures],
    weak_null: WeakNull | None, options: MeasureOptions,
) -> Section:  # fmt: skip
    """Make the report's section of the measures.

    What they are, the figures of each session, and the options, seeds and weak-null test in
    ``metrics.json``.
    """
    figures = {}
    for (path, session), found in zip(sessions, measures, strict=True):
        for name, figure in plot_measures(session, found).items():
            figures[f"{path.parent.name}/{path.name}: {name}"] = figure
    text = [
        "Co-confidence (CC): stretches of at least "
        f"{options.min_duration:g} s in which the players move together (relative velocity "
        f"difference below {options.dv_threshold:g}) without jitter in their velocity "
        f"difference ({registry.BAND}). Jitter index: each player's share of velocity in "
        f"{registry.BAND}. "
        "Leadership: windowed lagged cross-correlation of the velocities with peak picking "
        "(positive lag: player 0 leads). Transfer entropy between velocities, in bits.",
        _surrogates_text(options),
    ]
    if weak_null is not None:
        text.append(f"Weak-null test of synchrony over the sessions: {weak_null}.")
    return Section(
        key="measures",
        title="The field's measures and their chance levels",
        text=text,
        figures=figures,
        metrics={
            "options": asdict(options),
            "weak_null": None if weak_null is None else asdict(weak_null),
        },
    )
