"""Motion between two people: the reference velocity of a rehabilitation curriculum's stages.

METHODS section 10: a patient plays, stage by stage, with an avatar whose motor signature moves
from the patient's to a healthy target person's. `StageMotion` is the motion source of stage
weight w (0: the patient, 1: the target), a drop-in for an
`mirror_avatar.motion.generator.IMSGenerator` as a virtual trainer's reference (it has ``rate`` and
``sample_velocity``). Two methods
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

A stage is saved as one ``.npz`` + JSON file (`save_stage`, `load_stage`; format
``mirror-avatar/curriculum-stage``): both generators, the weight and the method. As a player SPEC it
is a virtual trainer with the stage's motion; `StageMotion.sample` gives trials of the stage moving
alone (a virtual trainer without partners, the leader preset), as ``generator sample`` writes them.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import preset
from mirror_avatar.engine.loop import play
from mirror_avatar.files.model_files import (
    check_object,
    check_real,
    join_parts,
    load_model,
    part_arrays,
    save_model,
)
from mirror_avatar.files.trials import Trial, make_trial
from mirror_avatar.motion.generator import IMSGenerator, Seed
from mirror_avatar.players import VirtualTrainer

Method = Literal["mixture", "displacement"]
METHODS: tuple[Method, ...] = ("mixture", "displacement")

BLOCK_SECONDS = 5.0
"""Length (s) of each block of a mixture stage's velocity (**choice**: a few strokes)."""

QUANTILE_SECONDS = 600.0
"""Seconds of each generator's motion its quantile function is estimated from (**choice**)."""

N_QUANTILES = 2001
"""Probabilities, evenly spaced on [0, 1], the quantile functions are tabulated at."""

PROBABILITIES = np.linspace(0.0, 1.0, N_QUANTILES)
"""The probabilities the quantile functions are tabulated at."""

QUANTILE_SEED = 0
"""Seed of the motion the quantile functions are estimated from."""

FORMAT_NAME = "mirror-avatar/curriculum-stage"
FORMAT_VERSION = 1
PEOPLE = ("patient", "target")

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
            raise InputError(
                "stage",
                f"the patient's and the target's generators differ in rate ({patient.rate:g} Hz "
                f"and {target.rate:g} Hz)",
            )
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
        rank = np.interp(velocity, self._patient_quantiles, PROBABILITIES)
        moved = np.interp(rank, PROBABILITIES, self._target_quantiles)
        return (1.0 - self.weight) * velocity + self.weight * moved

    def sample_velocities(self, n_samples: int, random_states: Sequence[Seed]) -> Array:
        """`sample_velocity` from each random state, shape (len(random_states), n_samples)."""
        return np.array([self.sample_velocity(n_samples, r) for r in random_states])

    def sample(self, duration: float, n: int = 1, random_state: Seed = None) -> list[Trial]:
        """Generate trials of the stage moving alone, ``duration`` s each.

        A virtual trainer (leader preset, no partner) tracks the stage's velocity; its positions
        are sampled at the control period's rate.
        """
        seeds = np.random.default_rng(random_state).integers(0, 2**63 - 1, size=n)
        trials = []
        for k, seed in enumerate(seeds):
            player = VirtualTrainer(preset("leader"), self, label="stage")
            session = play([player], duration, int(seed))
            trials.append(
                make_trial(
                    session.times,
                    session.positions[0],
                    label=f"generated-{k + 1}",
                    group="stage",
                    metadata={"seed": int(seed), "index": k},
                )  # fmt: skip
            )
        return trials

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
    return np.quantile(velocity, PROBABILITIES)


def save_stage(motion: StageMotion, path: str | os.PathLike[str], metadata: dict[str, Any]) -> Path:
    """Write a stage to one ``.npz`` file, atomically, with ``metadata`` (stage, plan...)."""
    parts: dict[str, Any] = {}
    info: dict[str, Any] = {"weight": motion.weight, "method": motion.method, "stage": metadata}
    for name, generator in zip(PEOPLE, (motion.patient, motion.target), strict=True):
        parts[name], info[name] = generator.to_arrays()
    return save_model(path, FORMAT_NAME, FORMAT_VERSION, join_parts(parts), info)


def load_stage(path: str | os.PathLike[str]) -> StageMotion:
    """Read a stage written by `save_stage`, checking both generators and the weight."""
    arrays, info = load_model(path, FORMAT_NAME, FORMAT_VERSION, ())
    generators = []
    for name in PEOPLE:
        metadata = check_object(path, name, info.get(name))
        generators.append(IMSGenerator.from_arrays(part_arrays(arrays, name), metadata, path))
    weight = check_real(path, "weight", info.get("weight"), 0.0, 1.0)
    method = info.get("method")
    if method not in METHODS:
        raise InputError(path, f"method is not one of {', '.join(METHODS)}")
    try:
        return StageMotion(generators[0], generators[1], weight, method)
    except InputError as error:
        raise InputError(path, error.problem) from None
