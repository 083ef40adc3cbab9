"""The deep cyber player: a Q-network chooses the acceleration of its HKB end effector.

Follows METHODS section 8's deep cyber player: every period T the avatar encodes its own state
and its neighbours' (`mirror_avatar.deep.features.encode`: "dynamic input", padded slots), takes
the action of highest value under its network (`mirror_avatar.deep.network`; hidden layers
100-50-50 by default) and holds that acceleration over T on its own end effector, exactly as
the tabular `mirror_avatar.learning.agent.CyberPlayer` does with its Q-table (what they share is
`mirror_avatar.learning.acceleration_player.AccelerationPlayer`). `deep_step` is the compiled
step, called by `DeepCyberPlayer.step` and, through the deep players' kind (`KIND`,
`mirror_avatar.players.kinds`), by the compiled batch loop; the DQN learner is
`mirror_avatar.deep.training.DQNLearner`.

A trained player is one ``.npz`` file (format ``mirror-avatar/deep-cyber-player``): the flat
network parameters, the layer widths, the action set and JSON metadata (dynamics, input
layout, training summary and seed), read without unpickling and checked value by value
(`load_deep_cyber_player`; limits `MAX_UNITS`, `MAX_LAYERS`, `MAX_SLOTS`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.deep.features import count_features, encode
from mirror_avatar.deep.network import count_parameters, greedy_action, initial_parameters
from mirror_avatar.dynamics import FOLLOWER, HKBParams, Record, integrate_hkb
from mirror_avatar.files.model_files import (
    Source,
    check_array,
    check_integer,
    check_object,
    load_model,
    require_arrays,
)
from mirror_avatar.files.trials import Trial
from mirror_avatar.learning.acceleration_player import (
    DEFAULT_ACTIONS,
    DEFAULT_SUBSTEPS,
    AccelerationPlayer,
    read_parameters,
    read_reference,
    read_target_counts,
    reference_arrays,
)
from mirror_avatar.learning.agent import check_training
from mirror_avatar.motion.models import MotionModel
from mirror_avatar.players.base import Observation, PlayerPlan
from mirror_avatar.players.kinds import PlayerKind, parameter_table, register_kind
from mirror_avatar.players.reference import ReferenceDraw

Array = NDArray[np.float64]
Ints = NDArray[np.int64]

HIDDEN_LAYERS = (100, 50, 50)
"""Widths of the hidden layers (METHODS section 8)."""

MAX_UNITS = 1024
"""Widest layer a model file may declare (**choice**: 10 times the default's widest)."""

MAX_LAYERS = 8
"""Most hidden layers a model file may declare (**choice**)."""

MAX_SLOTS = 32
"""Most neighbour slots a model file may declare (**choice**: a group of 33)."""

FORMAT_NAME = "mirror-avatar/deep-cyber-player"
FORMAT_VERSION = 1


@njit(cache=True, nogil=True)
def deep_step(
    weights: Array,
    sizes: Ints,
    n_slots: int,
    use_reference: bool,
    actions: Array,
    p: Record,
    n_substeps: int,
    x: float,
    v: float,
    positions: Array,
    velocities: Array,
    reference: float,
) -> tuple[float, float, float]:
    """Apply the greedy action of the network for one period given the neighbours at t_k.

    Parameters
    ----------
    weights, sizes
        The network (`mirror_avatar.deep.network`).
    n_slots, use_reference
        The input layout (`mirror_avatar.deep.features`).
    actions
        Accelerations (units/s²), shape (sizes[-1],).
    p, n_substeps
        The end effector, a record of `mirror_avatar.dynamics.PARAMS_DTYPE`, and its RK4 substeps.
    x, v
        Own position (units) and velocity (units/s) at t_k.
    positions, velocities
        The neighbours' positions and velocities at t_k, shape (m,).
    reference
        Own reference velocity (units/s), read when ``use_reference``.

    Returns
    -------
    tuple of float
        Position and velocity at t_k + T, and the acceleration applied (units/s²).
    """
    features = np.empty(sizes[0])
    encode(x, v, reference, positions, velocities, n_slots, use_reference, features)
    u = actions[greedy_action(weights, sizes, features)]
    x, v = integrate_hkb(x, v, u, p, n_substeps)
    return x, v, u


@dataclass(frozen=True, eq=False)
class NetworkPolicy:
    """What a trained deep cyber player plays: its network, input layout and actions.

    Attributes
    ----------
    weights
        Flat network parameters (`mirror_avatar.deep.network`).
    sizes
        Layer widths from input to output, shape (n_layers + 1,).
    n_slots, use_reference
        The input layout (`mirror_avatar.deep.features`).
    actions
        Accelerations (units/s²), shape (sizes[-1],).
    n_substeps
        RK4 substeps per period.
    """

    weights: Array
    sizes: Ints
    n_slots: int
    use_reference: bool
    actions: Array
    n_substeps: int


class PackedNetworks(NamedTuple):
    """A session's D deep players as the compiled batch loop reads them, each row padded."""

    weights: Array
    """Flat network parameters, shape (D, P)."""
    sizes: Ints
    """Layer widths, shape (D, L)."""
    n_sizes: Ints
    """How many layer widths each network has, shape (D,)."""
    n_slots: Ints
    """Neighbour slots of each input, shape (D,)."""
    use_reference: Ints
    """1 where the input holds the player's reference velocity, shape (D,)."""
    actions: Array
    """Accelerations (units/s²), shape (D, A)."""
    n_actions: Ints
    """How many actions each network has, shape (D,)."""
    substeps: Ints
    """RK4 substeps per control period, shape (D,)."""
    params: NDArray[np.void]
    """The distinct end effectors, records of `mirror_avatar.dynamics.PARAMS_DTYPE`, (P,)."""
    param_rows: Ints
    """Each player's row in ``params``, shape (D,)."""


def pack_networks(plans: Sequence[PlayerPlan], players: Ints) -> PackedNetworks:
    """Pack a session's deep players (their plans; their rows in the session are not needed)."""
    networks: list[NetworkPolicy] = [plan.policy for plan in plans]
    count = len(networks)
    weights = np.zeros((count, max([n.weights.size for n in networks], default=1)))
    sizes = np.zeros((count, max([n.sizes.size for n in networks], default=1)), dtype=np.int64)
    n_actions = np.array([n.actions.size for n in networks], dtype=np.int64)
    actions = np.zeros((count, max(n_actions, default=1)))
    for d, network in enumerate(networks):
        weights[d, : network.weights.size] = network.weights
        sizes[d, : network.sizes.size] = network.sizes
        actions[d, : network.actions.size] = network.actions
    return PackedNetworks(
        weights,
        sizes,
        np.array([n.sizes.size for n in networks], dtype=np.int64),
        np.array([n.n_slots for n in networks], dtype=np.int64),
        np.array([n.use_reference for n in networks], dtype=np.int64),
        actions,
        n_actions,
        np.array([n.n_substeps for n in networks], dtype=np.int64),
        *parameter_table(plans),
    )


@njit(cache=True, nogil=True, inline="always")
def play_network(
    weights: Array,
    sizes: Ints,
    n_sizes: Ints,
    n_slots: Ints,
    use_reference: Ints,
    actions: Array,
    n_actions: Ints,
    substeps: Ints,
    params: NDArray[np.void],
    param_rows: Ints,
    slot: int,
    k: int,
    x: float,
    v: float,
    positions: Array,
    velocities: Array,
    previous: Array,
    reference: float,
) -> tuple[float, float, float]:
    """`deep_step` of deep player ``slot`` of the packed networks.

    The first arguments are the fields of `PackedNetworks`, the others a kind's step's
    (`mirror_avatar.players.kinds`).
    """
    return deep_step(
        weights[slot],
        sizes[slot, : n_sizes[slot]],
        n_slots[slot],
        use_reference[slot] != 0,
        actions[slot, : n_actions[slot]],
        params[param_rows[slot]],
        substeps[slot],
        x,
        v,
        positions,
        velocities,
        reference,
    )


KIND = register_kind(PlayerKind("deep", PackedNetworks, pack_networks, play_network))
"""The deep players' kind in the compiled batch loop."""


class DeepCyberPlayer(AccelerationPlayer):
    """A deep Q-network avatar (see the module docstring).

    Parameters
    ----------
    hidden
        Widths of the hidden layers, default `HIDDEN_LAYERS`.
    n_slots
        Neighbour slots of the input (0 for a dyad; N - 1 in a group of N).
    use_reference
        Whether the input holds the avatar's own reference velocity (an avatar that leads); it
        is drawn from ``reference``.
    actions, params, n_substeps, initial_position, reference, label
        As in `AccelerationPlayer`.

    Attributes
    ----------
    weights_ : ndarray
        The network's flat parameters; set by `initialise_policy`, a learner or a file.
    training_, target_counts_
        As in `AccelerationPlayer`.
    """

    agent = "dqn"
    format_name = FORMAT_NAME
    format_version = FORMAT_VERSION

    weights_: Array

    def __init__(
        self,
        hidden: Sequence[int] = HIDDEN_LAYERS,
        n_slots: int = 0,
        use_reference: bool = False,
        actions: ArrayLike = DEFAULT_ACTIONS,
        params: HKBParams = FOLLOWER,
        n_substeps: int = DEFAULT_SUBSTEPS,
        initial_position: float = 0.0,
        reference: MotionModel | Trial | None = None,
        label: str = "deep cyber player",
    ) -> None:
        super().__init__(actions, params, n_substeps, initial_position, reference, label)
        self.hidden = tuple(hidden)
        self.n_slots = n_slots
        self.use_reference = use_reference

    @property
    def needs_reference(self) -> bool:
        """True when the input holds the avatar's own reference velocity."""
        return bool(self.use_reference)

    @property
    def sizes_(self) -> Ints:
        """Layer widths from input to output, shape (len(hidden) + 2,)."""
        n_inputs = count_features(self.n_slots, self.use_reference)
        return np.array([n_inputs, *self.hidden, self.actions_.size], dtype=np.int64)

    @property
    def policy_(self) -> NetworkPolicy:
        """The greedy policy of the current network."""
        if not hasattr(self, "weights_"):
            raise InputError("deep cyber player", "has no network: train it or load one first")
        return NetworkPolicy(
            self.weights_,
            self.sizes_,
            int(self.n_slots),
            self.needs_reference,
            self.actions_,
            self.substeps_,
        )

    def initialise_policy(self, random_state: int | np.random.Generator | None) -> None:
        """Draw `weights_` afresh (`mirror_avatar.deep.network.initial_parameters`, seeded)."""
        self.weights_ = initial_parameters(self.sizes_, np.random.default_rng(random_state))

    def _prepare(self) -> None:
        self._policy = self.policy_

    def _advance(self, observation: Observation, reference: float) -> tuple[float, float, float]:
        policy = self._policy
        x, v = self._state
        return deep_step(
            policy.weights,
            policy.sizes,
            policy.n_slots,
            policy.use_reference,
            policy.actions,
            self._record[0],
            policy.n_substeps,
            x,
            v,
            observation.positions,
            observation.velocities,
            reference,
        )

    def describe(self) -> dict[str, Any]:
        """Class, label, parameters, network layout and, once trained, its target's IMS."""
        return super().describe() | {"network": self._layout()}

    def _layout(self) -> dict[str, Any]:
        return {
            "hidden": list(self.hidden),
            "n_slots": int(self.n_slots),
            "use_reference": self.needs_reference,
        }

    def _policy_plan(
        self, start: tuple[float, float], reference: ReferenceDraw | None
    ) -> PlayerPlan:
        return PlayerPlan(KIND.name, start, self.params, reference=reference, policy=self.policy_)

    def model_arrays(self, source: Source) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
        """Return the arrays and metadata of its file (`deep_player_arrays`)."""
        return deep_player_arrays(self, source)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> DeepCyberPlayer:
        """Read a model written by `save` (see `load_deep_cyber_player`)."""
        return load_deep_cyber_player(path)


def deep_player_arrays(
    player: DeepCyberPlayer, source: Source
) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
    """Return a trained deep player's arrays and JSON metadata, as its file holds them.

    The arrays are ``weights``, ``sizes``, ``actions`` and, once trained, ``target_counts``; the
    metadata holds the dynamics parameters, the network layout, the training summary and its
    seed. An avatar whose input holds its reference velocity also stores its reference
    generator, so the file alone plays.
    """
    training = getattr(player, "training_", {})
    arrays = {"weights": player.weights_, "sizes": player.sizes_, "actions": player.actions_}
    if hasattr(player, "target_counts_"):
        arrays["target_counts"] = player.target_counts_
    metadata = {
        "parameters": player.parameters(),
        "network": player._layout(),
        "training": training,
        "seed": training.get("seed"),
    }
    motion_arrays, motion_metadata = reference_arrays(player, source)
    return arrays | motion_arrays, metadata | motion_metadata


DEEP_PLAYER_ARRAYS = ("weights", "sizes", "actions")
"""The arrays every deep player's file holds."""


def load_deep_cyber_player(path: str | os.PathLike[str]) -> DeepCyberPlayer:
    """Read a player written by `DeepCyberPlayer.save`, checking every value it reads.

    Raises
    ------
    InputError
        ``path: problem`` when the file is missing, corrupt, of another format or version,
        holds a value out of its range, or does not fit together (layer widths that do not
        match the input layout, the action set or the number of parameters).
    """
    arrays, metadata = load_model(path, FORMAT_NAME, FORMAT_VERSION, DEEP_PLAYER_ARRAYS)
    return deep_player_from_arrays(arrays, metadata, path)


def deep_player_from_arrays(
    arrays: Mapping[str, NDArray[Any]], metadata: Mapping[str, Any], path: Source
) -> DeepCyberPlayer:
    """Rebuild a deep player from a file's arrays and metadata (see `load_deep_cyber_player`)."""
    require_arrays(path, arrays, DEEP_PLAYER_ARRAYS)
    layout = check_object(path, "network", metadata.get("network"))
    hidden = layout.get("hidden")
    if not isinstance(hidden, list) or not 1 <= len(hidden) <= MAX_LAYERS:
        raise InputError(path, f"network hidden must list 1 to {MAX_LAYERS} layer widths")
    widths = [check_integer(path, "hidden layer width", w, 1, MAX_UNITS) for w in hidden]
    n_slots = check_integer(path, "n_slots", layout.get("n_slots"), 0, MAX_SLOTS)
    use_reference = layout.get("use_reference")
    if not isinstance(use_reference, bool):
        raise InputError(path, "network use_reference must be true or false")
    actions = check_array(path, "actions", arrays["actions"], "float", (None,))
    parameters = check_object(path, "parameters", metadata.get("parameters"))
    player = DeepCyberPlayer(
        widths, n_slots, use_reference, actions, **read_parameters(path, parameters)
    )
    try:
        sizes = player.sizes_
    except InputError as error:
        raise InputError(path, error.problem) from None
    stored = check_array(path, "sizes", arrays["sizes"], "integer", (None,), 1, MAX_UNITS)
    if not np.array_equal(stored, sizes):
        raise InputError(path, f"layer widths {stored.tolist()} do not match {sizes.tolist()}")
    weights = check_array(path, "weights", arrays["weights"], "float", (count_parameters(sizes),))
    player.weights_ = weights.astype(np.float64)
    player.training_ = check_training(path, metadata.get("training", {}))
    target = read_target_counts(path, arrays)
    if target is not None:
        player.target_counts_ = target
    if use_reference:
        player.reference = read_reference(path, arrays, metadata)
    return player
