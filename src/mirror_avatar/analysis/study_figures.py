"""Figures of a study's statistics: every participant's values, the identification answers, power.

As `mirror_avatar.figures`: each function builds a `matplotlib.figure.Figure` on the Agg canvas
and never touches pyplot's global state.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from numpy.typing import NDArray

from mirror_avatar.analysis.identification import Identification, scored_answers
from mirror_avatar.figures.style import FIGSIZE

PARTICIPANT_COLOUR = "0.6"
MEAN_COLOUR = "C0"


def plot_participants(means: pd.DataFrame, summary: pd.DataFrame, label: str) -> Figure:
    """Each participant's mean per condition, joined by a line, with the mean and its CI.

    Parameters
    ----------
    means
        Participants x conditions (`mirror_avatar.analysis.statistics.participant_means`).
    summary
        The measure's rows of `condition_summaries`: ``condition, mean, ci_low, ci_high``.
    label
        The measure's axis label, with its units.
    """
    figure = _new_figure(1.0)
    axes = figure.add_subplot()
    x = np.arange(means.shape[1], dtype=np.float64)
    for _, values in means.iterrows():
        axes.plot(x, values.to_numpy(), color=PARTICIPANT_COLOUR, lw=0.9, marker="o", ms=3,
                  alpha=0.8)  # fmt: skip
    shown = summary.set_index("condition").reindex(means.columns)
    error = np.abs(shown[["ci_low", "ci_high"]].to_numpy().T - shown["mean"].to_numpy())
    axes.errorbar(x + 0.08, shown["mean"], yerr=error, color=MEAN_COLOUR, lw=2, marker="s", ms=6,
                  capsize=4, label="mean over participants, 95 % CI")  # fmt: skip
    axes.plot([], [], color=PARTICIPANT_COLOUR, marker="o", ms=3, label="a participant")
    axes.set_xticks(x, [str(c) for c in means.columns])
    axes.set_xlim(-0.4, x[-1] + 0.4 if x.size else 0.4)
    axes.set(xlabel="condition", ylabel=label)
    axes.legend(frameon=False, fontsize="small")
    return figure


def plot_identification(rows: pd.DataFrame, identification: Identification) -> Figure:
    """Answers "person" per true partner kind, per person; confidence of right and wrong.

    Left: each person's share of "person" answers when the partner was a person (hit
    rate) and when an avatar (false-alarm rate), joined by a line, with the pooled rates.
    Right: confidence of right and of wrong answers (every answer a dot), with their means.
    """
    figure = _new_figure(1.6)
    rates, confidence = figure.subplots(1, 2)
    table = identification.per_person
    for _, row in table.iterrows():
        rates.plot([0, 1], [row["hit_rate"], row["false_alarm_rate"]], color=PARTICIPANT_COLOUR,
                   marker="o", ms=3, lw=0.9)  # fmt: skip
    pooled = identification.detection
    rates.plot([0, 1], [pooled.hit_rate, pooled.false_alarm_rate], color=MEAN_COLOUR, lw=2,
               marker="s", ms=6, label=f"all answers (d' = {pooled.d_prime:.2f})")  # fmt: skip
    rates.axhline(0.5, color="0.3", ls=":", lw=1)
    rates.set_xticks([0, 1], ["partner a person", "partner an avatar"])
    rates.set(xlim=(-0.3, 1.3), ylim=(-0.05, 1.05), ylabel='share answered "person"')
    rates.legend(frameon=False, fontsize="small")
    _plot_confidence(confidence, rows)
    return figure


def _plot_confidence(axes: Axes, rows: pd.DataFrame) -> None:
    answers, _ = scored_answers(rows)
    rated = answers.dropna(subset=["confidence"])
    rng = np.random.default_rng(0)
    for x, right in enumerate((True, False)):
        values = rated.loc[rated["right"] == right, "confidence"].to_numpy(np.float64)
        axes.scatter(x + rng.uniform(-0.12, 0.12, values.size), values, s=10,
                     color=PARTICIPANT_COLOUR)  # fmt: skip
        if values.size:
            axes.plot([x - 0.25, x + 0.25], [values.mean()] * 2, color=MEAN_COLOUR, lw=2)
    axes.set_xticks([0, 1], ["right answers", "wrong answers"])
    axes.set(xlim=(-0.5, 1.5), ylabel="confidence")
    if rated.empty:
        axes.text(0.5, 0.5, "no confidence asked", ha="center", transform=axes.transAxes)


def plot_power(
    participants: NDArray[np.int64],
    power: NDArray[np.float64],
    intervals: NDArray[np.float64],
    target: float,
) -> Figure:
    """Plot the simulated power at each number of participants, its interval, the target.

    Parameters
    ----------
    participants, power
        Shape (k,): each n simulated and its power (a share, 0 to 1).
    intervals
        Shape (k, 2): each power's interval, low and high.
    target
        The power aimed at, drawn as a dashed line.
    """
    figure = _new_figure(1.0)
    axes = figure.add_subplot()
    below, above = power - intervals[:, 0], intervals[:, 1] - power
    axes.errorbar(participants, power, yerr=np.vstack([below, above]), color=MEAN_COLOUR,
                  marker="o", ms=4, capsize=3, lw=1.2)  # fmt: skip
    axes.axhline(target, color=PARTICIPANT_COLOUR, ls="--", lw=1.0, label=f"target {target:g}")
    axes.set(xlabel="participants", ylabel="power", ylim=(0.0, 1.03), xticks=participants)
    axes.legend(loc="lower right", frameon=False)
    return figure


def _new_figure(widen: float) -> Figure:
    """Make a figure on the Agg canvas, ``widen`` times as wide as the project's figures."""
    width, height = FIGSIZE
    figure = Figure(figsize=(width * widen, height), layout="constrained")
    FigureCanvasAgg(figure)
    return figure
