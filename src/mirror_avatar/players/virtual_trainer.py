"""The virtual trainer: an HKB end effector under per-interval optimal control (METHODS 5, 8).

Every period it responds to the mean of its neighbours (the partner of a dyad, METHODS section 8
in a group): it predicts their mean position at the end of the interval by constant velocity from
the last two samples, ``2 m(t_k) - m(t_k - T)`` (``m(t_k)`` at the first step), takes their mean
velocity as r_v (joint improvisation) and its reference velocity r_s from its IMS generator (or a
recorded trial), held over the interval, and applies
`mirror_avatar.dynamics.optimal_control_steps`. For a dyad this is METHODS section 5 exactly; in a
group it **departs** from section 8's velocity prediction ``m + T mean x'_j`` so that a dyad is
the group of two. Alone (no neighbour) it tracks its reference with the whole weight
(`mirror_avatar.dynamics.partner_weights`).

`virtual_trainer_problem` states a trainer's problem for one period; `virtual_trainer_step` solves
it for `VirtualTrainer.step`, and the compiled batch loop solves all its trainers' problems of a
period together (`mirror_avatar.dynamics.optimal_control_steps`, the same solver).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mirror_avatar.dynamics import PROBLEM_COLUMNS, HKBParams, optimal_control_steps
from mirror_avatar.players.base import (
    VIRTUAL_TRAINER,
    Observation,
    Player,
    PlayerPlan,
    partner_state,
)
from mirror_avatar.players.reference import (
    ReferenceDraw,
    ReferenceTrack,
    VelocitySource,
    draw_reference,
)
from mirror_avatar.trials import Trial

Array = NDArray[np.float64]


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
        An `IMSGenerator` or another `VelocitySource` (a fresh reference is drawn at each
        `reset` from its seed) or a recorded
        `Trial` (its velocity, the same at every reset).
    start
        Initial position (units) and velocity (units/s).
    label
        A name for the player (recorded in sessions).
    """

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
        return PlayerPlan(VIRTUAL_TRAINER, start, self.params, reference=draw)
