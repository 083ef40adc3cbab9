"""Motion between two people: the reference velocity of a rehabilitation curriculum's stages.

METHODS section 10: a patient plays, stage by stage, with an avatar whose motor signature moves
from the patient's to a healthy target person's. `StageMotion` is the motion source of stage
weight w (0: the patient, 1: the target), a drop-in for an `mirror_avatar.generator.IMSGenerator`
as a virtual trainer's reference (it has ``rate`` and ``sample_velocity``). Two methods
(METHODS 10, both measured by `mirror_avatar.experiments.curriculum`):

- ``"mixture"``: the velocity is drawn in blocks of `BLOCK_SECONDS`, each block from the target's
  generator with probability w and from the patient's otherwise. Its IMS is the mixture
  ``(1 - w) IMS_patient + w IMS_target``, so its EMD to the patient is w EMD(patient, target) in
  expectation (1-D EMD is the area between CDFs).
- ``"displacement"``: displacement interpolation of the velocity distributions. The patient's
  velocity is drawn and each sample is moved along the monotone map between the two quantile
  functions: ``v -> (1 - w) v + w Q_target(F_patient(v))``, so the stage's quantile function is
  ``(1 - w) Q_patient + w Q_target``, at EMD w EMD(patient, target) from the patient and
  (1 - w) EMD from the target, with the patient's timing and intermediate speeds.

The quantile functions are estimated from `QUANTILE_SECONDS` of each generator's motion drawn
from a fixed seed, on `N_QUANTILES` probabilities.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.errors import InputError
from mirror_avatar.generator import IMSGenerator, Seed

Method = Literal["mixture", "displacement"]
METHODS: tuple[Method, ...] = ("mixture", "displacement")

BLOCK_SECONDS = 5.0
"""Length (s) of each block of a mixture stage's velocity (**choice**: a few strokes)."""

QUANTILE_SECONDS = 600.0
"""Seconds of each generator's motion its quantile function is estimated from (**choice**)."""

N_QUANTILES = 2001
"""Probabilities, evenly spaced on [0, 1], the quantile functions are tabulated at."""

QUANTILE_SEED = 0
"""Seed of the motion the quantile functions are estimated from."""

Array = NDArray[np.float64]


class StageMotion:
    """The motion source of one curriculum stage, between a patient's and a target's generators.

    Parameters
    ----------
    patient, target
        Fitted generators of the same rate.
    weight
        w in [0, 1]: 0 moves as the patient, 1 as the target.
    method
        ``"mixture"`` or ``"displacement"`` (module docstring).

    Raises
    ------
    InputError
        A weight outside [0, 1], an unknown method, or generators of different rates.
    """

    def __init__(
        self, patient: IMSGenerator, target: IMSGenerator, weight: float, method: Method
    ) -> None:
        if not 0.0 <= weight <= 1.0:
            raise InputError("stage", f"weight {weight:g} is outside [0, 1]")
        if method not in METHODS:
            raise InputError("stage", f"method {method!r} is not one of {', '.join(METHODS)}")
        if not math.isclose(patient.rate, target.rate):
            raise InputError("stage", "the patient's and the target's generators differ in rate")
        self.patient, self.target = patient, target
        self.weight, self.method = float(weight), method
        self.rate = float(patient.rate)
        if method == "displacement":
            self._patient_quantiles = _quantiles(patient)
            self._target_quantiles = _quantiles(target)

    def sample_velocity(self, n_samples: int, random_state: Seed = None) -> Array:
        """Generate ``n_samples`` of the stage's velocity at `rate` (units/s)."""
        rng = np.random.default_rng(random_state)
        if self.method == "mixture":
            return self._mixture(n_samples, rng)
        velocity = self.patient.sample_velocity(n_samples, rng)
        probabilities = np.linspace(0.0, 1.0, N_QUANTILES)
        rank = np.interp(velocity, self._patient_quantiles, probabilities)
        moved = np.interp(rank, probabilities, self._target_quantiles)
        return (1.0 - self.weight) * velocity + self.weight * moved

    def _mixture(self, n_samples: int, rng: np.random.Generator) -> Array:
        block = max(1, int(round(BLOCK_SECONDS * self.rate)))
        blocks = []
        for _ in range(-(-n_samples // block)):
            source = self.target if rng.random() < self.weight else self.patient
            blocks.append(source.sample_velocity(block, rng))
        return np.concatenate(blocks)[:n_samples]


def _quantiles(generator: IMSGenerator) -> Array:
    """Tabulate a generator's velocity quantile function at `N_QUANTILES` probabilities."""
    n_samples = int(round(QUANTILE_SECONDS * generator.rate))
    velocity = generator.sample_velocity(n_samples, QUANTILE_SEED)
    return np.quantile(velocity, np.linspace(0.0, 1.0, N_QUANTILES))
