"""Data-copying: whether generated motion sits closer to its training trials than fresh motion.

METHODS section 3, data-copying. The three-sample test of Meehan, Chaudhuri & Dasgupta, "A
Non-Parametric Test to Detect Data-Copying in Generative Models" (AISTATS 2020, arXiv
2004.05675). A generator fitted on a person's **training** trials makes **generated** trials; the
person's **held-out** trials (same distribution, unseen by the generator) show how near fresh motion
comes to the training trials by chance. The points of the test are short windows of velocity
(`motion_windows`); each window's distance to its nearest training window is measured; the space is
cut into cells by k-means on the training windows; in each cell a Mann-Whitney U test compares the
generated windows' distances with the held-out windows', Z-scored under the null of one
distribution (`mann_whitney_z`); the cells' Z scores, weighted by the held-out windows' share of
each cell, average into the statistic C_T. Under the null C_T is about standard normal or
narrower; C_T far below 0 says the generated windows sit closer to the training windows than
fresh windows do: the generator copies.

Where this follows the paper: the statistic (Z_U per cell, C_T weighted by the held-out mass
P_n(pi) over the cells kept), the cells (k-means on the training set, as their experiments), the
cells kept (at least tau = 20 / m of the generated mass, i.e. 20 generated windows, as their
experiments). The threshold, C_T < -3, is a **choice** (`THRESHOLD`): the paper reads a C_T
well below 0 as data-copying.

Where it departs: the points are overlapping windows of whole trials, not independent draws (on
simulated motion, four one-minute trials a set and 60 seeds, the cells' Z still had SD 1.00 under
the null, and C_T, averaging five cells, SD 0.40: -3 is a strict threshold); the training windows
are taken every 0.1 s rather than every second, so that a copied stretch of a training trial
finds a training window within 0.05 s of its own phase whatever its start (with training windows
every second, copies shifted by 0.2-0.5 s gave C_T near 0); each window's nearest training window
is searched among all of them (the paper's L(x) = d(x, T)), not only among the cell's as in the
authors' code; and Z_U has no continuity correction but the tie-corrected variance.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.signal
import scipy.spatial
import scipy.stats
from numpy.typing import NDArray
from sklearn.cluster import KMeans

from mirror_avatar.common.errors import InputError

Array = NDArray[np.float64]

WINDOW_SECONDS = 2.0
"""Length of a window (s) (**choice**: one or two strokes of the fast style, about 1 Hz, and
short enough that a minute of motion gives ~59 points)."""

HOP_SECONDS = 1.0
"""Held-out and generated windows start every second (**choice**: half a window)."""

WINDOW_RATE = 10.0
"""Rate (Hz) a window's velocity is decimated to: 20 numbers a window (**choice**: hand motion has
little power above 4 Hz, and nearest-neighbour distances lose meaning in many dimensions)."""

TRAINING_HOP_SECONDS = 1.0 / WINDOW_RATE
"""Training windows start at every decimated sample (**departure**, see the module's text)."""

LOW_PASS_HZ = 4.0
"""Cut-off (Hz) of the anti-aliasing low-pass before decimation (order-8 Butterworth, run forwards
and backwards: about -31 dB at the 5 Hz Nyquist frequency of `WINDOW_RATE`)."""

LOW_PASS_ORDER = 8
"""Order of the anti-aliasing Butterworth filter."""

MIN_GENERATED_WINDOWS = 20
"""Fewest generated windows a cell needs to count: the paper's tau = 20 / m."""

WINDOWS_PER_CELL = 40
"""The default number of cells gives each cell about this many held-out and generated windows
on average (**choice**: twice `MIN_GENERATED_WINDOWS`, so that uneven cells still count)."""

MAX_CELLS = 10
"""Most cells the default rule makes (**choice**: the paper used 5 cells for 2-d moons and 20 to
50 for MNIST embeddings)."""

THRESHOLD = -3.0
"""C_T below this is data-copying (**choice**: C_T is a weighted sum of Z scores, SD about 1
under the null; the paper reads a C_T well below 0 as data-copying and this package asks for
three SDs)."""

K_MEANS_RESTARTS = 4
"""Restarts of k-means (k-means++ seeding), the best kept (**choice**)."""


def motion_windows(velocity: Array, rate: float, hop: float = HOP_SECONDS) -> Array:
    """Windows of a velocity signal, low-passed and decimated: the points of the test.

    The signal is low-passed (`LOW_PASS_HZ`, zero phase), sampled at `WINDOW_RATE` Hz from its
    first sample on, and cut into windows of `WINDOW_SECONDS` starting every ``hop`` seconds
    (rounded to a whole number of decimated samples); a trial of 60 s at 100 Hz gives 59 windows
    at the default hop.

    Parameters
    ----------
    velocity
        Velocity (units/s), shape (n,), sampled uniformly at ``rate``.
    rate
        Sampling rate (Hz), above twice `LOW_PASS_HZ`.
    hop
        Time (s) between the starts of consecutive windows (`HOP_SECONDS`; the training windows
        use `TRAINING_HOP_SECONDS`).

    Returns
    -------
    numpy.ndarray
        Shape (k, d) with d = `WINDOW_SECONDS` x `WINDOW_RATE` = 20: each row a window's velocity
        (units/s); k = 0 when the signal is shorter than a window.
    """
    signal = np.asarray(velocity, dtype=np.float64)
    if signal.ndim != 1:
        raise InputError(None, f"a velocity signal must be one-dimensional, not {signal.shape}")
    if not rate > 2 * LOW_PASS_HZ:
        raise InputError(None, f"a rate of {rate} Hz is too low for {LOW_PASS_HZ:g} Hz windows")
    if not np.isfinite(signal).all():
        raise InputError(None, "a velocity signal has missing or infinite samples")
    size = round(WINDOW_SECONDS * WINDOW_RATE)
    step = max(1, round(hop * WINDOW_RATE))
    duration = (signal.size - 1) / rate if signal.size else -1.0
    n_decimated = math.floor(duration * WINDOW_RATE + 1e-9) + 1
    if n_decimated < size:
        return np.empty((0, size))
    sos = scipy.signal.butter(LOW_PASS_ORDER, LOW_PASS_HZ, fs=rate, output="sos")
    smooth = scipy.signal.sosfiltfilt(sos, signal)
    decimated = np.interp(
        np.arange(n_decimated) / WINDOW_RATE, np.arange(signal.size) / rate, smooth
    )
    windows = np.lib.stride_tricks.sliding_window_view(decimated, size)[::step]
    return np.ascontiguousarray(windows)


def nearest_distances(points: Array, training: Array) -> Array:
    """Distance of each point to its nearest training point, shape (k,).

    Reported as the root-mean-square velocity difference (units/s): the Euclidean distance over
    the square root of the dimension, which orders neighbours alike.
    """
    if points.shape[0] == 0:
        return np.empty(0)
    distances, _ = scipy.spatial.cKDTree(training).query(points, k=1)
    return np.asarray(distances, dtype=np.float64) / math.sqrt(training.shape[1])


def mann_whitney_z(generated: Array, held_out: Array) -> float:
    """Z score of the Mann-Whitney U of ``generated`` against ``held_out`` (the paper's Z_U).

    U counts the pairs (generated, held-out) whose generated value is the larger (ties count
    half); Z = (U - m n / 2) / sigma with the tie-corrected sigma of U under the null, no
    continuity correction. Negative: the generated values are smaller.

    Parameters
    ----------
    generated, held_out
        Shapes (m,) and (n,), both non-empty.
    """
    m, n = generated.size, held_out.size
    pooled = np.concatenate([generated, held_out])
    u = scipy.stats.rankdata(pooled)[:m].sum() - m * (m + 1) / 2
    _, counts = np.unique(pooled, return_counts=True)
    ties = float((counts**3 - counts).sum()) / ((m + n) * (m + n - 1)) if m + n > 1 else 0.0
    variance = m * n / 12 * (m + n + 1 - ties)
    return float((u - m * n / 2) / math.sqrt(variance)) if variance > 0 else 0.0


def default_cells(n_held_out: int, n_generated: int) -> int:
    """Cells of the default partition (between 1 and `MAX_CELLS`).

    One per `WINDOWS_PER_CELL` windows of the smaller of the held-out and generated sets: a
    minute of each (59 windows) makes one cell, four minutes five, eight minutes ten.
    """
    return int(np.clip(min(n_held_out, n_generated) // WINDOWS_PER_CELL, 1, MAX_CELLS))


@dataclass(frozen=True)
class CopyingTest:
    """The data-copying test: C_T, its cells, and the distances it ranks.

    Attributes
    ----------
    c_t
        The statistic: the cells' Z scores averaged with the held-out mass as weights, over the
        cells kept (`cell_used`). About N(0, 1) or narrower under the null; negative when the
        generated windows are nearer the training windows than the held-out ones.
    cell_z
        Mann-Whitney Z of each cell, shape (n_cells,) (NaN where a cell has no held-out or no
        generated window).
    cell_held_out_mass, cell_generated_mass
        Share of the held-out (P_n(pi)) and generated (Q_m(pi)) windows in each cell.
    cell_used
        Whether each cell counts: at least ``tau`` of the generated mass and a held-out window.
    median_held_out_distance, median_generated_distance
        Median distance (RMS velocity difference, units/s) of the held-out and of the generated
        windows to their nearest training window.
    n_windows
        Windows of the training, held-out and generated sets.
    tau
        The generated mass a cell needs (`MIN_GENERATED_WINDOWS` over the generated windows).
    threshold
        C_T below this is data-copying (`THRESHOLD`).
    seed
        Seed of k-means.
    """

    c_t: float
    cell_z: tuple[float, ...]
    cell_held_out_mass: tuple[float, ...]
    cell_generated_mass: tuple[float, ...]
    cell_used: tuple[bool, ...]
    median_held_out_distance: float
    median_generated_distance: float
    n_windows: tuple[int, int, int]
    tau: float
    threshold: float
    seed: int

    @property
    def n_cells(self) -> int:
        """Cells of the partition."""
        return len(self.cell_z)

    @property
    def cells_used(self) -> int:
        """Cells that count in C_T."""
        return sum(self.cell_used)

    @property
    def distance_ratio(self) -> float:
        """Median generated over median held-out distance to the training windows."""
        if self.median_held_out_distance > 0:
            return self.median_generated_distance / self.median_held_out_distance
        return math.inf if self.median_generated_distance > 0 else 1.0

    @property
    def copying(self) -> bool:
        """Whether C_T is below the threshold: data-copying."""
        return self.c_t < self.threshold

    def verdict(self) -> str:
        """One line: ``data-copying: C_T = -8.1 (...)`` or ``no data-copying: C_T = 0.4 (...)``."""
        words = "data-copying" if self.copying else "no data-copying"
        if self.copying:
            relation, tail = "closer to", ""
        elif self.c_t >= 0:
            relation, tail = "no closer to", ""
        else:
            relation, tail = "not significantly closer to", f", threshold {self.threshold:g}"
        return (
            f"{words}: C_T = {self.c_t:.1f} (generated windows {relation} the training trials "
            f"than held-out windows{tail}: median distance {self.distance_ratio:.2f} x)"
        )

    def to_json_dict(self) -> dict[str, Any]:
        """Return the numbers and the verdict (NaN Z scores as None)."""
        return {
            "c_t": self.c_t,
            "copying": self.copying,
            "threshold": self.threshold,
            "tau": self.tau,
            "n_cells": self.n_cells,
            "cells_used": self.cells_used,
            "cell_z": [None if math.isnan(z) else z for z in self.cell_z],
            "cell_held_out_mass": list(self.cell_held_out_mass),
            "cell_generated_mass": list(self.cell_generated_mass),
            "cell_used": list(self.cell_used),
            "median_held_out_distance": self.median_held_out_distance,
            "median_generated_distance": self.median_generated_distance,
            "distance_ratio": self.distance_ratio,
            "n_windows": dict(
                zip(("training", "held_out", "generated"), self.n_windows, strict=True)
            ),
            "seed": self.seed,
            "verdict": self.verdict(),
        }


def _stack(signals: Sequence[Array], rate: float, hop: float, name: str) -> Array:
    windows = [motion_windows(s, rate, hop) for s in signals]
    stacked = np.concatenate(windows) if windows else np.empty((0, 0))
    if stacked.shape[0] == 0:
        raise InputError(
            None, f"the {name} trials are all shorter than a {WINDOW_SECONDS:g} s window"
        )
    return stacked


def copying_test(
    training: Sequence[Array],
    held_out: Sequence[Array],
    generated: Sequence[Array],
    rate: float = 100.0,
    n_cells: int | None = None,
    seed: int = 0,
) -> CopyingTest:
    """Test whether ``generated`` copies ``training``, with ``held_out`` as fresh motion.

    Parameters
    ----------
    training
        Velocity signals (units/s), each shape (n_i,) at ``rate`` Hz, that the generator was
        fitted on; windowed every `TRAINING_HOP_SECONDS`.
    held_out
        The same person's velocity signals the generator never saw; windowed every
        `HOP_SECONDS`.
    generated
        The generator's velocity signals; windowed every `HOP_SECONDS`.
    rate
        Sampling rate (Hz) of every signal.
    n_cells
        Cells of the k-means partition of the training windows (default `default_cells`).
    seed
        Seed of k-means (recorded).

    Returns
    -------
    CopyingTest

    Raises
    ------
    InputError
        When a set has no window, the held-out or generated set has fewer than
        `MIN_GENERATED_WINDOWS` windows, or no cell keeps `MIN_GENERATED_WINDOWS` generated
        windows.
    """
    train = _stack(training, rate, TRAINING_HOP_SECONDS, "training")
    fresh = _stack(held_out, rate, HOP_SECONDS, "held-out")
    made = _stack(generated, rate, HOP_SECONDS, "generated")
    for name, windows in (("held-out", fresh), ("generated", made)):
        if windows.shape[0] < MIN_GENERATED_WINDOWS:
            raise InputError(
                None,
                f"the {name} trials give {windows.shape[0]} windows of {WINDOW_SECONDS:g} s, "
                f"fewer than the {MIN_GENERATED_WINDOWS} a cell needs",
            )
    cells = default_cells(fresh.shape[0], made.shape[0]) if n_cells is None else n_cells
    if not 1 <= cells <= train.shape[0]:
        raise InputError("n_cells", f"{cells} cells for {train.shape[0]} training windows")
    k_means = KMeans(n_clusters=cells, n_init=K_MEANS_RESTARTS, random_state=seed).fit(train)
    fresh_cell, made_cell = k_means.predict(fresh), k_means.predict(made)
    fresh_distance, made_distance = nearest_distances(fresh, train), nearest_distances(made, train)

    z, fresh_mass, made_mass, used = [], [], [], []
    for cell in range(cells):
        a, b = fresh_distance[fresh_cell == cell], made_distance[made_cell == cell]
        z.append(mann_whitney_z(b, a) if a.size and b.size else math.nan)
        fresh_mass.append(a.size / fresh.shape[0])
        made_mass.append(b.size / made.shape[0])
        used.append(b.size >= MIN_GENERATED_WINDOWS and a.size > 0)
    if not any(used):
        raise InputError(
            "n_cells", f"no cell of {cells} holds {MIN_GENERATED_WINDOWS} generated windows"
        )
    weights = np.where(used, fresh_mass, 0.0)
    c_t = float(np.dot(weights, np.where(used, z, 0.0)) / weights.sum())
    return CopyingTest(
        c_t=c_t,
        cell_z=tuple(z),
        cell_held_out_mass=tuple(fresh_mass),
        cell_generated_mass=tuple(made_mass),
        cell_used=tuple(used),
        median_held_out_distance=float(np.median(fresh_distance)),
        median_generated_distance=float(np.median(made_distance)),
        n_windows=(train.shape[0], fresh.shape[0], made.shape[0]),
        tau=MIN_GENERATED_WINDOWS / made.shape[0],
        threshold=THRESHOLD,
        seed=seed,
    )
