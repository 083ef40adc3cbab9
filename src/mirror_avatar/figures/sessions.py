"""Figures of a played or recorded session: positions, relative phase, group synchrony."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import ArrayLike, NDArray

from mirror_avatar.figures.style import new_figure, palette
from mirror_avatar.metrics import compute_cluster_phase, compute_phase, compute_relative_phase
from mirror_avatar.sessions.session import Session

SYNCHRONISATION_WINDOW = 2.0
"""Seconds of the centred moving mean drawn over rho_g(t) (**choice**: rho_g swings from sample
to sample as the players' phases cross; two seconds span about two cycles of the fast bundled
style, so the line shows how synchronisation drifts over a session)."""


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
    figure, axes = new_figure()
    colours = palette(list(series))
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
    figure, axes = new_figure()
    colours = palette(list(series))
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
    figure, axes = new_figure()
    colours = palette(list(phases))
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
