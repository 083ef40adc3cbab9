"""The player protocol: what every player declares and what the engine reads of it.

A `Player` is advanced one control period at a time: ``reset(seed)`` starts a trial and returns
the initial state, ``step(observation)`` sees the neighbours it is coupled to at t_k and returns
its own state at t_k + T. Like Gymnasium's ``Env``, the base class declares every attribute the
engine reads, with defaults: ``period``, ``label``, ``stochastic``, ``last_control`` and
``last_reference`` (recorded with each sample), and ``describe()`` (recorded in the session's
metadata). An `ExternalPlayer` (a person at a browser, a device) is not stepped: the engine asks
it for its current state at every sample. A player the compiled batch engine can run also
returns a `PlayerPlan` from ``plan``. `check_player` checks all of it.

Seeding rules (as in Gymnasium's ``reset(seed=...)``): ``reset(seed=s)`` with an integer makes
everything the player does afterwards a deterministic function of ``s`` and of its observations;
``reset(seed=None)`` draws fresh entropy. A player never touches global random state.

The neighbours' mean (`partner_state`), used by every built-in player, is compiled once here and
called from the Python step loop and the compiled batch loop alike.

A player that diverges is refused or stopped, never recorded: `dry_run` steps a newly made
player against a scripted partner (`mirror_avatar.specs` runs it on every spec), and the step
loop raises `PlayerDiverged` at the first sample whose state is not finite or beyond
`DIVERGED_BEYOND`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import CONTROL_PERIOD, HKBParams
from mirror_avatar.files.trials import PLAYING_RANGE

if TYPE_CHECKING:
    from mirror_avatar.players.reference import ReferenceDraw

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Observation:
    """What a player sees at t_k: the players it is coupled to (its neighbours).

    Attributes
    ----------
    k
        Index of the current sample (time ``k * period``).
    positions, velocities
        The neighbours' positions (units) and velocities (units/s) at t_k, shape (m,); m = 0
        for a player alone.
    previous_positions
        Their positions at t_{k-1}, shape (m,) (at k = 0, their positions at t_0).
    """

    k: int
    positions: Array
    velocities: Array
    previous_positions: Array

    @classmethod
    def of_partner(cls, k: int, position: float, velocity: float, previous: float) -> Observation:
        """Make the observation of a single partner (a dyad)."""
        return cls(k, np.array([position]), np.array([velocity]), np.array([previous]))


@dataclass(frozen=True, eq=False)
class PlayerPlan:
    """Everything the compiled batch loop needs to run one player for one session.

    Attributes
    ----------
    kind
        The name of its kind, registered by the module that defines the player
        (`mirror_avatar.players.kinds`), which packs and steps it.
    start
        Initial position (units) and velocity (units/s).
    params
        The HKB end effector and its costs (virtual trainer and cyber player), else None.
    reference
        The draw of the reference velocity at each control step (a virtual trainer, a cyber
        player with reference features), else None; the batch engine draws a chunk's
        references together (`mirror_avatar.players.reference.draw_references`).
    track
        A recording's positions and velocities on the control grid, shape (2, L), else None.
    policy
        A learned player's greedy policy, the record its kind defines (a Q-table,
        `mirror_avatar.learning.agent.GreedyPolicy`; a network,
        `mirror_avatar.deep.player.NetworkPolicy`), else None. The players live above this
        module, so it is not typed here.
    """

    kind: str
    start: tuple[float, float]
    params: HKBParams | None = None
    reference: ReferenceDraw | None = None
    track: Array | None = None
    policy: Any = None


class Player:
    """Base class of every player: the attributes the engine reads, with their defaults.

    Attributes
    ----------
    period : float
        Control period (s) at which `step` is called.
    label : str
        A name for the player, recorded in sessions.
    stochastic : bool
        True when different seeds give different trials (`check_player` tests it).
    last_control : float
        Control applied over the last step (units/s²); NaN for a player without one.
    last_reference : float
        Reference velocity used over the last step (units/s); NaN for a player without one.
    """

    period: float = CONTROL_PERIOD
    label: str = "player"
    stochastic: bool = False
    last_control: float = math.nan
    last_reference: float = math.nan
    TRIAL_STATE: tuple[str, ...] = ()
    """The attributes `reset` sets and `step` advances: what a successor takes over
    (`take_over`); empty for a player that cannot hand its trial over."""

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start a new trial and return the initial (position, velocity) (units, units/s)."""
        raise NotImplementedError

    def step(self, observation: Observation) -> tuple[float, float]:
        """Observe the neighbours at t_k and return own (position, velocity) at t_k + period.

        The position stays within [-0.5, 0.5].
        """
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:
        """JSON description recorded in sessions: class and label (subclasses add parameters)."""
        return {"class": type(self).__name__, "label": self.label}

    def plan(self, seed: int, n_steps: int) -> PlayerPlan | None:
        """Return what the compiled batch loop needs to play ``n_steps`` after ``reset(seed)``.

        None (the default) means the player runs only in the Python step loop.
        """
        return None

    def take_over(self, previous: Player) -> None:
        """Continue ``previous``'s trial from its current sample, in this player's way.

        The successor (the same kind of player in another role or with other parameters,
        already `reset` with the seed ``previous`` was reset with) takes ``previous``'s
        `TRIAL_STATE` (its state, its sample count, a drawn reference track), so its next
        `step` advances from where ``previous`` stands; what it does not take (its parameters,
        its policy, a reference of its own) stays its own. ``previous`` must not be stepped
        afterwards.

        Raises
        ------
        InputError
            When the two players do not keep the same trial state (another kind of player).
        """
        if not self.TRIAL_STATE or _state_owner(type(previous)) is not _state_owner(type(self)):
            raise InputError(self.label, f"cannot take over the trial of {type(previous).__name__}")
        for name in self.TRIAL_STATE:
            setattr(self, name, getattr(previous, name))


