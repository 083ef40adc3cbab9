"""The cyber player: a Q-table avatar driving its own HKB end effector (METHODS section 7).

Every control period T the avatar observes its own state and its partner's (the mean of its
neighbours), finds the cell of that state (`mirror_avatar.learning.discretisation`), applies the
acceleration of the best action of that cell, held over T, to its own Haken-Kelso-Bunz end
effector (`mirror_avatar.dynamics.integrate_hkb`, a few RK4 substeps), and reports that control
(what it shares with the deep avatar is `mirror_avatar.learning.acceleration_player`).
At play time the policy is greedy; `mirror_avatar.learning.training.QLearner` fills the Q-table.

Follows METHODS section 7; the **choice**s it leaves open, all configurable:

- actions: 0, ±0.5, ±1, ±2, ±4 (units/s², the group's later code);
- the end effector: `mirror_avatar.dynamics.FOLLOWER`'s (omega = 0.1 rad/s, alpha = 1, beta = 2,
  gamma = -1, eta = 1e-4) unless other parameters are given;
- the state discretisation (relative features by default);
- position clipped to the playing range [-0.5, 0.5] after each period, and the velocity component
  pushing further out set to zero (a hand stopped at the edge of the range);
- alone (no neighbour), the avatar takes its own state as its partner's.

`cyber_step` is the compiled step, called by `CyberPlayer.step` and, through the cyber players'
kind (`KIND`, `mirror_avatar.players.kinds`), by the compiled batch loop.

A trained player is saved as one ``.npz`` file holding the Q-table, the bin edges, the action set
and a JSON metadata string (format name ``mirror-avatar/cyber-player``), read without unpickling
and with every value it holds checked against its range (`CyberPlayer.save`,
`load_cyber_player`; the limits are `MAX_Q_CELLS`, `MAX_TRAINING_SESSIONS`, those of
`mirror_avatar.learning.acceleration_player`, `mirror_avatar.dynamics.PARAMETER_RANGES` and
`mirror_avatar.files.model_files`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import FOLLOWER, HKBParams, Record, integrate_hkb
from mirror_avatar.files.importing import excerpt
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
from mirror_avatar.learning.discretisation import (
    FEATURES,
    N_FEATURES,
    Discretisation,
    make_default_discretisation,
    state_index,
)
from mirror_avatar.motion.models import MotionModel
from mirror_avatar.players.base import Observation, PlayerPlan, partner_state
from mirror_avatar.players.kinds import PlayerKind, parameter_table, register_kind
from mirror_avatar.players.reference import ReferenceDraw

if TYPE_CHECKING:
    import os

Array = NDArray[np.float64]
Ints = NDArray[np.int64]

Q_INIT_SCALE = 1e-3
"""Scale of an untrained Q-table's random values (`CyberPlayer.initialise_policy`, **choice**)."""

MAX_Q_CELLS = 2**24
"""Most Q-table entries (states x actions) a model file may hold (**choice**: the largest default,
``"reference"`` features with the default actions, has 9600 x 9 = 86 400; 2^24 take 128 MiB)."""

MAX_TRAINING_SESSIONS = 10**9
"""Most training sessions a model file may record having played (**choice**: 950 years of 30 s
sessions)."""

FORMAT_NAME = "mirror-avatar/cyber-player"
FORMAT_VERSION = 1


@njit(cache=True, nogil=True)
def cyber_step(
    q: Array,
    mode: int,
    edges: Array,
    offsets: NDArray[np.int64],
    actions: Array,
    p: Record,
    n_substeps: int,
    x: float,
    v: float,
    positions: Array,
    velocities: Array,
    reference: float,
) -> tuple[float, float, float]:
    """Apply the greedy action for one period given the neighbours at t_k.

    Parameters
    ----------
    q, mode, edges, offsets, actions, n_substeps
        The policy (`GreedyPolicy`): Q-table (n_states, n_actions) and discretisation.
    p
        The end effector, a record of `mirror_avatar.dynamics.PARAMS_DTYPE`.
    x, v
        Own position (units) and velocity (units/s) at t_k.
    positions, velocities
        The neighbours' positions and velocities at t_k, shape (m,).
    reference
        Own reference velocity (units/s), used by ``"reference"`` features only.

    Returns
    -------
    tuple of float
        Position and velocity at t_k + T, and the acceleration applied (units/s²).
    """
    xp, vp, _ = partner_state(positions, velocities, positions, x, v)
    u = actions[np.argmax(q[state_index(x, v, xp, vp, reference, mode, edges, offsets)])]
    x, v = integrate_hkb(x, v, u, p, n_substeps)
    return x, v, u


