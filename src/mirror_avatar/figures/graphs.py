"""The figure of a coupling graph: who observes whom."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from mirror_avatar.figures.style import new_figure, palette


def plot_graph(adjacency: ArrayLike, labels: list[str], title: str = "Who observes whom") -> Figure:
    """Draw a coupling graph, players on a circle; an arrow k -> j when only k observes j."""
    figure, axes = new_figure()
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
    colours = palette(labels)
    for k, label in enumerate(labels):
        axes.scatter(xy[k, 0], xy[k, 1], s=600, color=colours[label], zorder=3)
        axes.annotate(label, xy[k] * 1.28, ha="center", va="center")
    axes.set(xlim=(-1.6, 1.6), ylim=(-1.5, 1.5), title=title, aspect="equal")
    axes.set_axis_off()
    return figure
