"""Figures of progress: training's learning curves, a participant's measures over sessions, bars."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from mirror_avatar.figures.style import new_figure, palette


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
    figure, axes = new_figure()
    colours = palette(list(curves) + list(baselines or {}))
    for name, (sessions, rms) in curves.items():
        axes.plot(np.asarray(sessions), np.asarray(rms), color=colours[name], lw=1.5, label=name)
    for name, value in (baselines or {}).items():
        axes.axhline(value, color=colours[name], ls="--", lw=1.0, label=name)
    axes.set(xlabel="training sessions", ylabel="RMS to the target (units)", title=title)
    axes.set_ylim(bottom=0.0)
    axes.legend(frameon=False)
    return figure


def plot_progress(table: pd.DataFrame, columns: Sequence[str], title: str) -> Figure:
    """Columns of a per-session table against the session number, one line with markers each."""
    figure, axes = new_figure()
    colours = palette(list(columns))
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
    figure, axes = new_figure()
    names = list(values)
    categories = list(next(iter(values.values())))
    colours = palette(names)
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
