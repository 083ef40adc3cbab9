"""Figures of the signature analysis: IMS, the similarity space, stroke moments, groups of people.

The functions take plain mappings from a group name to its data, so any experiment can add groups
(``"fast (generated)"``, ``"cyber player"``...) next to the human ones.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Polygon as PolygonPatch
from matplotlib.patches import Rectangle
from numpy.typing import ArrayLike

from mirror_avatar.figures.style import FIGSIZE, legend_beside, new_figure, palette
from mirror_avatar.signatures.groups import GroupComparison
from mirror_avatar.signatures.signature import DEFAULT_BINS, Bins, Ellipse

HUMAN_SKEWNESS = (-0.5, 0.5)
"""Range of stroke skewness seen in people (METHODS section 3)."""


HUMAN_KURTOSIS = (1.5, 3.0)
"""Range of stroke kurtosis (Pearson) seen in people (METHODS section 3)."""


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
    figure, axes = new_figure()
    colours = palette(list(group_ims) + list(trial_ims or {}))
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
    figure, axes = new_figure()
    colours = palette(list(points) + list(ellipses or {}))
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
    figure, axes = new_figure()
    colours = palette(list(moments) + list(ellipses or {}))
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
