"""Figures of many people's signatures that stay readable: labels never overlap.

`plot_people_space` draws the similarity space with each person named once, the names placed
by `place_labels` where they overlap neither each other nor leave the axes; `plot_emd_heatmap`
draws the EMD between every two trials, each row and column named by whose trial it is, the
figure growing and the type shrinking with the number of trials.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Polygon as PolygonPatch
from matplotlib.transforms import Bbox
from matplotlib.typing import ColorType
from numpy.typing import NDArray

from mirror_avatar.signatures.signature import Ellipse, SignatureAnalysis

Array = NDArray[np.float64]

RADII = (0.0, 8.0, 16.0, 26.0, 38.0, 52.0, 68.0, 86.0, 106.0, 130.0)
"""Distances (points) from its anchor at which a label is tried, nearest first."""

DIRECTIONS = 16
"""Directions tried at each distance."""

LABEL_GAP = 2.0
"""Clearance (points) kept around each label."""


def plot_people_space(analysis: SignatureAnalysis) -> Figure:
    """Trials in the similarity space, coloured by person, each person named once.

    Each person's name is placed near the centre of their trials (`place_labels`), with a thin
    line to it when it had to move away; their confidence region is drawn when they have 3
    trials or more. The figure and its type are sized for the number of people.

    Parameters
    ----------
    analysis
        The signature analysis; its groups are the people.
    """
    n = len(analysis.group_names)
    fontsize = 8.0 if n <= 15 else 7.0 if n <= 30 else 6.0
    figure = Figure(figsize=(8.0, 6.0) if n <= 15 else (10.0, 7.5), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    colours = person_colours(analysis.group_names)
    points = analysis.points_by_group()
    for name, xy in points.items():
        axes.scatter(xy[:, 0], xy[:, 1], s=18, color=colours[name], zorder=3)
        ellipse = analysis.ellipses.get(name)
        if ellipse is not None:
            _draw_region(axes, ellipse, colours[name])
    axes.set(xlabel="dimension 1 (EMD)", ylabel="dimension 2 (EMD)")
    axes.set_title(f"Similarity space: {n} people, {len(analysis.labels)} trials")
    axes.set_aspect("equal", adjustable="datalim")
    axes.margins(0.15)
    centres = np.array([xy.mean(axis=0) for xy in points.values()])
    place_labels(axes, centres, list(points), fontsize, [colours[name] for name in points],
                 analysis.coordinates)  # fmt: skip
    return figure


def plot_emd_heatmap(analysis: SignatureAnalysis) -> Figure:
    """Draw the EMD between every two trials, grouped by person, every row and column named.

    Rows and columns are the trials in the order of their people, named ``person/trial``; thin
    lines separate the people. Cells are sized so that one line of type fits each (the figure
    grows with the number of trials), and the EMD is written in the cells when there are few.
    """
    order = np.concatenate([analysis.members(g) for g in analysis.group_names])
    names = [_whose(analysis.labels[i], analysis.groups[i]) for i in order]
    m = order.size
    cell = float(np.clip(6.0 / m, 0.14, 0.45))
    fontsize = float(np.clip(cell * 72 * 0.6, 4.5, 9.0))
    margin = 0.09 * max(map(len, names)) * fontsize / 8 + 0.6
    side = m * cell
    figure = Figure(figsize=(side + margin + 1.4, side + margin + 0.6), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    image = axes.imshow(analysis.emd[np.ix_(order, order)], cmap="viridis", origin="upper")
    figure.colorbar(image, ax=axes, label="EMD", shrink=0.8)
    axes.set_xticks(np.arange(m), names, rotation=90, fontsize=fontsize)
    axes.set_yticks(np.arange(m), names, fontsize=fontsize)
    edges = np.cumsum([analysis.members(g).size for g in analysis.group_names])[:-1] - 0.5
    for edge in edges:
        axes.axhline(edge, color="white", lw=1.0)
        axes.axvline(edge, color="white", lw=1.0)
    if m <= 12:
        emd = analysis.emd[np.ix_(order, order)]
        for (row, column), value in np.ndenumerate(emd):
            axes.text(column, row, f"{value:.3f}", ha="center", va="center", color="white",
                      fontsize=fontsize * 0.85)  # fmt: skip
    axes.set_title("EMD between trials (grouped by person)", fontsize=max(fontsize, 8.0))
    return figure


def place_labels(
    axes: Axes,
    anchors: Array,
    texts: Sequence[str],
    fontsize: float,
    colours: Sequence[ColorType],
    obstacles: Array,
) -> None:
    """Write each text near its anchor where it covers no other label and no point.

    Labels are placed in order; each tries positions at `RADII` from its anchor in `DIRECTIONS`
    directions, nearest first, and takes the first that is clear (with `LABEL_GAP` around it)
    of the labels placed before and of the points, and inside the axes; when none is, the one
    overlapping the fewest. A label away from its anchor gets a thin line to it. The axes'
    limits are fixed first (the figure is laid out once), so that positions on the page are
    final.

    Parameters
    ----------
    axes
        Axes already holding the data.
    anchors
        Data coordinates of each label's point, shape (k, 2).
    texts, colours
        Each label's text and colour, length k.
    fontsize
        Type size (points).
    obstacles
        Data coordinates of the points labels must not cover, shape (p, 2).
    """
    figure = axes.get_figure()
    assert isinstance(figure, Figure)
    figure.draw_without_rendering()
    axes.set_xlim(axes.get_xlim())
    axes.set_ylim(axes.get_ylim())
    renderer = figure.canvas.get_renderer()  # type: ignore[attr-defined]
    frame = axes.get_window_extent(renderer)
    points = figure.dpi / 72.0
    to_data = axes.transData.inverted()
    taken = [_marker_box(xy, points) for xy in axes.transData.transform(obstacles)]
    for anchor, text, colour in zip(anchors, texts, colours, strict=True):
        label = axes.text(anchor[0], anchor[1], text, fontsize=fontsize, color=colour,
                          ha="center", va="center", zorder=5, fontweight="bold")  # fmt: skip
        label.set_in_layout(False)
        home = axes.transData.transform(anchor)
        best: tuple[int, Array, Bbox] | None = None
        for offset in _offsets():
            label.set_position(_pair(to_data.transform(home + offset * points)))
            box = label.get_window_extent(renderer).padded(LABEL_GAP * points)
            clashes = sum(box.overlaps(other) for other in taken) + (not _inside(box, frame))
            if best is None or clashes < best[0]:
                best = (clashes, offset, box)
            if clashes == 0:
                break
        assert best is not None
        _, offset, box = best
        centre = to_data.transform(home + offset * points)
        label.set_position(_pair(centre))
        taken.append(box)
        if np.hypot(*offset) > RADII[1]:
            axes.plot(*np.transpose([anchor, centre]), color=colour, lw=0.6, zorder=4)


def person_colours(names: Sequence[str]) -> dict[str, ColorType]:
    """Give each person a colour: the 20 colours of ``tab20`` in turn, then repeated."""
    palette = colormaps["tab20"](np.arange(20))
    return {name: palette[(2 * k) % 20 + (k // 10) % 2] for k, name in enumerate(names)}


def _pair(xy: Array) -> tuple[float, float]:
    return float(xy[0]), float(xy[1])


def _offsets() -> list[Array]:
    angles = 2 * np.pi * np.arange(DIRECTIONS) / DIRECTIONS
    return [
        np.array([radius * np.cos(a), radius * np.sin(a)])
        for radius in RADII
        for a in (angles if radius > 0 else angles[:1])
    ]


def _marker_box(centre: Array, points: float) -> Bbox:
    """Return the display box of a scatter marker (about 4.5 points across) at ``centre``."""
    half = 2.5 * points
    return Bbox.from_extents(centre[0] - half, centre[1] - half, centre[0] + half, centre[1] + half)


def _inside(box: Bbox, frame: Bbox) -> bool:
    return bool(
        box.x0 >= frame.x0 and box.x1 <= frame.x1 and box.y0 >= frame.y0 and box.y1 <= frame.y1
    )


def _draw_region(axes: Axes, ellipse: Ellipse, colour: ColorType) -> None:
    boundary = ellipse.boundary()
    axes.add_patch(PolygonPatch(boundary, closed=True, fill=False, lw=1.0, color=colour, alpha=0.7))
    axes.update_datalim(boundary)


def _whose(label: str, person: str) -> str:
    return label if label.startswith(f"{person}/") else f"{person}/{label}"
