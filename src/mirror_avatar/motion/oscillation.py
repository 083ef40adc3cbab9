"""The oscillation generator: a person's strokes played at a slowly drifting pace, size and centre.

An oscillating hand keeps its pace, its amplitude and its centre for several cycles and lets them
drift; the recorded strokes add noise of their own to each (where the tracker's samples put a
reversal). This generator models each of three series of a trial's strokes as a slow AR(1)
**latent** seen through white noise (`fit_ar1_noise`): the log length (samples), the log half
size ``|D| / 2`` (units) and the midpoint (units), each less its mean over the strokes of its
direction. It generates from the latents alone: stroke ``i`` of direction ``d`` lasts
``exp(mean + x_length)`` samples and ends at ``centre + d * half_size`` (clipped to the playing
range), so that its pace, size and centre follow the fitted drift and its noise (the recording's)
is left out. The stroke's shape (profile) is the one the chain of
`mirror_avatar.motion.strokes` draws (METHODS section 4b), stretched to that length and size.

`choose_kind` picks, per person, between the chain and this generator by cross-validation among
the fitted trials only (METHODS section 4b, "A second generator kind for oscillating motion").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Self

import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from mirror_avatar.files.trials import PLAYING_RANGE, Trial
from mirror_avatar.motion.strokes import Seed, StrokeGenerator, log_length, log_size, reversals
from mirror_avatar.motion.strokes import _room_ahead as _room
from mirror_avatar.signatures.likeness import classifier_test, trial_velocity

Array = NDArray[np.float64]

SERIES = ("log length", "log half size", "midpoint")
"""The per-stroke series whose slow latents the oscillation generator fits, in order."""

MAX_PHI = 0.999
"""Largest AR(1) coefficient the fit allows (the latent stays stationary)."""


def ar1_noise_loglik(series: Sequence[Array], phi: float, q: float, r: float) -> float:
    """Log-likelihood of zero-mean series under an AR(1) latent seen through white noise.

    ``x[t] = phi x[t-1] + e[t]``, ``e ~ N(0, q)``; ``y[t] = x[t] + w[t]``, ``w ~ N(0, r)``;
    each series starts from the stationary latent (variance ``q / (1 - phi^2)``) and is
    independent of the others. The Kalman filter's prediction-error decomposition (Durbin &
    Koopman, "Time series analysis by state space methods", 2012, section 7.2), run over the
    series side by side.
    """
    longest = max(len(y) for y in series)
    values = np.zeros((len(series), longest))
    present = np.zeros((len(series), longest), dtype=bool)
    for row, y in enumerate(series):
        values[row, : len(y)] = y
        present[row, : len(y)] = True
    mean = np.zeros(len(series))
    variance = q / (1.0 - phi * phi)
    total = 0.0
    for t in range(longest):
        innovation_variance = variance + r
        innovation = values[:, t] - mean
        here = present[:, t]
        total -= 0.5 * float(
            np.sum(
                np.log(2 * math.pi * innovation_variance)
                + innovation[here] ** 2 / innovation_variance
            )
        )
        gain = variance / innovation_variance
        mean = phi * (mean + gain * innovation)
        variance = phi * phi * variance * (1.0 - gain) + q
    return total


def fit_ar1_noise(series: Sequence[Array]) -> Array:
    """Maximum-likelihood ``(phi, q, r)`` of `ar1_noise_loglik` for zero-mean series, shape (3,).

    ``phi`` within ``[0, MAX_PHI]`` (a slow latent: a series whose neighbours anticorrelate is
    read as noise about a steady latent), ``q`` and ``r`` the latent's innovation variance and
    the noise variance (the series' units squared). Started from the moments: the lag-2 over the
    lag-1 autocovariance for ``phi``, the lag-1 autocovariance over ``phi`` for the latent's
    variance, the rest of the variance for the noise.
    """
    arrays = [np.asarray(y, dtype=np.float64) for y in series if len(y) > 2]
    variance = max(float(np.mean(np.concatenate(arrays) ** 2)), 1e-12)
    lag1, lag2 = (
        sum(float(np.dot(y[:-h], y[h:])) for y in arrays) / sum(y.size - h for y in arrays)
        for h in (1, 2)
    )
    phi0 = min(max(lag2 / lag1 if lag1 > 0 else 0.5, 0.05), 0.95)
    share = min(max(lag1 / phi0 / variance, 0.05), 0.95)
    start = np.array(
        [math.log(phi0 / (MAX_PHI - phi0)), math.log(share * (1 - phi0**2)), math.log(1 - share)]
    )

    def cost(theta: Array) -> float:
        phi = MAX_PHI / (1.0 + math.exp(-theta[0]))
        q, r = variance * math.exp(theta[1]), variance * math.exp(theta[2])
        return -ar1_noise_loglik(arrays, phi, q, r)

    bounds = [(-12.0, 12.0), (-25.0, 3.0), (-25.0, 3.0)]
    theta = scipy.optimize.minimize(cost, start, method="L-BFGS-B", bounds=bounds).x
    return np.array(
        [
            MAX_PHI / (1.0 + math.exp(-theta[0])),
            variance * math.exp(theta[1]),
            variance * math.exp(theta[2]),
        ]
    )


def stroke_series(positions: Array, min_reversal: float) -> tuple[Array, Array]:
    """Return a trial's strokes as rows (log length, log half size, midpoint), their directions.

    The trial's first and last strokes are left out (cut short by its ends); shapes (m, 3), (m,).
    """
    edges = reversals(positions, min_reversal)[1:-1]
    if edges.size < 2:
        return np.empty((0, 3)), np.empty(0)
    ends = positions[edges]
    displacement = np.diff(ends)
    rows = np.column_stack(
        [
            log_length(np.diff(edges).astype(np.float64)),
            log_size(displacement / 2),
            (ends[:-1] + ends[1:]) / 2,
        ]
    )
    return rows, np.sign(displacement)


class OscillationGenerator(StrokeGenerator):
    """Chain a person's stroke shapes at a pace, size and centre drifting as slow AR(1) latents.

    Parameters as `StrokeGenerator` (module docstring).

    Attributes
    ----------
    means_ : ndarray, shape (2, 3)
        Mean log length, log half size and midpoint of the strokes moving down (row 0) and up.
    latents_ : ndarray, shape (3, 3)
        Per series of `SERIES`, the fitted ``(phi, q, r)`` of `fit_ar1_noise`.
    """

    means_: Array
    latents_: Array
    noise = 0.0

    def fit(self, trials: Sequence[Trial]) -> Self:
        """Cut the trials into strokes (`StrokeGenerator.fit`) and fit the three latents."""
        super().fit(trials)
        cut = [stroke_series(self.signal(t), self.min_reversal) for t in trials]
        rows = np.concatenate([r for r, _ in cut])
        directions = np.concatenate([d for _, d in cut])
        self.means_ = np.stack(
            [
                rows[directions == d].mean(axis=0) if np.any(directions == d) else rows.mean(axis=0)
                for d in (-1.0, 1.0)
            ]
        )
        centred = [r - self.means_[(d > 0).astype(int)] for r, d in cut if len(r)]
        self.latents_ = np.stack([fit_ar1_noise([c[:, j] for c in centred]) for j in range(3)])
        return self

    def sample_positions(self, n_samples: int, random_state: Seed = None) -> Array:
        """Generate ``n_samples`` positions at `rate` (units, within the playing range)."""
        self._check_fitted()
        rng = np.random.default_rng(self.random_state if random_state is None else random_state)
        positions = np.empty(n_samples)
        phi, q = self.latents_[:, 0], self.latents_[:, 1]
        latent = rng.standard_normal(3) * np.sqrt(q / (1.0 - phi**2))
        stroke = int(rng.integers(self.lengths_.size))
        position = float(self.starts_[stroke])
        direction = float(np.sign(self.displacements_[stroke])) or 1.0
        low, high = PLAYING_RANGE
        time, filled = None, 0
        while filled < n_samples:
            mean = self.means_[int(direction > 0)]
            seen = latent + self.noise * rng.standard_normal(3) * np.sqrt(self.latents_[:, 2])
            length = max(math.exp(mean[0] + seen[0]), 1.0)
            end = mean[2] + seen[2] + direction * math.exp(mean[1] + seen[1])
            end = min(max(end, low), high)
            if (end - position) * direction <= 0:
                end = position
            if time is None:
                time = -rng.random() * length
            filled = self._draw_stroke(
                positions, filled, time, length, position, end - position, stroke
            )
            size = abs(end - position)
            position, time = end, time + length
            stroke = self._next_stroke(length, size, position, -direction, rng)
            direction = -direction
            latent = phi * latent + rng.standard_normal(3) * np.sqrt(q)
        return np.clip(positions, low, high)


def choose_kind(
    trials: Sequence[Trial], settings: dict[str, Any] | None = None, rate: float = 100.0
) -> str:
    """Return ``"strokes"`` or ``"oscillation"``, the kind the fitted trials tell apart less.

    Leave one trial out: each kind is fitted on the other trials and generates two trials as
    long as the left-out one (seeds 1 and 2); the classifier of METHODS section 3 (its
    cross-validated AUC, no permutations) tells its windows from the left-out trial's. The kind
    with the lower mean AUC over the left-out trials wins (the chain on a tie).
    """
    settings = settings or {}
    scores = {}
    for kind, cls in (("strokes", StrokeGenerator), ("oscillation", OscillationGenerator)):
        aucs = []
        for left in range(len(trials)):
            model = cls(random_state=0, **settings).fit(
                [t for k, t in enumerate(trials) if k != left]
            )
            n = round(trials[left].duration * rate) + 1
            generated = [model.sample_velocity(n, seed) for seed in (1, 2)]
            aucs.append(
                classifier_test([trial_velocity(trials[left], rate)], generated, rate, 1).auc
            )
        scores[kind] = float(np.mean(aucs))
    return "oscillation" if scores["oscillation"] < scores["strokes"] else "strokes"


def smooth_ar1_noise(y: Array, phi: float, q: float, r: float) -> Array:
    """Kalman-smoothed latent of one zero-mean series under `ar1_noise_loglik`'s model, (n,).

    The Rauch-Tung-Striebel smoother (Durbin & Koopman 2012, section 4.4).
    """
    n = y.size
    predicted_mean, predicted_var = np.zeros(n), np.zeros(n)
    filtered_mean, filtered_var = np.zeros(n), np.zeros(n)
    mean, variance = 0.0, q / (1.0 - phi * phi)
    for t in range(n):
        predicted_mean[t], predicted_var[t] = mean, variance
        gain = variance / (variance + r) if variance + r > 0 else 0.0
        filtered_mean[t] = mean + gain * (y[t] - mean)
        filtered_var[t] = variance * (1.0 - gain)
        mean, variance = phi * filtered_mean[t], phi * phi * filtered_var[t] + q
    smoothed = filtered_mean.copy()
    for t in range(n - 2, -1, -1):
        back = filtered_var[t] * phi / predicted_var[t + 1] if predicted_var[t + 1] > 0 else 0.0
        smoothed[t] = filtered_mean[t] + back * (smoothed[t + 1] - predicted_mean[t + 1])
    return smoothed


class LatentChainGenerator(OscillationGenerator):
    """The chain, its next stroke drawn also by its smoothed latents' nearness to simulated ones."""

    def fit(self, trials: Sequence[Trial]) -> Self:
        """Fit the latents (`OscillationGenerator.fit`) and smooth them at each drawable stroke."""
        super().fit(trials)
        cut = [stroke_series(self.signal(t), self.min_reversal) for t in trials]
        smoothed = []
        for rows, directions in cut:
            if not len(rows):
                continue
            centred = rows - self.means_[(directions > 0).astype(int)]
            smoothed.append(
                np.column_stack(
                    [smooth_ar1_noise(centred[:, j], *self.latents_[j]) for j in range(3)]
                )
            )
        states = np.concatenate(smoothed)
        assert states.shape[0] == self.lengths_.size, (states.shape, self.lengths_.size)
        stationary = self.latents_[:, 1] / (1.0 - self.latents_[:, 0] ** 2)
        total = stationary + self.latents_[:, 2]
        self._used = stationary > 0.05 * total
        self._states = states
        self._state_scale = np.maximum(states.std(axis=0), 1e-9)
        return self

    def sample_positions(self, n_samples: int, random_state: Seed = None) -> Array:
        """Generate ``n_samples`` positions (units): the chain, the latents simulated alongside."""
        rng = np.random.default_rng(self.random_state if random_state is None else random_state)
        phi, q = self.latents_[:, 0], self.latents_[:, 1]
        self._latent_rng = np.random.default_rng(rng.integers(2**63))
        self._latent = self._latent_rng.standard_normal(3) * np.sqrt(q / (1.0 - phi**2))
        return StrokeGenerator.sample_positions(self, n_samples, rng)

    def _next_stroke(self, length, size, position, direction, rng):
        phi, q = self.latents_[:, 0], self.latents_[:, 1]
        self._latent = phi * self._latent + self._latent_rng.standard_normal(3) * np.sqrt(q)
        state = np.array([log_length(length), log_size(size), _room(position, direction)])
        distance = (((self._features - state) / self._scale) ** 2).sum(axis=1)
        distance += ((((self._states - self._latent) / self._state_scale) ** 2)[:, self._used]).sum(
            axis=1
        )
        distance[self._other_way[direction]] = np.inf
        k = min(self._k, int(np.isfinite(distance).sum())) or self._k
        nearest = np.argpartition(distance, k - 1)[:k]
        nearest = nearest[np.argsort(distance[nearest], kind="stable")]
        return int(nearest[np.searchsorted(self._rank_cdf(k), rng.random(), side="right")])
