"""The player step protocol shared by every kind of player.

Virtual trainer, recorded trial, cyber player and live human are all advanced one control period
at a time by the same two calls.

Seeding rules (as in Gymnasium's ``reset(seed=...)``): ``reset(seed=s)`` with an integer makes
everything the player does afterwards a deterministic function of ``s`` and of the partner's
observations; ``reset(seed=None)`` draws fresh entropy. A player never touches global random state.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.hkb import CONTROL_PERIOD, HKBParams, optimal_control_step
from mirror_avatar.trials import PLAYING_RANGE, Trial

if TYPE_CHECKING:
    from mirror_avatar.generator import IMSGenerator

__all__ = [
    "CONTROL_PERIOD",
    "Player",
    "PlayerCheckError",
    "RecordedPlayer",
    "ReferenceTrack",
    "VirtualTrainer",
    "check_player",
    "draw_reference",
]

REFERENCE_BLOCK = 65.0
"""Seconds of reference velocity a virtual trainer draws from its generator at a time."""

Array = NDArray[np.float64]


@runtime_checkable
class Player(Protocol):
    """A mirror-game player.

    Attributes
    ----------
    period
        Control period (s) at which `step` is called.
    """

    period: float

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start a new trial and return the initial (position, velocity) (units, units/s)."""
        ...

    def step(self, partner_position: float, partner_velocity: float) -> tuple[float, float]:
        """Observe the partner at the current time and advance one period.

        Parameters
        ----------
        partner_position, partner_velocity
            The partner's position (units) and velocity (units/s) now, at time t_k.

        Returns
        -------
        tuple of float
            Own (position, velocity) at t_k + period; position within [-0.5, 0.5].
        """
        ...


