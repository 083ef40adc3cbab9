"""Figures of the signature analysis, one function per figure, each returning a Figure.

The functions take plain mappings from a group name to its data, so any experiment can add groups
(``"fast (generated)"``, ``"cyber player"``...) next to the human ones. They never touch pyplot's
global state: each builds a `matplotlib.figure.Figure` rendered with the Agg canvas.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Polygon as PolygonPatch
from matplotlib.patches import Rectangle
from numpy.typing import ArrayLike, NDArray

from mirror_avatar.metrics import compute_cluster_phase, compute_phase, compute_relative_phase
from mirror_avatar.session import Session
from mirror_avatar.signature import DEFAULT_BINS, Bins, Ellipse
from mirror_avatar.signature_groups import GroupComparison

HUMAN_SKEWNESS = (-0.5, 0.5)
"""Range of stroke skewness seen in people (METHODS section 3)."""

HUMAN_KURTOSIS = (1.5, 3.0)
"""Range of stroke kurtosis (Pearson) seen in people (METHODS section 3)."""

FIGSIZE = (6.4, 4.4)

SYNCHRONISATION_WINDOW = 2.0
"""Seconds of the centred moving mean drawn over rho_g(t) (**choice**: rho_g swings from sample
to sample as the players' phases cross; two seconds span about two cycles of the fast bundled
style, so the line shows how synchronisation drifts over a session)."""


def plot_ims(
    group_ims: Mapping[str, ArrayLike],
    bins: Bins = DEFAULT_BINS,
    trial_ims: Mapping[str, ArrayLike] | None = None,
    title: str = "Individual motor signatures",
) -> Figure:
    """Velocity signatures as probability densities, one curve per group.

    Parameters
    ----------
    group_ims
        Group name -> its signature (probabilities), shape (bins.n,). Groups are drawn in the
        mapping's order, each in its own colour.
    bins
        The bins of every signature.
    trial_ims
        Optional group name -> signatures of its single trials, shape (k, bins.n), drawn as thin
        lines in the group's colour behind the group's curve.
    title
        Axes title.

    Returns
    -------
    matplotlib.figure.Figure
        Density (probability / bin width, 1/(units/s)) against velocity (units/s).
    """
    figure, axes = _new_figure()
    colours = _colours(list(group_ims) + list(trial_ims or {}))
    for name, singles in (trial_ims or {}).items():
        for ims in np.atleast_2d(np.asarray(singles, dtype=np.float64)):
            axes.plot(bins.centres, ims / bins.width, color=colours[name], lw=0.5, alpha=0.35)
    for name, ims in group_ims.items():
        density = np.asarray(ims, dtype=np.float64) / bins.width
        axes.plot(bins.centres, density, color=colours[name], lw=1.8, label=name)
    axes.set(xlabel="velocity (units/s)", ylabel="probability density (s/unit)", title=title)
    axes.set_xlim(bins.lo, bins.hi)
    legend_beside(axes)
    return figure


def plot_similarity_space(
    points: Mapping[str, ArrayLike],
    ellipses: Mapping[str, Ellipse | None] | None = None,
    title: str = "Similarity space (classical MDS of EMD)",
) -> Figure:
    """Trials as points in the similarity space, with each group's characteristic region.

    Parameters
    ----------
    points
        Group name -> coordinates of its trials, shape (k, 2) (EMD units).
    ellipses
        Optional group name -> its confidence ellipse (``None`` or absent: not drawn).
    title
        Axes title.
    """
    figure, axes = _new_figure()
    colours = _colours(list(points) + list(ellipses or {}))
    for name, xy in points.items():
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        axes.scatter(xy[:, 0], xy[:, 1], s=22, color=colours[name], label=name, zorder=3)
    _draw_ellipses(axes, ellipses or {}, colours)
    axes.set(xlabel="dimension 1 (EMD)", ylabel="dimension 2 (EMD)", title=title)
    axes.set_aspect("equal", adjustable="datalim")
    legend_beside(axes)
    return figure


def plot_skew_kurtosis(
    moments: Mapping[str, ArrayLike],
    ellipses: Mapping[str, Ellipse | None] | None = None,
    show_human_range: bool = True,
    title: str = "Velocity strokes: skewness and kurtosis",
) -> Figure:
    """Each stroke's skewness and kurtosis, with each group's region.

    Parameters
    ----------
    moments
        Group name -> (skewness, kurtosis) of its strokes, shape (k, 2).
    ellipses
        Optional group name -> confidence ellipse of its strokes.
    show_human_range
        Outline (dashed) the range people's strokes fall in (`HUMAN_SKEWNESS` x `HUMAN_KURTOSIS`).
    title
        Axes title.
    """
    figure, axes = _new_figure()
    colours = _colours(list(moments) + list(ellipses or {}))
    if show_human_range:
        (s0, s1), (k0, k1) = HUMAN_SKEWNESS, HUMAN_KURTOSIS
        axes.add_patch(
            Rectangle(
                (s0, k0),
                s1 - s0,
                k1 - k0,
                fill=False,
                ls="--",
                color="k",
                zorder=4,
                label="human range",
            )  # fmt: skip
        )
    for name, sk in moments.items():
        sk = np.asarray(sk, dtype=np.float64).reshape(-1, 2)
        axes.scatter(sk[:, 0], sk[:, 1], s=5, alpha=0.35, color=colours[name], label=name)
    _draw_ellipses(axes, ellipses or {}, colours)
    axes.set(xlabel="skewness", ylabel="kurtosis (Pearson)", title=title)
    legend_beside(axes, markerscale=2)
    return figure


def plot_learning_curves(
    curves: Mapping[str, tuple[ArrayLike, ArrayLike]],
    baselines: Mapping[str, float] | None = None,
    title: str = "Cyber player: learning curves",
) -> Figure:
    """RMS position error to the target against training sessions, one line per run.

    Parameters
    ----------
    curves
        Run name -> (sessions trained, shape (k,); RMS to the target over the block, units,
        shape (k,)).
    baselines
        Optional name -> a constant RMS (units) drawn as a dashed horizontal line.
    title
        Axes title.
    """
    figure, axes = _new_figure()
    colours = _colours(list(curves) + list(baselines or {}))
    for name, (sessions, rms) in curves.items():
        axes.plot(np.asarray(sessions), np.asarray(rms), color=colours[name], lw=1.5, label=name)
    for name, value in (baselines or {}).items():
        axes.axhline(value, color=colours[name], ls="--", lw=1.0, label=name)
    axes.set(xlabel="training sessions", ylabel="RMS to the target (units)", title=title)
    axes.set_ylim(bottom=0.0)
    axes.legend(frameon=False)
    return figure


def plot_positions(
    times: ArrayLike,
    positions: Mapping[str, ArrayLike],
    title: str = "Positions",
) -> Figure:
    """Position time series of several players on one time axis.

    Parameters
    ----------
    times
        Sample times (s), shape (n,).
    positions
        Player name -> positions (units), shape (n,).
    title
        Axes title.
    """
    return plot_series(times, positions, "position (units)", title)


def plot_series(
    times: ArrayLike, series: Mapping[str, ArrayLike], ylabel: str, title: str
) -> Figure:
    """Several time series on one time axis (s), one line each.

    Parameters
    ----------
    times
        Sample times (s), shape (n,).
    series
        Name -> values, shape (n,).
    ylabel, title
        Axis label (with units) and axes title.
    """
    figure, axes = _new_figure()
    colours = _colours(list(series))
    t = np.asarray(times, dtype=np.float64)
    for name, values in series.items():
        axes.plot(t, np.asarray(values, dtype=np.float64), color=colours[name], lw=1.2, label=name)
    axes.set(xlabel="time (s)", ylabel=ylabel, title=title)
    axes.legend(frameon=False)
    return figure


def plot_group_synchronisation(
    times: ArrayLike,
    series: Mapping[str, ArrayLike],
    title: str = "Group synchronisation",
    window: float = SYNCHRONISATION_WINDOW,
) -> Figure:
    """Group synchronisation rho_g(t) of one or more sessions: each raw, faint, and its mean.

    Parameters
    ----------
    times
        Sample times (s), shape (n,), uniformly spaced.
    series
        Name -> rho_g at each sample, shape (n,), in [0, 1].
    title
        Axes title.
    window
        Length (s) of the centred moving mean drawn bold (`moving_mean`).
    """
    figure, axes = _new_figure()
    colours = _colours(list(series))
    t = np.asarray(times, dtype=np.float64)
    n = max(1, round(window / float(np.median(np.diff(t))))) if t.size > 1 else 1
    for name, values in series.items():
        rho = np.asarray(values, dtype=np.float64)
        axes.plot(t, rho, color=colours[name], lw=0.6, alpha=0.25)
        axes.plot(t, moving_mean(rho, n), color=colours[name], lw=1.8, label=name)
    axes.set(xlabel="time (s)", ylabel="rho_g (1 = synchronised)", ylim=(0.0, 1.02), title=title)
    axes.legend(frameon=False, title=f"{window:g} s moving mean (faint: each sample)")
    return figure


def moving_mean(values: ArrayLike, n: int) -> NDArray[np.float64]:
    """Return the centred moving mean over ``n`` samples, the shape of ``values``.

    Sample k averages samples k - n // 2 to k + (n - 1) // 2; near the ends, those that exist.
    """
    x = np.asarray(values, dtype=np.float64)
    sums = np.concatenate([[0.0], np.cumsum(x)])
    k = np.arange(x.size)
    lo, hi = np.maximum(k - n // 2, 0), np.minimum(k + (n - 1) // 2 + 1, x.size)
    return (sums[hi] - sums[lo]) / (hi - lo)


def plot_progress(table: pd.DataFrame, columns: Sequence[str], title: str) -> Figure:
    """Columns of a per-session table against the session number, one line with markers each."""
    figure, axes = _new_figure()
    colours = _colours(list(columns))
    for column in columns:
        axes.plot(table.index, table[column], "o-", color=colours[column], lw=1.2, label=column)
    axes.set(xlabel="session", title=title)
    axes.legend(frameon=False)
    return figure


def plot_bars(
    values: Mapping[str, Mapping[str, float]], ylabel: str, title: str, limit: float | None = None
) -> Figure:
    """Draw grouped bars: for each category (x axis), one bar per series.

    Parameters
    ----------
    values
        Series name -> category -> value; every series has the same categories.
    ylabel, title
        Axis label and axes title.
    limit
        Optional value drawn as a dashed horizontal line (a threshold).
    """
    figure, axes = _new_figure()
    names = list(values)
    categories = list(next(iter(values.values())))
    colours = _colours(names)
    width = 0.8 / len(names)
    x = np.arange(len(categories))
    for i, name in enumerate(names):
        heights = [values[name][c] for c in categories]
        axes.bar(x + (i - (len(names) - 1) / 2) * width, heights, width, color=colours[name],
                 label=name)  # fmt: skip
    if limit is not None:
        axes.axhline(limit, color="0.4", ls="--", lw=1.0)
    axes.set_xticks(x, categories)
    axes.set(ylabel=ylabel, title=title)
    axes.legend(frameon=False)
    return figure


def plot_graph(adjacency: ArrayLike, labels: list[str], title: str = "Who observes whom") -> Figure:
    """Draw a coupling graph, players on a circle; an arrow k -> j when only k observes j."""
    figure, axes = _new_figure()
    links = np.asarray(adjacency) != 0
    n = links.shape[0]
    angles = np.pi / 2 - 2 * np.pi * np.arange(n) / n
    xy = np.column_stack([np.cos(angles), np.sin(angles)])
    for k in range(n):
        for j in range(n):
            if links[k, j] and (k < j or not links[j, k]):
                style = "-" if links[j, k] else "->"
                arrow = {"arrowstyle": style, "color": "0.45", "lw": 1.5}
                axes.annotate("", xy=xy[j], xytext=xy[k], arrowprops=arrow)
    colours = _colours(labels)
    for k, label in enumerate(labels):
        axes.scatter(xy[k, 0], xy[k, 1], s=600, color=colours[label], zorder=3)
        axes.annotate(label, xy[k] * 1.28, ha="center", va="center")
    axes.set(xlim=(-1.6, 1.6), ylim=(-1.5, 1.5), title=title, aspect="equal")
    axes.set_axis_off()
    return figure


LEGEND_INSIDE = 10
"""Entries up to which a legend sits inside the axes; with more, `legend_beside` moves it out."""


def legend_beside(axes: Axes, markerscale: float = 1.0) -> None:
    """Draw the legend inside the axes, or for many entries beside them in small type.

    Past `LEGEND_INSIDE` entries the legend goes to the right of the axes in columns of at
    most 25, and the figure widens by each column's width, so that the axes keep their size.
    """
    n = len(axes.get_legend_handles_labels()[1])
    if n <= LEGEND_INSIDE:
        axes.legend(frameon=False, markerscale=markerscale)
        return
    columns = -(-n // 25)
    axes.legend(frameon=False, markerscale=markerscale, fontsize=6, ncol=columns,
                loc="upper left", bbox_to_anchor=(1.01, 1.0))  # fmt: skip
    figure = axes.get_figure()
    assert isinstance(figure, Figure)
    width, height = figure.get_size_inches()
    figure.set_size_inches(width + 1.5 * columns, max(height, 0.12 * min(n, 25) + 1.0))


def _new_figure() -> tuple[Figure, Axes]:
    figure = Figure(figsize=FIGSIZE, layout="constrained")
    FigureCanvasAgg(figure)
    return figure, figure.add_subplot()


def _colours(names: list[str]) -> dict[str, str]:
    unique = list(dict.fromkeys(names))
    return {name: f"C{i % 10}" for i, name in enumerate(unique)}


def _draw_ellipses(
    axes: Axes, ellipses: Mapping[str, Ellipse | None], colours: Mapping[str, str]
) -> None:
    for name, ellipse in ellipses.items():
        if ellipse is not None:
            outline = PolygonPatch(
                ellipse.boundary(), closed=True, fill=False, lw=1.5, color=colours[name], zorder=2
            )
            axes.add_patch(outline)
            axes.update_datalim(ellipse.boundary())
    axes.autoscale_view()


def plot_relative_phase(
    phases: Mapping[str, ArrayLike],
    n_bins: int = 36,
    title: str = "Relative phase",
) -> Figure:
    """Distribution of relative phase, one density per condition, with its circular mean dashed.

    Parameters
    ----------
    phases
        Condition name -> relative phase samples (rad, in [-pi, pi]), any shape.
    n_bins
        Histogram bins over [-pi, pi].
    title
        Axes title.
    """
    figure, axes = _new_figure()
    colours = _colours(list(phases))
    edges = np.linspace(-np.pi, np.pi, n_bins + 1)
    for name, values in phases.items():
        phase = np.ravel(np.asarray(values, dtype=np.float64))
        density, _ = np.histogram(phase, bins=edges, density=True)
        axes.stairs(density, edges, color=colours[name], lw=1.5, label=name)
        mean = float(np.angle(np.mean(np.exp(1j * phase))))
        axes.axvline(mean, color=colours[name], ls="--", lw=1.0)
    axes.set(xlabel="relative phase (rad)", ylabel="probability density (1/rad)", title=title)
    axes.set_xlim(-np.pi, np.pi)
    axes.legend(frameon=False)
    return figure


SESSION_FIGURES = ("positions", "relative_phase", "group_synchronisation")
"""Every figure `plot_session` may draw, by file stem."""


def plot_session(session: Session, trim: float = 0.0, seconds: float = 30.0) -> dict[str, Figure]:
    """Draw what people look at for one session: positions, and how the players lock.

    Parameters
    ----------
    session
        Any number of players.
    trim
        Seconds left out at the start, as in the session's metrics.
    seconds
        Length of the position plot (s), from the start of what is kept.

    Returns
    -------
    dict
        ``positions``; for two players ``relative_phase`` (player 0 minus player 1); for a group
        ``group_synchronisation`` (rho_g over time); keyed by file stem.
    """
    kept = session.trimmed(trim) if trim > 0 else session
    show = kept.times <= kept.times[0] + seconds
    labels = [f"{k}: {label}" for k, label in enumerate(kept.labels)]
    figures = {
        "positions": plot_positions(
            kept.times[show],
            {label: x[show] for label, x in zip(labels, kept.positions, strict=True)},
            title=f"Positions (first {seconds:g} s)",
        )
    }
    moving = bool(np.all(np.ptp(kept.positions, axis=1) > 0))
    if kept.n_players == 2 and moving:
        figures["relative_phase"] = plot_relative_phase(
            {"player 0 - player 1": compute_relative_phase(*kept.positions)},
            title="Relative phase (positive: player 0 ahead)",
        )
    elif kept.n_players > 2 and moving:
        cluster = compute_cluster_phase(np.array([compute_phase(x) for x in kept.positions]))
        figures["group_synchronisation"] = plot_group_synchronisation(
            kept.times, {"rho_g": cluster.group}
        )
    return figures


def plot_group_comparison(comparison: GroupComparison) -> Figure:
    """Two groups of people: their similarity space, and each test against its shuffled labels.

    Left, the people (classical MDS of their mean EMD), a cross on each one classified into the
    other group; middle, between- minus within-group EMD over relabellings of people, the true
    value as a line; right, the leave-one-person-out accuracy likewise.
    """
    figure = Figure(figsize=(FIGSIZE[0] * 2, FIGSIZE[1]), layout="constrained")
    FigureCanvasAgg(figure)
    space, separation, accuracy = figure.subplots(1, 3)
    wrong = comparison.classification.predicted != comparison.positive
    for k, name in enumerate(comparison.groups):
        mine = comparison.positive == bool(k)
        xy = comparison.coordinates[mine]
        space.scatter(xy[:, 0], xy[:, 1], s=22, color=f"C{k}", label=name, zorder=3)
        missed = comparison.coordinates[mine & wrong]
        space.scatter(missed[:, 0], missed[:, 1], s=60, marker="x", color="black", zorder=4)
    space.set(xlabel="dimension 1 (EMD)", ylabel="dimension 2 (EMD)", title="People")
    space.set_aspect("equal", adjustable="datalim")
    space.legend(frameon=False)
    for axes, test, label in (
        (separation, comparison.separation, "between - within EMD"),
        (accuracy, comparison.chance, "accuracy (leave one person out)"),
    ):
        axes.hist(test.null, bins=30, color="0.7", label="labels shuffled by person")
        axes.axvline(test.statistic, color="C3", label=f"true labels (p = {test.p_value:.3g})")
        axes.set(xlabel=label, ylabel="relabellings")
        axes.legend(frameon=False, fontsize=7)
    return figure
