"""Stroke models that can be shared: strokes averaged in groups, so no trial can be rebuilt.

A fitted `StrokeGenerator` keeps the person's own strokes with their predecessors' lengths and
sizes: chaining them back rebuilds the training trials, and motion identifies a person (METHODS
section 5). `shareable` writes a model whose every stroke is the average of a group of at least
``group_size`` of the person's strokes of one direction, found by **MDAV microaggregation**
(maximum distance to average vector; Domingo-Ferrer & Mateo-Sanz 2002, "Practical data-oriented
microaggregation for statistical disclosure control", IEEE TKDE 14(1); the fixed-size variant of
Domingo-Ferrer & Torra 2005, Data Mining and Knowledge Discovery 11(2)), `mdav_groups`. Strokes
are grouped by their standardised log length, log size, predecessor's log length and log size,
and start; a group's stroke has the geometric mean length (rounded to whole samples) and size,
the mean start and predecessor's features, and the mean of its members' profiles each
stretched to that length. The jitter bandwidths add back the spread of log lengths and log
sizes the averaging took away (`_restored_bandwidth`); the hyper-parameters are kept; the
trials' labels and durations are left out.

Whether a model rebuilds a trial is measured by `rebuild_errors`: each of the trial's strokes set
against the model stroke that reproduces it best, as the model holds it (its start, displacement
and profile stretched to the stroke's length). A fitted model rebuilds its training strokes
exactly (error 0); a shared one should rebuild them no better than strokes of trials it never
saw.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.ndimage
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.trials import Trial
from mirror_avatar.motion.strokes import (
    LOG_FLOOR,
    StrokeGenerator,
    log_length,
    log_size,
    reversals,
)

Array = NDArray[np.float64]

DETAIL_WINDOW = 9
"""Samples of the moving average that splits a profile into its smooth part and its detail
(**choice**: 0.09 s at 100 Hz, half power near 5 Hz, so tremor and the small turns within a
stroke are detail)."""

SIGN_SEED = 0
"""Seed of the signs that mix a group's details (`blended_profile`)."""

DEFAULT_GROUP_SIZE = 3
"""Fewest strokes averaged into each stroke of a shared model (microaggregation's k)."""


def mdav_groups(points: Array, group_size: int) -> list[NDArray[np.int64]]:
    """Partition points into groups of ``group_size`` to ``2 group_size - 1`` near each other.

    MDAV (module docstring): while three groups' worth remain, the point farthest from the
    remaining points' centroid and its ``group_size - 1`` nearest form a group, then the point
    farthest from that one and its nearest form another; two groups' worth are split the same
    way once; fewer form the last group. Distances are Euclidean.

    Parameters
    ----------
    points : ndarray, shape (n, d)
        The points, ``n >= group_size``.
    group_size
        Fewest points per group (k >= 1).

    Returns
    -------
    list of ndarray of int
        Each group's point indices.
    """
    remaining = np.arange(points.shape[0])
    groups: list[NDArray[np.int64]] = []

    def take_around(anchor: NDArray[np.float64]) -> None:
        nonlocal remaining
        distance = np.sum((points[remaining] - anchor) ** 2, axis=1)
        nearest = np.argsort(distance, kind="stable")[:group_size]
        groups.append(remaining[nearest])
        remaining = np.delete(remaining, nearest)

    def farthest_from(anchor: NDArray[np.float64]) -> NDArray[np.float64]:
        distance = np.sum((points[remaining] - anchor) ** 2, axis=1)
        return points[remaining[int(np.argmax(distance))]]

    while remaining.size >= 3 * group_size:
        first = farthest_from(points[remaining].mean(axis=0))
        take_around(first)
        take_around(farthest_from(first))
    if remaining.size >= 2 * group_size:
        take_around(farthest_from(points[remaining].mean(axis=0)))
    if remaining.size:
        groups.append(remaining)
    return groups


def shareable(model: StrokeGenerator, group_size: int = DEFAULT_GROUP_SIZE) -> StrokeGenerator:
    """Return a fitted stroke model whose strokes are averages of ``group_size`` or more.

    Parameters
    ----------
    model
        A fitted stroke generator (its own strokes, or averaged ones: they are averaged again).
    group_size
        Fewest strokes averaged into each (k, at least 2).

    Raises
    ------
    InputError
        ``group_size`` below 2, or fewer strokes of a direction than ``group_size`` (or fewer
        groups than the generator needs).
    """
    if group_size < 2:
        raise InputError("--group-size", f"must be at least 2 strokes, got {group_size}")
    features = _standardised(model)
    groups: list[NDArray[np.int64]] = []
    for direction in (-1.0, 1.0):
        members = np.flatnonzero(np.sign(model.displacements_) == direction)
        if members.size < group_size:
            raise InputError(
                "model",
                f"{members.size} strokes move {'down' if direction < 0 else 'up'}; averaging "
                f"groups of {group_size} needs as many: fit on more trials or lower --group-size",
            )
        groups.extend(members[group] for group in mdav_groups(features[members], group_size))
    return _averaged(model, groups, group_size)


def _standardised(model: StrokeGenerator) -> Array:
    """Return the strokes' grouping features in units of each feature's SD, (m, 5)."""
    columns = np.column_stack(
        [
            log_length(model.lengths_),
            log_size(model.displacements_),
            log_length(model.before_lengths_),
            log_size(model.before_sizes_),
            model.starts_,
        ]
    )
    spread = np.maximum(columns.std(axis=0), 1e-9)
    return (columns - columns.mean(axis=0)) / spread