def draw_reference(
    reference: IMSGenerator | Trial,
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

    def __init__(self, reference: IMSGenerator | Trial, period: float, seed: int | None) -> None:
        self.reference = reference
        self.period = period
        self.seed = int(np.random.SeedSequence(seed).entropy)  # type: ignore[arg-type]
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


class VirtualTrainer:
    """The model-based player: an HKB end effector under per-interval optimal control.

    Every period it predicts the partner's position at the end of the interval by constant
    velocity, ``2 r_p(t_k) - r_p(t_k - T)`` (``r_p(t_k)`` at the first step), takes its reference
    velocity r_s from its IMS generator (or a recorded trial), held constant over the interval,
    and the observed partner velocity as r_v (joint improvisation), and applies
    `mirror_avatar.hkb.optimal_control_step` (METHODS section 5).

    Parameters
    ----------
    params
        End-effector and cost parameters (`mirror_avatar.hkb.LEADER`, ``FOLLOWER``, ``JOINT``...).
    reference
        An `IMSGenerator` (a fresh reference is drawn at each `reset` from its seed) or a recorded
        `Trial` (its velocity, the same at every reset).
    start
        Initial position (units) and velocity (units/s).
    label
        A name for the player (recorded in sessions).

    Attributes
    ----------
    last_control, last_reference : float
        Control (units/s²) and reference velocity (units/s) of the last step.
    """

    def __init__(
        self,
        params: HKBParams,
        reference: IMSGenerator | Trial,
        start: tuple[float, float] = (0.0, 0.0),
        label: str = "virtual trainer",
    ) -> None:
        self.params = params
        self.reference = reference
        self.start = start
        self.label = label
        self.period = params.period
        self._vector = params.as_vector()
        self.last_control = math.nan
        self.last_reference = math.nan

    @property
    def stochastic(self) -> bool:
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
        self._previous_partner = math.nan
        self.last_control = self.last_reference = math.nan
        return self._x, self._v

    def step(self, partner_position: float, partner_velocity: float) -> tuple[float, float]:
        """Observe the partner at t_k and advance to t_k + T under the optimal control."""
        previous = self._previous_partner
        prediction = partner_position if math.isnan(previous) else 2 * partner_position - previous
        reference = self._references[self._k]
        self._x, self._v, self.last_control = optimal_control_step(
            self._x, self._v, prediction, reference, partner_velocity, self._vector
        )
        self.last_reference = reference
        self._previous_partner = partner_position
        self._k += 1
        return self._x, self._v


class RecordedPlayer:
    """A recorded trial replayed open-loop: it ignores its partner.

    Positions and velocities (METHODS section 2) are interpolated onto the control grid; after
    the end of the recording the player stays still at its last position.

    Parameters
    ----------
    trial
        The recording.
    period
        Control period (s).
    """

    stochastic = False

    def __init__(self, trial: Trial, period: float = CONTROL_PERIOD) -> None:
        self.trial = trial
        self.period = period
        self.label = trial.label or "recorded trial"
        offsets = trial.times - trial.times[0]
        n_steps = int(math.floor(offsets[-1] / period)) + 1
        grid = np.arange(n_steps) * period
        self._positions = np.clip(np.interp(grid, offsets, trial.positions), *PLAYING_RANGE)
        self._velocities = np.interp(grid, offsets, trial.velocity())

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Rewind to the start of the recording (``seed`` changes nothing)."""
        self._k = 0
        return float(self._positions[0]), float(self._velocities[0])

    def step(self, partner_position: float, partner_velocity: float) -> tuple[float, float]:
        """Return the recording one period later, whatever the partner does."""
        self._k += 1
        if self._k >= self._positions.size:
            return float(self._positions[-1]), 0.0
        return float(self._positions[self._k]), float(self._velocities[self._k])


class PlayerCheckError(AssertionError):
    """A player does not honour the step protocol."""


def _partner_motion(k: int, period: float) -> tuple[float, float]:
    t = k * period
    return 0.3 * math.sin(2.0 * t), 0.6 * math.cos(2.0 * t)


def _trajectory(player: Player, seed: int, n_steps: int) -> Array:
    name = type(player).__name__
    start = player.reset(seed=seed)
    states = [start]
    for k in range(n_steps):
        states.append(player.step(*_partner_motion(k, player.period)))
    array = np.asarray(states, dtype=np.float64)
    if array.shape != (n_steps + 1, 2):
        raise PlayerCheckError(f"{name}: reset and step must return (position, velocity) pairs")
    if not np.all(np.isfinite(array)):
        raise PlayerCheckError(f"{name}: returned a non-finite position or velocity")
    low, high = PLAYING_RANGE
    if np.any(array[:, 0] < low) or np.any(array[:, 0] > high):
        raise PlayerCheckError(f"{name}: position left the playing range {PLAYING_RANGE}")
    return array


def check_player(factory: Callable[[], Player], n_steps: int = 200) -> None:
    """Check that a player honours the step protocol, as gymnasium's ``check_env`` does for envs.

    Two fresh players from ``factory`` play ``n_steps`` periods against the same scripted
    partner. Checked: a positive ``period``; ``reset`` and ``step`` return two finite floats;
    positions stay in [-0.5, 0.5]; the same seed gives the same trajectory (also for one player
    reset twice); a player with ``stochastic = True`` moves differently under another seed.

    Raises
    ------
    PlayerCheckError
        Naming the player type and what it got wrong.
    """
    first, second = factory(), factory()
    name = type(first).__name__
    if not isinstance(first, Player):
        raise PlayerCheckError(f"{name}: lacks period, reset or step")
    if not (isinstance(first.period, float | int) and first.period > 0):
        raise PlayerCheckError(f"{name}: period must be a positive number of seconds")
    reference = _trajectory(first, 11, n_steps)
    if not np.array_equal(reference, _trajectory(second, 11, n_steps)):
        raise PlayerCheckError(f"{name}: the same seed gave two different trajectories")
    if not np.array_equal(reference, _trajectory(first, 11, n_steps)):
        raise PlayerCheckError(f"{name}: resetting with the same seed did not replay the trial")
    other = _trajectory(first, 12, n_steps)
    if getattr(first, "stochastic", False) and np.array_equal(reference, other):
        raise PlayerCheckError(f"{name}: a stochastic player ignored its seed")
