"""The figures' common style: size, colours, legends; each figure on its own Agg canvas.

No figure touches pyplot's global state: `new_figure` builds a `matplotlib.figure.Figure`
rendered with the Agg canvas, so figures are drawn safely from any thread.
"""

from __future__ import annotations

from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

FIGSIZE = (6.4, 4.4)


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


def new_figure() -> tuple[Figure, Axes]:
    """Make a figure of `FIGSIZE` on its own Agg canvas, with one axes."""
    figure = Figure(figsize=FIGSIZE, layout="constrained")
    FigureCanvasAgg(figure)
    return figure, figure.add_subplot()


def palette(names: list[str]) -> dict[str, str]:
    """Give each distinct name one of matplotlib's ten cycle colours, in order of appearance."""
    unique = list(dict.fromkeys(names))
    return {name: f"C{i % 10}" for i, name in enumerate(unique)}