@dataclass(frozen=True, eq=False)
class GreedyPolicy:
    """What a trained cyber player plays: its Q-table, cells and actions.

    Attributes
    ----------
    q_table
        Action values, shape (n_states, n_actions).
    discretisation
        The cells.
    actions
        Accelerations (units/s²), shape (n_actions,).
    n_substeps
        RK4 substeps per period.
    """

    q_table: Array
    discretisation: Discretisation
    actions: Array
    n_substeps: int


class PackedPolicies(NamedTuple):
    """A session's C cyber players as the compiled batch loop reads them, each row padded."""

    q_tables: Array
    """Q-tables padded with -inf, shape (C, S, A)."""
    modes: Ints
    """Feature codes, shape (C,)."""
    edges: Array
    """Bin edges, shape (C, E)."""
    offsets: Ints
    """Edge offsets, shape (C, 5)."""
    actions: Array
    """Accelerations (units/s²), shape (C, A)."""
    n_actions: Ints
    """How many actions each has, shape (C,)."""
    substeps: Ints
    """RK4 substeps per period, shape (C,)."""
    params: NDArray[np.void]
    """The distinct end effectors, records of `mirror_avatar.dynamics.PARAMS_DTYPE`, (P,)."""
    param_rows: Ints
    """Each player's row in ``params``, shape (C,)."""


def pack_policies(plans: Sequence[PlayerPlan], players: Ints) -> PackedPolicies:
    """Pack a session's cyber players (their plans; their rows in the session are not needed)."""
    policies: list[GreedyPolicy] = [plan.policy for plan in plans]
    count = len(policies)
    n_states = max([p.q_table.shape[0] for p in policies], default=1)
    n_actions = np.array([p.actions.size for p in policies], dtype=np.int64)
    n_edges = max([p.discretisation.flat_edges.size for p in policies], default=1)
    q_tables = np.full((count, n_states, max(n_actions, default=1)), -np.inf)
    edges = np.zeros((count, n_edges))
    offsets = np.zeros((count, 5), dtype=np.int64)
    actions = np.zeros((count, q_tables.shape[2]))
    for c, policy in enumerate(policies):
        q = policy.q_table
        q_tables[c, : q.shape[0], : q.shape[1]] = q
        flat = policy.discretisation.flat_edges
        edges[c, : flat.size] = flat
        offsets[c] = policy.discretisation.offsets
        actions[c, : policy.actions.size] = policy.actions
    return PackedPolicies(
        q_tables,
        np.array([p.discretisation.mode for p in policies], dtype=np.int64),
        edges,
        offsets,
        actions,
        n_actions,
        np.array([p.n_substeps for p in policies], dtype=np.int64),
        *parameter_table(plans),
    )