def _state_owner(kind: type[Player]) -> type[Player]:
    """Return the class that declares ``kind``'s `Player.TRIAL_STATE`."""
    return next(c for c in kind.__mro__ if "TRIAL_STATE" in vars(c))


class ExternalPlayer(Player):
    """A player whose motion comes from outside (a person): the engine reads, never steps it."""

    def current_state(self) -> tuple[float, float]:
        """Return the (position, velocity) to record for the sample being taken now."""
        raise NotImplementedError

    def step(self, observation: Observation) -> tuple[float, float]:
        """Not used: the engine takes `current_state` at every sample instead."""
        return self.current_state()


@njit(cache=True, inline="always")
def neighbour_mean(values: Array) -> float:
    """Mean of the neighbours' values, summed in order (exactly the value for one neighbour)."""
    total = values[0]
    for j in range(1, values.size):
        total += values[j]
    return total / values.size


@njit(cache=True, inline="always")
def partner_state(
    positions: Array, velocities: Array, previous: Array, x: float, v: float
) -> tuple[float, float, float]:
    """Return the partner a player responds to: its neighbours' mean (METHODS section 8).

    Parameters
    ----------
    positions, velocities, previous
        The neighbours' positions and velocities at t_k and positions at t_{k-1}, shape (m,).
    x, v
        The player's own state, taken as the partner when it has no neighbour (m = 0).

    Returns
    -------
    tuple of float
        Mean position and velocity at t_k and mean position at t_{k-1}.
    """
    if positions.size == 0:
        return x, v, x
    return neighbour_mean(positions), neighbour_mean(velocities), neighbour_mean(previous)


@njit(cache=True, inline="always")
def gather_neighbours(
    positions: Array,
    velocities: Array,
    k: int,
    index: NDArray[np.int64],
    xs: Array,
    vs: Array,
    previous: Array,
) -> None:
    """Copy the neighbours' states at sample k (and positions at k - 1) into the buffers.

    Parameters
    ----------
    positions, velocities
        All players' recorded states, shape (N, n).
    k
        The current sample.
    index
        The neighbours' indices, shape (m,).
    xs, vs, previous
        Buffers of at least m elements receiving positions and velocities at t_k and positions at
        t_{k-1} (at t_0 for k = 0).
    """
    before = k - 1 if k > 0 else 0
    for j in range(index.size):
        xs[j] = positions[index[j], k]
        vs[j] = velocities[index[j], k]
        previous[j] = positions[index[j], before]