def _averaged(
    model: StrokeGenerator, groups: list[NDArray[np.int64]], group_size: int
) -> StrokeGenerator:
    """Return a model with one stroke per group: its members' average (module docstring)."""
    lengths, profiles = [], []
    signs = np.random.default_rng(SIGN_SEED)
    for group in groups:
        length = max(1.0, float(np.round(np.exp(log_length(model.lengths_[group]).mean()))))
        grid = np.linspace(0.0, 1.0, int(length) + 1)
        stretched = np.array([model.profile_at(int(i), grid) for i in group])
        lengths.append(length)
        profiles.append(blended_profile(stretched, signs.choice([-1.0, 1.0], size=group.size)))
    shared = model.unfitted(model.random_state)
    shared.lengths_ = np.array(lengths)
    shared.displacements_ = np.array(
        [np.sign(model.displacements_[g[0]]) * _mean_size(model.displacements_[g]) for g in groups]
    )
    shared.starts_ = np.array([model.starts_[g].mean() for g in groups])
    shared.before_lengths_ = np.array(
        [np.exp(log_length(model.before_lengths_[g]).mean()) for g in groups]
    )
    shared.before_sizes_ = np.array([_mean_size(model.before_sizes_[g]) for g in groups])
    shared.profiles_ = np.concatenate(profiles)
    shared.bandwidth_ = _restored_bandwidth(model, shared, groups)
    summary = model.training_summary_
    shared.training_summary_ = {
        "groups": summary["groups"],
        "n_trials": len(summary.get("labels", [])) or summary.get("n_trials", 0),
        "n_strokes": summary["n_strokes"],
        "holds": f"averages of {group_size} or more strokes",
        "random_state": summary.get("random_state"),
    }
    shared._prepare_sampling()
    return shared


def blended_profile(profiles: Array, signs: Array) -> Array:
    """Return one profile from a group's: their smooth parts' mean plus their detail, mixed.

    Each profile (rows of ``profiles``, one length) is split into its moving average over
    `DETAIL_WINDOW` samples and the rest, its detail; the result is the mean of the smooth parts
    plus ``sum(signs[i] * detail[i]) / sqrt(k)``, which keeps the detail's variance when the
    members' details are uncorrelated (the mean alone divides it by k) without being any one
    member's, and is then tilted linearly so that it runs from 0 to 1.
    """
    smooth = scipy.ndimage.uniform_filter1d(profiles, DETAIL_WINDOW, axis=1, mode="nearest")
    detail = (signs[:, None] * (profiles - smooth)).sum(axis=0) / math.sqrt(len(profiles))
    blended = smooth.mean(axis=0) + detail
    phase = np.linspace(0.0, 1.0, blended.size)
    return blended - blended[0] * (1.0 - phase) - (blended[-1] - 1.0) * phase


def _restored_bandwidth(
    model: StrokeGenerator, shared: StrokeGenerator, groups: list[NDArray[np.int64]]
) -> Array:
    """Return jitter bandwidths that add back the spread the averaging took away, (2,).

    For log length and log size each: ``sqrt(h^2 + var(strokes) - var(groups))``, ``h`` the
    model's bandwidth, ``var(groups)`` the variance of the groups' values weighted by their
    sizes (never below ``h``).
    """
    weights = np.array([group.size for group in groups], dtype=np.float64)
    lost = []
    for own, averaged in (
        (log_length(model.lengths_), log_length(shared.lengths_)),
        (log_size(model.displacements_), log_size(shared.displacements_)),
    ):
        centre = np.average(averaged, weights=weights)
        kept = np.average((averaged - centre) ** 2, weights=weights)
        lost.append(max(0.0, float(own.var()) - float(kept)))
    return np.sqrt(model.bandwidth_**2 + np.array(lost))


def _mean_size(displacements: Array) -> float:
    """Return the size whose `log_size` is the mean of the displacements' (units)."""
    return max(0.0, float(np.exp(log_size(displacements).mean())) - LOG_FLOOR)


def rebuild_errors(model: StrokeGenerator, trials: list[Trial]) -> Array:
    """Return how closely the model's strokes rebuild each stroke of ``trials`` (units, RMS).

    The trials are cut as the fit cuts them (at `model.rate`, reversals beyond
    ``min_reversal``), their first and last strokes left out as the fit leaves them out; each
    stroke's error is the smallest RMS difference between its positions and a model stroke
    placed at that stroke's start, with its displacement and its profile stretched to the
    stroke's length (module docstring).

    Returns
    -------
    ndarray, shape (strokes,)
        One error per stroke of the trials, in their order.
    """
    errors = []
    for trial in trials:
        positions = model.signal(trial)
        edges = reversals(positions, model.min_reversal)
        for first, last in zip(edges[1:-2], edges[2:-1], strict=True):
            stroke = positions[first : last + 1]
            phase = np.linspace(0.0, 1.0, stroke.size)
            rebuilt = (
                np.array([model.profile_at(j, phase) for j in range(model.lengths_.size)])
                * model.displacements_[:, None]
                + model.starts_[:, None]
            )
            errors.append(np.sqrt(np.mean((rebuilt - stroke) ** 2, axis=1)).min())
    return np.array(errors)
