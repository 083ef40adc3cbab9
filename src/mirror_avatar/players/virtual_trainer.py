"""The virtual trainer: an HKB end effector under per-interval optimal control (METHODS 5, 8).

Every period it responds to the mean of its neighbours (the partner of a dyad, METHODS section 8
in a group): it predicts their mean position at the end of the interval by constant velocity from
the last two samples, ``2 m(t_k) - m(t_k - T)`` (``m(t_k)`` at the first step), takes their mean
velocity as r_v (joint improvisation) and its reference velocity r_s from its motion model (or a
recorded trial), held over the interval, and applies
`mirror_avatar.dynamics.optimal_control_steps`. For a dyad this is METHODS section 5 exactly; in a
group it **departs** from section 8's velocity prediction ``m + T mean x'_j`` so that a dyad is
the group of two. Alone (no neighbour) it tracks its reference with the whole weight
(`mirror_avatar.dynamics.partner_weights`).

`virtual_trainer_problem` states a trainer's problem for one period; `virtual_trainer_step` solves
it for `VirtualTrainer.step`. The trainers' kind (`KIND`, `mirror_avatar.players.kinds`) is
solved together: in the compiled batch loop each trainer poses its problem of a period
(`pose_trainer`) and `solve_trainers` solves them all in lockstep
(`mirror_avatar.dynamics.optimal_control_steps`, the same solver), which gives each the result
it would have alone.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mirror_avatar.dynamics import (
    PROBLEM_COLUMNS,
    HKBParams,
    coupling_rate,
    optimal_control_steps,
)
from mirror_avatar.files.trials import Trial
from mirror_avatar.players.base import Observation, Player, PlayerPlan, partner_state
from mirror_avatar.players.kinds import PlayerKind, parameter_table, register_kind
from mirror_avatar.players.reference import (
    ReferenceDraw,
    ReferenceTrack,
    VelocitySource,
    draw_reference,
)

Array = NDArray[np.float64]
Ints = NDArray[np.int64]


@njit(cache=True, nogil=True, inline="always")
def virtual_trainer_problem(
    x: float,
    v: float,
    positions: Array,
    velocities: Array,
    previous: Array,
    reference: float,
    problem: Array,
) -> bool:
    """Write a virtual trainer's optimal-control problem given its neighbours into ``problem``.

    Parameters
    ----------
    x, v
        Its position (units) and velocity (units/s) at t_k.
    positions, velocities, previous
        The neighbours' positions and velocities at t_k and positions at t_{k-1}, shape (m,).
    reference
        Its reference velocity r_s over the interval (units/s).
    problem
        Receives the row of `mirror_avatar.dynamics.solve_intervals`, shape (5,): the state,
        the predicted mean position of the neighbours, the reference and their mean velocity.

    Returns
    -------
    bool
        Whether it has a neighbour (``coupled``).
    """
    mean_x, mean_v, mean_previous = partner_state(positions, velocities, previous, x, v)
    problem[0], problem[1], problem[2] = x, v, 2.0 * mean_x - mean_previous
    problem[3], problem[4] = reference, mean_v
    return positions.size > 0


@njit(cache=True, nogil=True)
def virtual_trainer_step(
    params: NDArray[np.void],
    x: float,
    v: float,
    positions: Array,
    velocities: Array,
    previous: Array,
    reference: float,
) -> tuple[float, float, float]:
    """Advance one virtual trainer by one period given its neighbours (see the module docstring).

    ``params`` holds its record of `mirror_avatar.dynamics.PARAMS_DTYPE`, shape (1,); the other
    arguments are those of `virtual_trainer_problem`. Returns its position and velocity at
    t_k + T and its control at t_k (units/s²).
    """
    problems = np.empty((1, PROBLEM_COLUMNS))
    coupled = np.array(
        [virtual_trainer_problem(x, v, positions, velocities, previous, reference, problems[0])]
    )
    out = np.empty((1, 3))
    optimal_control_steps(problems, coupled, params, np.zeros(1, np.int64), out)
    return out[0, 0], out[0, 1], out[0, 2]


class VirtualTrainer(Player):
    """The model-based player (see the module docstring).

    Parameters
    ----------
    params
        End-effector and cost parameters (`mirror_avatar.dynamics.LEADER`, ``FOLLOWER``,
        ``JOINT``...).
    reference
        A motion model (a stroke or IMS generator) or another `VelocitySource` (a fresh
        reference is drawn at each `reset` from its seed) or a recorded `Trial` (its velocity,
        the same at every reset).
    start
        Initial position (units) and velocity (units/s).
    label
        A name for the player (recorded in sessions).
    """

    TRIAL_STATE = ("_references", "seed_", "_k", "_x", "_v", "last_control", "last_reference")

    def __init__(
        self,
        params: HKBParams,
        reference: VelocitySource | Trial,
        start: tuple[float, float] = (0.0, 0.0),
        label: str = "virtual trainer",
    ) -> None:
        self.params = params
        self.reference = reference
        self.start = start
        self.label = label
        self.period = params.period
        self._record = params.record()
        self.last_control = math.nan
        self.last_reference = math.nan

    @property
    def stochastic(self) -> bool:  # type: ignore[override]
        """True when the reference is drawn afresh at every reset (a generator)."""
        return not isinstance(self.reference, Trial)

    def draw_reference(self, seed: int | None, n_steps: int) -> Array:
        """Return the reference velocity a reset with ``seed`` uses for its first ``n_steps``."""
        return draw_reference(self.reference, n_steps, self.period, np.random.default_rng(seed))

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start a trial at `start` with a reference drawn from ``seed`` (fresh entropy if None).

        The seed actually used is kept in ``seed_``.
        """
        self._references = ReferenceTrack(self.reference, self.period, seed)
        self.seed_ = self._references.seed
        self._k = 0
        self._x, self._v = float(self.start[0]), float(self.start[1])
        self.last_control = self.last_reference = math.nan
        return self._x, self._v

    def step(self, observation: Observation) -> tuple[float, float]:
        """Observe the neighbours at t_k and advance to t_k + T under the optimal control."""
        reference = self._references[self._k]
        self._x, self._v, self.last_control = virtual_trainer_step(
            self._record,
            self._x,
            self._v,
            observation.positions,
            observation.velocities,
            observation.previous_positions,
            reference,
        )
        self.last_reference = reference
        self._k += 1
        return self._x, self._v

    def describe(self) -> dict[str, Any]:
        """Class, label and parameters."""
        return super().describe() | {"params": self.params.to_dict()}

    def plan(self, seed: int, n_steps: int) -> PlayerPlan:
        """Return the start, parameters and the draw of the reference `reset(seed)` uses."""
        start = (float(self.start[0]), float(self.start[1]))
        draw = ReferenceDraw(self.reference, n_steps, self.period, seed)
        return PlayerPlan(KIND.name, start, self.params, reference=draw)