class PlayerCheckError(AssertionError):
    """A player does not honour the protocol."""


DIVERGED_BEYOND = 1e6
"""A position (units) or velocity (units/s) beyond this magnitude, or not finite, means its
player has diverged (**choice**: a million times the playing range, far beyond any player that
works, yet finite enough that the samples before it can be analysed without overflow)."""


class PlayerDiverged(InputError):
    """A player's position or velocity is not finite or beyond `DIVERGED_BEYOND`: it diverged.

    Parameters
    ----------
    index
        The player's index in the session.
    label
        Its label.
    sample
        The first sample whose state is not finite.
    period
        The control period (s), to say when.
    state
        The position (units) and velocity (units/s) it returned.
    """

    def __init__(
        self, index: int, label: str, sample: int, period: float, state: tuple[float, float]
    ) -> None:
        self.index, self.label, self.sample = index, label, sample
        super().__init__(
            f"player {index} ({label})",
            f"diverged at sample {sample} ({sample * period:.2f} s): it returned position "
            f"{state[0]!r} and velocity {state[1]!r}, not finite or beyond {DIVERGED_BEYOND:g}; "
            "the session ends there (give its spec parameters nearer their defaults)",
        )

    def describe(self) -> dict[str, Any]:
        """Return what a trial's sidecar records of it: sample, player index, label, message."""
        return {
            "sample": self.sample,
            "player": self.index,
            "label": self.label,
            "message": str(self),
        }


DRY_RUN_SECONDS = 5.0
"""Length of a player's dry run against a scripted partner (s; **choice**: a few oscillations of
the partner, 170 control periods, a few milliseconds for a model partner)."""

DRY_RUN_MAX_SPEED = 100.0
"""Largest speed (units/s) a player may reach in its dry run (**choice**: crossing the playing
range a hundred times a second; the fastest bundled trials stay under 10 units/s)."""


def dry_run(player: Player, source: str, hint: str = "", seconds: float = DRY_RUN_SECONDS) -> None:
    """Step ``player`` for ``seconds`` against one scripted partner and refuse it if it diverges.

    The partner moves as ``0.3 sin(2 t)`` units (about 0.32 Hz), the neighbour `check_player`
    scripts. The player is reset with seed 0 first; reset it again before use.

    Parameters
    ----------
    player
        The player, built.
    source
        What made it (its spec), named by the error.
    hint
        What the error adds on how to fix it (the parameters given).
    seconds
        How long to play (s).

    Raises
    ------
    InputError
        ``source: ...`` when a position or velocity stops being finite, a position leaves the
        playing range or a speed exceeds `DRY_RUN_MAX_SPEED`, saying when.
    """
    n_steps = int(round(seconds / player.period))
    state = player.reset(seed=0)
    for k in range(n_steps + 1):
        problem = _state_problem(float(state[0]), float(state[1]))
        if problem is not None:
            raise InputError(
                source,
                f"diverges: {k * player.period:.2f} s into a dry run against a partner moving "
                f"as 0.3 sin(2t), {problem}" + (f" ({hint})" if hint else ""),
            )
        if k < n_steps:
            state = player.step(_scripted_observation(k, player.period, 1))


def _state_problem(x: float, v: float) -> str | None:
    """Say what is wrong with a dry run's state, or None (see `dry_run`)."""
    low, high = PLAYING_RANGE
    if not (math.isfinite(x) and math.isfinite(v)):
        return f"its position {x!r} and velocity {v!r} stopped being finite"
    if not low <= x <= high:
        return f"its position {x:.6g} left the playing range {low:g}..{high:g}"
    if abs(v) > DRY_RUN_MAX_SPEED:
        return f"its speed {abs(v):.6g} units/s exceeded {DRY_RUN_MAX_SPEED:g}"
    return None