@njit(cache=True, nogil=True, inline="always")
def play_policy(
    q_tables: Array,
    modes: Ints,
    edges: Array,
    offsets: Ints,
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
    """`cyber_step` of cyber player ``slot`` of the packed policies.

    The first arguments are the fields of `PackedPolicies`, the others a kind's step's
    (`mirror_avatar.players.kinds`).
    """
    return cyber_step(
        q_tables[slot],
        modes[slot],
        edges[slot],
        offsets[slot],
        actions[slot, : n_actions[slot]],
        params[param_rows[slot]],
        substeps[slot],
        x,
        v,
        positions,
        velocities,
        reference,
    )


KIND = register_kind(PlayerKind("cyber", PackedPolicies, pack_policies, play_policy))
"""The cyber players' kind in the compiled batch loop."""


class CyberPlayer(AccelerationPlayer):
    """A Q-learning avatar (see the module docstring).

    Parameters
    ----------
    discretisation
        State discretisation; default `make_default_discretisation()` (relative features).
    actions, params, n_substeps, initial_position, reference, label
        As in `AccelerationPlayer`; ``reference`` is used by ``"reference"`` features only.

    Attributes
    ----------
    q_table_ : ndarray, shape (n_states, n_actions)
        The learned action values; set by `initialise_q` or a learner, or by loading a file.
    training_, target_counts_
        As in `AccelerationPlayer`.
    """

    agent = "tabular"
    format_name = FORMAT_NAME
    format_version = FORMAT_VERSION

    q_table_: Array

    def __init__(
        self,
        discretisation: Discretisation | None = None,
        actions: ArrayLike = DEFAULT_ACTIONS,
        params: HKBParams = FOLLOWER,
        n_substeps: int = DEFAULT_SUBSTEPS,
        initial_position: float = 0.0,
        reference: MotionModel | Trial | None = None,
        label: str = "cyber player",
    ) -> None:
        super().__init__(actions, params, n_substeps, initial_position, reference, label)
        self.discretisation = discretisation

    @property
    def needs_reference(self) -> bool:
        """True with ``"reference"`` features."""
        return self.discretisation_.needs_reference

    @cached_property
    def discretisation_(self) -> Discretisation:
        """The discretisation in use (the default one when none was given), fixed on first use."""
        return self.discretisation or make_default_discretisation()

    @property
    def policy_(self) -> GreedyPolicy:
        """The greedy policy of the current Q-table."""
        if not hasattr(self, "q_table_"):
            raise InputError("cyber player", "has no Q-table: train it or load one first")
        return GreedyPolicy(self.q_table_, self.discretisation_, self.actions_, self.substeps_)

    def initialise_q(self, random_state: int | np.random.Generator | None, scale: float) -> None:
        """Fill `q_table_` with independent uniform values in [-scale, 0] (seeded)."""
        rng = np.random.default_rng(random_state)
        shape = (self.discretisation_.n_states, self.actions_.size)
        self.q_table_ = -scale * rng.random(shape)

    def initialise_policy(self, random_state: int | np.random.Generator | None) -> None:
        """Fill the Q-table with uniform values in [-`Q_INIT_SCALE`, 0] (`initialise_q`)."""
        self.initialise_q(random_state, Q_INIT_SCALE)

    def _prepare(self) -> None:
        policy = self.policy_
        disc = policy.discretisation
        self._policy = (
            policy.q_table,
            disc.mode,
            disc.flat_edges,
            disc.offsets,
            policy.actions,
            policy.n_substeps,
        )

    def _advance(self, observation: Observation, reference: float) -> tuple[float, float, float]:
        q, mode, edges, offsets, actions, n_substeps = self._policy
        x, v = self._state
        return cyber_step(
            q,
            mode,
            edges,
            offsets,
            actions,
            self._record[0],
            n_substeps,
            x,
            v,
            observation.positions,
            observation.velocities,
            reference,
        )

    def describe(self) -> dict[str, Any]:
        """Class, label, parameters, feature set and, once trained, its target's IMS."""
        return super().describe() | {"features": self.discretisation_.features}

    def _policy_plan(
        self, start: tuple[float, float], reference: ReferenceDraw | None
    ) -> PlayerPlan:
        return PlayerPlan(KIND.name, start, self.params, reference=reference, policy=self.policy_)

    def model_arrays(self, source: Source) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
        """Return the arrays and metadata of its file (`cyber_player_arrays`)."""
        return cyber_player_arrays(self, source)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> CyberPlayer:
        """Read a model written by `save` (see `load_cyber_player`)."""
        return load_cyber_player(path)


def cyber_player_arrays(
    player: CyberPlayer, source: Source
) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
    """Return a trained player's arrays and JSON metadata, as its file holds them.

    The file holds arrays ``q_table`` (n_states, n_actions), ``edges`` (all interior bin edges),
    ``edge_counts`` (4,), ``actions`` (n_actions,) and the JSON metadata of
    `mirror_avatar.files.model_files.save_model`: format name and version, the dynamics parameters,
    the discretisation, the training summary and its seed; once trained, ``target_counts``
    (DEFAULT_BINS.n,), its target's velocity counts. A player with ``"reference"`` features also
    stores its reference generator (arrays prefixed ``reference_``, metadata ``reference``), so the
    file alone plays.

    Raises
    ------
    InputError
        ``source: problem`` if a player with ``"reference"`` features has no motion model
        (`mirror_avatar.motion.models.MotionModel`) as its reference.
    """
    disc = player.discretisation_
    training = getattr(player, "training_", {})
    metadata: dict[str, Any] = {
        "parameters": player.parameters(),
        "discretisation": {"features": disc.features, "shape": list(disc.shape)},
        "training": training,
        "seed": training.get("seed"),
    }
    arrays = {
        "q_table": player.q_table_,
        "edges": disc.flat_edges,
        "edge_counts": np.array([e.size for e in disc.edges], dtype=np.int64),
        "actions": player.actions_,
    }
    if hasattr(player, "target_counts_"):
        arrays["target_counts"] = player.target_counts_
    motion_arrays, motion_metadata = reference_arrays(player, source)
    return arrays | motion_arrays, metadata | motion_metadata


def load_cyber_player(path: str | os.PathLike[str]) -> CyberPlayer:
    """Read a player written by `CyberPlayer.save` (see `cyber_player_from_arrays`)."""
    arrays, metadata = load_model(path, FORMAT_NAME, FORMAT_VERSION, CYBER_PLAYER_ARRAYS)
    return cyber_player_from_arrays(arrays, metadata, path)


CYBER_PLAYER_ARRAYS = ("q_table", "edges", "edge_counts", "actions")
"""The arrays every cyber player's file holds."""


def cyber_player_from_arrays(
    arrays: Mapping[str, NDArray[Any]], metadata: Mapping[str, Any], path: Source
) -> CyberPlayer:
    """Rebuild a player from `cyber_player_arrays` output, checking every value it reads.

    The dynamics parameters must lie in `mirror_avatar.dynamics.PARAMETER_RANGES`, n_substeps
    in 1..`MAX_SUBSTEPS` and the initial position in the playing range; the actions as
    `CyberPlayer.actions_` requires; the bin edges finite and strictly increasing per feature;
    the Q-table finite, of at most `MAX_Q_CELLS` entries; a reference motion model as
    `mirror_avatar.motion.models.motion_from_arrays` requires.

    Raises
    ------
    InputError
        ``path: problem`` when the file is missing, not a readable ``.npz`` (corrupt or
        truncated), of another format or version, holds a value out of its range, or is
        internally inconsistent (for instance a Q-table whose shape does not match the
        discretisation and action set).
    """
    require_arrays(path, arrays, CYBER_PLAYER_ARRAYS)
    edges = check_array(path, "edges", arrays["edges"], "float", (None,))
    counts = check_array(
        path, "edge_counts", arrays["edge_counts"], "integer", (N_FEATURES,), 0, edges.size
    ).tolist()
    if sum(counts) != edges.size:
        raise InputError(path, f"edge_counts add up to {sum(counts)}, not the {edges.size} edges")
    features = check_object(path, "discretisation", metadata.get("discretisation")).get("features")
    if features not in FEATURES:
        raise InputError(path, f"features {excerpt(features)} are not one of {', '.join(FEATURES)}")
    actions = check_array(path, "actions", arrays["actions"], "float", (None,))
    parameters = check_object(path, "parameters", metadata.get("parameters"))
    try:
        disc = Discretisation(features, tuple(np.split(edges, np.cumsum(counts)[:-1])))
        player = CyberPlayer(disc, actions, **read_parameters(path, parameters))
        n_actions = player.actions_.size
    except InputError as error:
        raise InputError(path, error.problem) from None
    check_integer(path, "Q-table size", disc.n_states * n_actions, 1, MAX_Q_CELLS)
    q = check_array(path, "q_table", arrays["q_table"], "float", (None, None))
    if q.shape != (disc.n_states, n_actions):
        raise InputError(
            path,
            f"Q-table shape {q.shape} does not match {disc.n_states} states x {n_actions} actions",
        )
    player.q_table_ = q.astype(np.float64)
    player.training_ = check_training(path, metadata.get("training", {}))
    target = read_target_counts(path, arrays)
    if target is not None:
        player.target_counts_ = target
    if disc.needs_reference:
        player.reference = read_reference(path, arrays, metadata)
    return player


POLICY_ROLE_NAMES = ("follower", "leader", "group")
"""The roles a cyber player may have been trained in (``training.role`` of its file; absent for
a player never trained)."""


def check_training(path: Source, training: object) -> dict[str, Any]:
    """Return a file's training summary once the entries play and training read are valid."""
    summary = check_object(path, "training", training)
    role = summary.get("role")
    if not (role is None or role in POLICY_ROLE_NAMES):
        raise InputError(
            path, f"training role {excerpt(role)} is none of {', '.join(POLICY_ROLE_NAMES)}"
        )
    if "n_sessions" in summary:
        check_integer(path, "n_sessions", summary["n_sessions"], 0, MAX_TRAINING_SESSIONS)
    return summary