class TrainerLanes(NamedTuple):
    """A session's K virtual trainers as the compiled batch loop solves them, in lockstep.

    The lanes are ordered as suits the lockstep shots (`stiffest_first`); a trainer's slot is
    its number among the session's trainers.
    """

    players: Ints
    """Each lane's player, its row in the session, shape (K,)."""
    lanes: Ints
    """Each slot's lane, shape (K,)."""
    params: NDArray[np.void]
    """The distinct parameters, records of `mirror_avatar.dynamics.PARAMS_DTYPE`, (P,)."""
    param_rows: Ints
    """Each lane's row in ``params``, shape (K,)."""
    problems: Array
    """Each lane's problem of the period, shape (K, `PROBLEM_COLUMNS`)."""
    coupled: NDArray[np.bool_]
    """Whether each lane's trainer has a neighbour, shape (K,)."""
    solved: Array
    """Each lane's position, velocity and control, shape (K, 3)."""


def pack_trainers(plans: Sequence[PlayerPlan], players: Ints) -> TrainerLanes:
    """Pack a session's virtual trainers (their plans, and their rows in the session)."""
    params, rows = parameter_table(plans)
    order = stiffest_first(params, rows)
    lanes = np.empty(order.size, dtype=np.int64)
    lanes[order] = np.arange(order.size)
    count = len(plans)
    return TrainerLanes(
        players[order],
        lanes,
        params,
        rows[order],
        np.empty((count, PROBLEM_COLUMNS)),
        np.empty(count, np.bool_),
        np.empty((count, 3)),
    )


@njit(cache=True, nogil=True)
def stiffest_first(params: NDArray[np.void], rows: Ints) -> Ints:
    """Order the trainers by their costate-control rate, fastest first (stable).

    The rate (`mirror_avatar.dynamics.coupling_rate`) sets a problem's fewest RK4 steps, and
    the lockstep shots stop at the last problem still stepping: problems with as many steps
    side by side waste none. Each problem's solution does not depend on the order.
    """
    rates = np.empty(rows.size)
    for t in range(rows.size):
        p = params[rows[t]]
        rates[t] = coupling_rate(p, p.theta_p)
    return np.argsort(-rates, kind="mergesort")


@njit(cache=True, nogil=True, inline="always")
def pose_trainer(
    players: Ints,
    lanes: Ints,
    params: NDArray[np.void],
    param_rows: Ints,
    problems: Array,
    coupled: NDArray[np.bool_],
    solved: Array,
    slot: int,
    k: int,
    x: float,
    v: float,
    positions: Array,
    velocities: Array,
    previous: Array,
    reference: float,
) -> None:
    """Pose trainer ``slot``'s problem of period k in its lane (`virtual_trainer_problem`).

    The first arguments are the fields of `TrainerLanes`, the others a kind's step's
    (`mirror_avatar.players.kinds`).
    """
    lane = lanes[slot]
    coupled[lane] = virtual_trainer_problem(
        x, v, positions, velocities, previous, reference, problems[lane]
    )


@njit(cache=True, nogil=True, inline="always")
def solve_trainers(
    players: Ints,
    lanes: Ints,
    params: NDArray[np.void],
    param_rows: Ints,
    problems: Array,
    coupled: NDArray[np.bool_],
    solved: Array,
    k: int,
    out: Array,
) -> None:
    """Solve the posed problems together and write the trainers' samples into ``out``.

    The first arguments are the fields of `TrainerLanes`; ``out`` (4, N, n) receives positions
    and velocities at sample k + 1 and controls at sample k.
    """
    optimal_control_steps(problems, coupled, params, param_rows, solved)
    for t in range(players.size):
        out[0, players[t], k + 1] = solved[t, 0]
        out[1, players[t], k + 1] = solved[t, 1]
        out[2, players[t], k] = solved[t, 2]


KIND = register_kind(
    PlayerKind("virtual_trainer", TrainerLanes, pack_trainers, pose_trainer, solve_trainers)
)
"""The virtual trainers' kind in the compiled batch loop, solved together."""