def _scripted_observation(k: int, period: float, n_neighbours: int) -> Observation:
    """Return the scripted neighbours at t_k: neighbour j moves as ``0.3 sin(2 t + 0.7 j)`` units.

    Each array is a row of a C-ordered array, so C-contiguous as the engine's are: a compiled
    step given a strided view would be compiled again for that layout.
    """
    t = np.array([k * period, max(k - 1, 0) * period])
    phase = 2.0 * t[:, None] + np.arange(n_neighbours) * 0.7
    x = 0.3 * np.sin(phase)
    return Observation(k, x[0], 0.6 * np.cos(phase[0]), x[1])


def _trajectory(player: Player, seed: int, n_steps: int, n_neighbours: int) -> Array:
    name = type(player).__name__
    states = [player.reset(seed=seed)]
    for k in range(n_steps):
        states.append(player.step(_scripted_observation(k, player.period, n_neighbours)))
        for attribute in ("last_control", "last_reference"):
            if not isinstance(getattr(player, attribute), float):
                raise PlayerCheckError(f"{name}: {attribute} must be a float (NaN for none)")
    array = np.asarray(states, dtype=np.float64)
    if array.shape != (n_steps + 1, 2):
        raise PlayerCheckError(f"{name}: reset and step must return (position, velocity) pairs")
    if not np.all(np.isfinite(array)):
        raise PlayerCheckError(f"{name}: returned a non-finite position or velocity")
    low, high = PLAYING_RANGE
    if np.any(array[:, 0] < low) or np.any(array[:, 0] > high):
        raise PlayerCheckError(f"{name}: position left the playing range {PLAYING_RANGE}")
    return array


def check_player(
    factory: Callable[[], Player], n_steps: int = 200, neighbours: tuple[int, ...] = (1, 3, 0)
) -> None:
    """Check that a player honours the protocol, as gymnasium's ``check_env`` does for envs.

    Fresh players from ``factory`` play ``n_steps`` periods against scripted neighbours (one, a
    group of three, and none). Checked: the declared attributes (a positive ``period``, a string
    ``label``, a boolean ``stochastic``, float ``last_control`` and ``last_reference``, a
    JSON-serialisable ``describe()``); ``reset`` and ``step`` return two finite floats;
    positions stay in [-0.5, 0.5]; the same seed gives the same trajectory (also for one player
    reset twice); a player with ``stochastic = True`` moves differently under another seed.

    Raises
    ------
    PlayerCheckError
        Naming the player type and what it got wrong.
    """
    first = factory()
    name = type(first).__name__
    _check_attributes(first, name)
    for n_neighbours in neighbours:
        try:
            reference = _trajectory(first, 11, n_steps, n_neighbours)
        except PlayerCheckError:
            raise
        except Exception as error:
            raise PlayerCheckError(
                f"{name}: failed with {n_neighbours} neighbours ({type(error).__name__}: {error})"
            ) from error
        if not np.array_equal(reference, _trajectory(factory(), 11, n_steps, n_neighbours)):
            raise PlayerCheckError(f"{name}: the same seed gave two different trajectories")
        if not np.array_equal(reference, _trajectory(first, 11, n_steps, n_neighbours)):
            raise PlayerCheckError(f"{name}: resetting with the same seed did not replay the trial")
        other = _trajectory(first, 12, n_steps, n_neighbours)
        if first.stochastic and np.array_equal(reference, other):
            raise PlayerCheckError(f"{name}: a stochastic player ignored its seed")


def _check_attributes(player: Player, name: str) -> None:
    if not isinstance(player, Player):
        raise PlayerCheckError(f"{name}: not a mirror_avatar.players.Player")
    if not (isinstance(player.period, float | int) and player.period > 0):
        raise PlayerCheckError(f"{name}: period must be a positive number of seconds")
    if not isinstance(player.label, str):
        raise PlayerCheckError(f"{name}: label must be a string")
    if not isinstance(player.stochastic, bool):
        raise PlayerCheckError(f"{name}: stochastic must be True or False")
    try:
        json.dumps(player.describe())
    except (TypeError, ValueError):
        raise PlayerCheckError(f"{name}: describe() must be JSON-serialisable") from None
