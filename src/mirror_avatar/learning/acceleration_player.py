"""What every learned avatar shares: an HKB end effector driven by one of a set of accelerations.

Every control period T a learned avatar (the tabular `mirror_avatar.learning.agent.CyberPlayer`,
the deep `mirror_avatar.deep.player.DeepCyberPlayer`) observes its own state and its neighbours',
picks one acceleration from its action set with its policy, holds it over T on its own
Haken-Kelso-Bunz end effector (`mirror_avatar.dynamics.integrate_hkb`, a few RK4 substeps) and
reports that control. `AccelerationPlayer` holds what they share: the end effector, the action
set, the start, the optional motion source (a reference velocity drawn at each `reset`, for
avatars that lead) and the velocity counts of the player it learned to imitate. Subclasses give
the policy (`_advance`, `needs_reference`, `_policy_plan`).

The shared parts of their model files are here too: the dynamics parameters
(`read_parameters`) and the motion source (`reference_arrays`, `read_reference`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import fields
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import entropy_of
from mirror_avatar.dynamics import FOLLOWER, HKBParams
from mirror_avatar.files.importing import excerpt
from mirror_avatar.files.model_files import (
    Source,
    check_array,
    check_integer,
    check_real,
    save_model,
)
from mirror_avatar.files.trials import PLAYING_RANGE, Trial
from mirror_avatar.motion.models import MotionModel, model_arrays, motion_from_arrays
from mirror_avatar.players.base import Observation, Player, PlayerPlan
from mirror_avatar.players.reference import ReferenceDraw, ReferenceTrack
from mirror_avatar.signatures.signature import DEFAULT_BINS

Array = NDArray[np.float64]
Agent = Literal["tabular", "dqn"]
"""How a learned avatar chooses: a Q-table or a deep Q-network."""

DEFAULT_ACTIONS = (-4.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 4.0)
"""The 9 accelerations (units/s²) the avatar can choose from (**choice**, METHODS section 7)."""

DEFAULT_SUBSTEPS = 3
"""RK4 substeps per control period of the avatar's end effector (**choice**)."""

MAX_SUBSTEPS = 64
"""Most RK4 substeps per control period (**choice**: 20 times the default; each step's cost grows
with them, and a model file asking for 10^9 would stall every step for most of a minute)."""

MAX_ACTIONS = 64
"""Most actions a player may choose from (**choice**: the default set has 9)."""

MAX_ACCELERATION = 100.0
"""Largest |action| (units/s²) (**choice**: 25 times the default set's largest, 4)."""

REFERENCE_PREFIX = "reference_"
"""Prefix of the reference generator's arrays in a model file."""


