"""Reference velocities: the motion a player draws from its own motor signature (METHODS section 5).

A virtual trainer (and a cyber player with reference features) takes its reference velocity r_s
from a motion model (stroke or IMS generator) or a recorded trial, on the control grid
``k * period``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mirror_avatar.common.seeds import entropy_of
from mirror_avatar.files.trials import Trial

REFERENCE_BLOCK = 65.0
"""Seconds of reference velocity a player draws from its generator at a time."""

Array = NDArray[np.float64]


class VelocitySource(Protocol):
    """Anything a reference velocity is drawn from.

    A motion model (`mirror_avatar.motion.strokes.StrokeGenerator` or
    `mirror_avatar.motion.generator.IMSGenerator`), or a curriculum stage's motion
    (`mirror_avatar.training.curriculum.StageMotion`).
    """

    rate: float

    def sample_velocities(
        self, n_samples: int, random_states: Sequence[np.random.Generator]
    ) -> Array:
        """Generate ``n_samples`` of velocity (units/s) at `rate` from each random state.

        Returns shape (len(random_states), n_samples); row j draws only from
        ``random_states[j]``.
        """
        ...


RandomState = int | np.random.Generator | None


@dataclass(frozen=True, eq=False)
class ReferenceDraw:
    """A reference velocity to draw: what `draw_reference` would be called with.

    Player plans hold draws rather than drawn references, so that the batch engine draws all
    of a chunk's references together (`draw_references`).

    Attributes
    ----------
    source
        A motion model (any `VelocitySource`) or a recorded `Trial`.
    n_steps
        Control steps to draw.
    period
        Control period (s).
    random_state
        Seed or generator of the draw (as `numpy.random.default_rng` takes it).
    """

    source: VelocitySource | Trial
    n_steps: int
    period: float
    random_state: RandomState


def draw_reference(
    reference: VelocitySource | Trial,
    n_steps: int,
    period: float,
    rng: np.random.Generator,
) -> Array:
    """Draw the reference velocity r_s at the control times ``k * period``, k < n_steps.

    A generator's velocity samples (at its own rate) are drawn from ``rng`` in consecutive blocks
    of `REFERENCE_BLOCK` seconds and interpolated linearly onto the control grid, so a longer
    draw from the same seed extends a shorter one. A recorded trial's velocity is interpolated
    the same way and repeats from its start when the session outlasts it.

    Returns
    -------
    numpy.ndarray
        Reference velocity (units/s), shape (n_steps,).
    """
    return draw_references([ReferenceDraw(reference, n_steps, period, rng)])[0]


def draw_references(draws: Sequence[ReferenceDraw]) -> list[Array]:
    """Draw many references, each as `draw_reference` draws it alone.

    The draws from one source with the same steps and period are drawn together: the source
    generates their velocity blocks side by side (`VelocitySource.sample_velocities`, which
    filters them in one pass), each from its own random state.

    Returns
    -------
    list of numpy.ndarray
        One reference velocity (units/s) per draw, shape (draw.n_steps,).
    """
    drawn: list[Array] = [np.empty(0)] * len(draws)
    together: dict[tuple[int, int, float], tuple[VelocitySource, list[int]]] = {}
    for i, draw in enumerate(draws):
        if isinstance(draw.source, Trial):
            drawn[i] = _trial_reference(draw.source, draw.n_steps, draw.period)
        else:
            key = (id(draw.source), draw.n_steps, draw.period)
            together.setdefault(key, (draw.source, []))[1].append(i)
    for (_, n_steps, period), (source, indices) in together.items():
        rngs = [np.random.default_rng(draws[i].random_state) for i in indices]
        references = _generated_references(source, n_steps, period, rngs)
        for i, reference in zip(indices, references, strict=True):
            drawn[i] = reference
    return drawn


def _trial_reference(trial: Trial, n_steps: int, period: float) -> Array:
    times = np.arange(n_steps) * period
    offsets = trial.times - trial.times[0]
    return np.interp(np.mod(times, offsets[-1]), offsets, trial.velocity())


def _generated_references(
    source: VelocitySource, n_steps: int, period: float, rngs: Sequence[np.random.Generator]
) -> list[Array]:
    times: Array = np.arange(n_steps, dtype=np.float64) * period
    rate = float(source.rate)
    block = int(round(REFERENCE_BLOCK * rate))
    n_samples = int(math.ceil(times[-1] * rate)) + 2 if n_steps > 1 else 2
    blocks = [source.sample_velocities(block, rngs) for _ in range(-(-n_samples // block))]
    velocities = blocks[0] if len(blocks) == 1 else np.concatenate(blocks, axis=1)
    grid = np.arange(velocities.shape[1], dtype=np.float64) / rate
    return list(interpolate_rows(times, grid, rate, velocities))


@njit(cache=True, nogil=True)
def interpolate_rows(times: Array, grid: Array, rate: float, values: Array) -> Array:
    """`interpolate_on_grid` of each row of ``values`` (L, n): shape (L, m), in one call."""
    out = np.empty((values.shape[0], times.size))
    for j in range(values.shape[0]):
        out[j] = interpolate_on_grid(times, grid, rate, values[j])
    return out


@njit(cache=True, nogil=True)
def interpolate_on_grid(times: Array, grid: Array, rate: float, values: Array) -> Array:
    """`numpy.interp` of ``values`` sampled on the uniform ``grid`` (``i / rate``), compiled.

    Each time's interval is found from ``time * rate`` and checked against ``grid``, then
    interpolated with `numpy.interp`'s arithmetic (bit for bit); times beyond the grid take
    the end values.

    Parameters
    ----------
    times
        Where to interpolate (s), shape (m,).
    grid
        The sample times ``arange(n) / rate`` (s), shape (n,), n >= 2.
    rate
        Sampling rate of ``values`` (Hz).
    values
        Samples, shape (n,).

    Returns
    -------
    numpy.ndarray
        Shape (m,).
    """
    n = grid.size
    out = np.empty(times.size)
    for i in range(times.size):
        t = times[i]
        if t >= grid[n - 1]:
            out[i] = values[n - 1]
            continue
        if t < grid[0]:
            out[i] = values[0]
            continue
        j = min(max(int(t * rate), 0), n - 2)
        while grid[j] > t:
            j -= 1
        while grid[j + 1] <= t:
            j += 1
        if grid[j] == t:
            out[i] = values[j]
            continue
        slope = (values[j + 1] - values[j]) / (grid[j + 1] - grid[j])
        out[i] = slope * (t - grid[j]) + values[j]
    return out


class ReferenceTrack:
    """A player's reference velocity at the control times ``k * period``, drawn from one seed.

    Drawn with `draw_reference` in blocks of `REFERENCE_BLOCK` seconds and extended (by doubling,
    the same values as one longer draw) when a step runs past its end, so a session of any
    length has a reference.

    Parameters
    ----------
    reference
        A motion model (a stroke or IMS generator, any `VelocitySource`) or a recorded `Trial`.
    period
        Control period (s).
    seed
        Seed of the draw; None draws fresh entropy.

    Attributes
    ----------
    seed : int
        The entropy actually used (replays the same reference).
    """

    def __init__(self, reference: VelocitySource | Trial, period: float, seed: int | None) -> None:
        self.reference = reference
        self.period = period
        self.seed = entropy_of(seed)
        self._values = self._draw(int(round(REFERENCE_BLOCK / period)))

    def _draw(self, n_steps: int) -> Array:
        return draw_reference(
            self.reference, n_steps, self.period, np.random.default_rng(self.seed)
        )

    def __getitem__(self, k: int) -> float:
        """Return the reference velocity (units/s) of control period k (k >= 0)."""
        while k >= self._values.size:
            self._values = self._draw(2 * self._values.size)
        return float(self._values[k])
