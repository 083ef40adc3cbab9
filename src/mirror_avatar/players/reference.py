"""Reference velocities: the motion a player draws from its own motor signature (METHODS section 5).

A virtual trainer (and a cyber player with reference features) takes its reference velocity r_s
from an IMS generator or a recorded trial, on the control grid ``k * period``.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.seeds import entropy_of
from mirror_avatar.trials import Trial

REFERENCE_BLOCK = 65.0
"""Seconds of reference velocity a player draws from its generator at a time."""

Array = NDArray[np.float64]


class VelocitySource(Protocol):
    """Anything a reference velocity is drawn from.

    An `mirror_avatar.generator.IMSGenerator`, or a curriculum stage's motion
    (`mirror_avatar.curriculum.StageMotion`).
    """

    rate: float

    def sample_velocity(
        self, n_samples: int, random_state: int | np.random.Generator | None = None
    ) -> Array:
        """Generate ``n_samples`` of velocity (units/s) at `rate`."""
        ...


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
    times = np.arange(n_steps) * period
    if isinstance(reference, Trial):
        trial = reference
        offsets = trial.times - trial.times[0]
        return np.interp(np.mod(times, offsets[-1]), offsets, trial.velocity())
    rate = float(reference.rate)
    block = int(round(REFERENCE_BLOCK * rate))
    n_samples = int(math.ceil(times[-1] * rate)) + 2 if n_steps > 1 else 2
    blocks = [reference.sample_velocity(block, rng) for _ in range(-(-n_samples // block))]
    velocity = np.concatenate(blocks)
    return np.interp(times, np.arange(velocity.size) / rate, velocity)


class ReferenceTrack:
    """A player's reference velocity at the control times ``k * period``, drawn from one seed.

    Drawn with `draw_reference` in blocks of `REFERENCE_BLOCK` seconds and extended (by doubling,
    the same values as one longer draw) when a step runs past its end, so a session of any
    length has a reference.

    Parameters
    ----------
    reference
        An `IMSGenerator` or a recorded `Trial`.
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