class AccelerationPlayer(Player):
    """Base class of the learned avatars (see the module docstring).

    Parameters
    ----------
    actions
        Accelerations (units/s²) to choose from, default `DEFAULT_ACTIONS`.
    params
        The avatar's own end effector (alpha, beta, gamma, omega, eta and period are used; eta
        weighs the control effort in the training reward).
    n_substeps
        RK4 substeps per period.
    initial_position
        Position (units) returned by `reset`; the avatar starts at rest.
    reference
        The avatar's own motion source when its policy reads it (`needs_reference`): a motion
        model (`mirror_avatar.motion.models.MotionModel`, a stroke or IMS generator: a reference
        velocity is drawn at each `reset` from its seed, as a virtual trainer does) or a recorded
        `Trial`.
    label
        A name for the player (recorded in sessions).

    Attributes
    ----------
    training_ : dict
        Summary of how the policy was trained (seed, sessions, hyper-parameters, last scores).
    target_counts_ : ndarray, shape (DEFAULT_BINS.n,)
        Velocity samples of the player it learned to imitate, per bin of the velocity signature
        (`mirror_avatar.signatures.signature.count_velocities`), summed over the training sessions;
        its signature is `target_ims`.
    """

    agent: ClassVar[Agent]
    """How the subclass chooses its action (recorded with it in an avatar's file)."""
    format_name: ClassVar[str]
    format_version: ClassVar[int]
    """Its model file's format (`mirror_avatar.files.model_files`)."""

    training_: dict[str, Any]
    target_counts_: Array
    TRIAL_STATE = ("_k", "_state", "last_control", "last_reference")
    """A successor policy (a personal avatar's other role) keeps its own reference track."""

    def __init__(
        self,
        actions: ArrayLike = DEFAULT_ACTIONS,
        params: HKBParams = FOLLOWER,
        n_substeps: int = DEFAULT_SUBSTEPS,
        initial_position: float = 0.0,
        reference: MotionModel | Trial | None = None,
        label: str = "cyber player",
    ) -> None:
        self.actions = actions
        self.params = params
        self.n_substeps = n_substeps
        self.initial_position = initial_position
        self.reference = reference
        self.label = label
        self.period = params.period
        self.last_control = math.nan
        self.last_reference = math.nan

    @property
    def needs_reference(self) -> bool:
        """True when the policy reads the avatar's own reference velocity."""
        raise NotImplementedError

    @property
    def stochastic(self) -> bool:  # type: ignore[override]
        """True when every `reset` draws a fresh reference from a generator."""
        return self.needs_reference and isinstance(self.reference, MotionModel)

    @property
    def actions_(self) -> Array:
        """The action set as a float array, shape (n_actions,).

        Raises
        ------
        InputError
            Not 1 to `MAX_ACTIONS` finite accelerations within ±`MAX_ACCELERATION`.
        """
        actions = np.asarray(self.actions, dtype=np.float64)
        limit = MAX_ACCELERATION
        check_array("cyber player", "actions", actions, "float", (None,), -limit, limit)
        check_integer("cyber player", "number of actions", actions.size, 1, MAX_ACTIONS)
        return actions

    @property
    def substeps_(self) -> int:
        """RK4 substeps per period, checked against `MAX_SUBSTEPS`."""
        return check_integer("cyber player", "n_substeps", self.n_substeps, 1, MAX_SUBSTEPS)

    def initialise_policy(self, random_state: int | np.random.Generator | None) -> None:
        """Give the avatar a fresh, untrained policy drawn from ``random_state``."""
        raise NotImplementedError

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start a trial at rest at `initial_position`.

        The greedy policy is deterministic; when it reads a reference velocity, that is drawn
        from ``seed`` (fresh entropy if None), otherwise ``seed`` changes nothing.
        """
        self._prepare()
        self._record = self.params.record()
        self._references = self._reference_track(seed)
        self._k = 0
        self._state = (float(self.initial_position), 0.0)
        self.last_control = self.last_reference = math.nan
        return self._state

    def _prepare(self) -> None:
        """Check the policy and cache what `_advance` reads (called by `reset`)."""
        raise NotImplementedError

    def _reference_track(self, seed: int | None) -> ReferenceTrack | None:
        if not self.needs_reference:
            return None
        return ReferenceTrack(self._motion_source(), float(self.period), seed)

    def _motion_source(self) -> MotionModel | Trial:
        if self.reference is None:
            raise InputError("cyber player", "its policy needs a reference generator")
        return self.reference

    def step(self, observation: Observation) -> tuple[float, float]:
        """Observe the neighbours, apply the greedy acceleration for one period, return (x, x')."""
        if self._references is None:
            r = 0.0
        else:
            r = self.last_reference = self._references[self._k]
        self._k += 1
        x, v, self.last_control = self._advance(observation, r)
        self._state = (x, v)
        return self._state

    def _advance(self, observation: Observation, reference: float) -> tuple[float, float, float]:
        """Return position and velocity at t_k + T and the acceleration applied."""
        raise NotImplementedError

    def parameters(self) -> dict[str, float | int]:
        """Return the dynamics parameters, as saved in a model file."""
        return self.params.to_dict() | {
            "n_substeps": int(self.n_substeps),
            "initial_position": float(self.initial_position),
        }

    def target_ims(self) -> Array | None:
        """Velocity signature (IMS) of the player it learned to imitate; None before training."""
        counts = getattr(self, "target_counts_", None)
        if counts is None or not counts.sum() > 0:
            return None
        return counts / counts.sum()

    def describe(self) -> dict[str, Any]:
        """Class, label, parameters and, once trained, its target's IMS.

        ``target_ims`` lets `mirror_avatar.metrics.session_metrics` score how close the player's
        own velocity signature stays to its target's in any session it plays.
        """
        target = self.target_ims()
        return (
            super().describe()
            | {"params": self.parameters()}
            | ({} if target is None else {"target_ims": target.tolist()})
        )

    def plan(self, seed: int, n_steps: int) -> PlayerPlan:
        """Return the start, end effector, policy and the reference draw `reset(seed)` uses."""
        reference = None
        if self.needs_reference:
            reference = ReferenceDraw(self._motion_source(), n_steps, self.period, entropy_of(seed))
        start = (float(self.initial_position), 0.0)
        return self._policy_plan(start, reference)

    def model_arrays(self, source: Source) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
        """Return the arrays and JSON metadata of the trained avatar's model file."""
        raise NotImplementedError

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the trained avatar to one ``.npz`` model file (`model_arrays`), atomically."""
        return save_model(path, self.format_name, self.format_version, *self.model_arrays(path))

    def _policy_plan(
        self, start: tuple[float, float], reference: ReferenceDraw | None
    ) -> PlayerPlan:
        """Return the `PlayerPlan` of this policy from the start and reference draw of `plan`."""
        raise NotImplementedError


def read_parameters(source: Source, parameters: Mapping[str, Any]) -> dict[str, Any]:
    """Check a model file's ``parameters`` and return `AccelerationPlayer` keyword arguments.

    Returns ``params`` (an `HKBParams`; files of version 1 lack theta_p, taken as 0),
    ``n_substeps`` and ``initial_position``.

    Raises
    ------
    InputError
        An unknown or missing parameter, or one out of its range (`HKBParams` checks its own).
    """
    own = ("n_substeps", "initial_position")
    unknown = sorted(parameters.keys() - {f.name for f in fields(HKBParams)} - set(own))
    if unknown:
        raise InputError(source, f"unknown parameter {excerpt(unknown[0])}")
    missing = [name for name in ("omega", *own) if name not in parameters]
    if missing:
        raise InputError(source, f"parameters lack {missing[0]}")
    dynamics = {"theta_p": 0.0} | {k: v for k, v in parameters.items() if k not in own}
    try:
        params = HKBParams(**dynamics)
    except InputError as error:
        raise InputError(source, error.problem) from None
    n_substeps = check_integer(source, "n_substeps", parameters["n_substeps"], 1, MAX_SUBSTEPS)
    start = check_real(source, "initial_position", parameters["initial_position"], *PLAYING_RANGE)
    return {"params": params, "n_substeps": n_substeps, "initial_position": start}


def reference_arrays(
    player: AccelerationPlayer, source: Source
) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
    """Return the arrays (prefixed `REFERENCE_PREFIX`) and metadata saving the motion source.

    Empty when its policy reads no reference.

    Raises
    ------
    InputError
        ``source: problem`` if the policy reads a reference that is not a motion model.
    """
    if not player.needs_reference:
        return {}, {}
    if not isinstance(player.reference, MotionModel):
        raise InputError(source, "only a reference motion model can be saved with the player")
    arrays, metadata = model_arrays(player.reference)
    return {f"{REFERENCE_PREFIX}{k}": a for k, a in arrays.items()}, {"reference": metadata}


def read_reference(
    source: Source, arrays: Mapping[str, NDArray[Any]], metadata: Mapping[str, Any]
) -> MotionModel:
    """Rebuild the motion source `reference_arrays` saved, checking it.

    Its metadata names its kind (`mirror_avatar.motion.models.motion_from_arrays`); a file
    without one, written before the stroke generator, holds an IMS generator.

    Raises
    ------
    InputError
        ``source: problem`` when the file holds no generator or a bad one.
    """
    if not isinstance(metadata.get("reference"), dict):
        raise InputError(source, "reference features but no reference generator in the file")
    prefixed = {
        k.removeprefix(REFERENCE_PREFIX): a
        for k, a in arrays.items()
        if k.startswith(REFERENCE_PREFIX)
    }
    return motion_from_arrays(prefixed, metadata["reference"], source)


def read_target_counts(source: Source, arrays: Mapping[str, NDArray[Any]]) -> Array | None:
    """Return the target's velocity counts a model file holds, checked (None if it has none)."""
    if "target_counts" not in arrays:
        return None
    counts = arrays["target_counts"]
    return check_array(source, "target_counts", counts, "number", (DEFAULT_BINS.n,), 0).astype(
        np.float64
    )
