"""The cyber player: a Q-learning avatar driving its own HKB end effector (METHODS section 7).

Every control period T the avatar observes the state ``[x, x', x_p, x_p']`` (own position and
velocity, partner's position and velocity), picks one of a small set of accelerations ``u`` and
applies it, held constant over T, to its own Haken-Kelso-Bunz end effector

    x'' = -(alpha x² + beta x'² - gamma) x' - omega² x + u,

integrated with a few classical Runge-Kutta (RK4) substeps. During training it is rewarded for
matching the **target player** ``[x_t, x_t']`` (the person it must imitate, who plays with the
same partner):

    rho = -(x - x_t)² - 0.1 (x' - x_t')² - eta u²,

and learns by tabular Q-learning, ``Q(s,a) += alpha [r + gamma max_a' Q(s',a') - Q(s,a)]``, with a
seeded random initial Q-table and epsilon-greedy exploration whose epsilon decreases monotonically
from session to session. At play time the policy is greedy.

Follows METHODS section 7; the **choice**s it leaves open, all configurable:

- actions: 0, ±0.5, ±1, ±2, ±4 (units/s², the group's later code);
- omega = 0.1 rad/s for the avatar's own end effector (the paper's follower value; alpha = 1,
  beta = 2, gamma = -1 as in section 5);
- state discretisation (`Discretisation`): ``"absolute"`` features ``[x, x', x_p, x_p']`` or
  ``"relative"`` features ``[x - x_p, x' - x_p', x_p, x_p']`` (the default, measured better on the
  real-data follower task, see the tests and benchmark), each cut by its own increasing bin edges;
- **departure**: ``"reference"`` features ``[x - x_p, x' - r_s, x, r_s]``, where r_s is the
  avatar's own reference velocity drawn from an IMS generator exactly as a virtual trainer draws
  it (METHODS section 5). The avatar then has a motion source of its own, as the person it
  imitates does; in training r_s is the target's reference in each session. Used for the
  leader, whose motion the partner's state cannot predict (measured in
  `mirror_avatar.training.make_role_discretisation`);
- position clipped to the playing range [-0.5, 0.5] after each period, and the velocity component
  pushing further out set to zero (a hand stopped at the edge of the range);
- a training session starts the avatar at the target's initial state;
- epsilon schedule (`ExponentialEpsilon`), learning rate, discount and the scale of the random
  initial Q-table.

The whole Q-learning session is one compiled function (`run_q_session`) taking arrays at the
control period, so a training loop only streams sessions to it. Models are saved as one ``.npz``
file holding the Q-table, the bin edges, the action set and a JSON metadata string (format name
``mirror-avatar/cyber-player``), loaded with ``allow_pickle=False``.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray
from tqdm.auto import tqdm

from mirror_avatar.atomic import write_atomic_bytes
from mirror_avatar.errors import InputError
from mirror_avatar.generator import IMSGenerator
from mirror_avatar.hkb import CONTROL_PERIOD, clip_to_range, hkb_acceleration
from mirror_avatar.model_files import load_model, save_model
from mirror_avatar.players import ReferenceTrack
from mirror_avatar.trials import Trial

Array = NDArray[np.float64]
Features = Literal["absolute", "relative", "reference"]
FEATURES: tuple[Features, ...] = ("absolute", "relative", "reference")
"""The state feature sets, in the order of their compiled codes `ABSOLUTE`, `RELATIVE`,
`REFERENCE`."""
ABSOLUTE, RELATIVE, REFERENCE = range(3)

DEFAULT_ACTIONS = (-4.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 4.0)
"""The 9 accelerations (units/s²) the avatar can choose from (**choice**, METHODS section 7)."""

VELOCITY_WEIGHT = 0.1
"""Weight of the velocity error in the reward (METHODS section 7)."""

FORMAT_NAME = "mirror-avatar/cyber-player"
REFERENCE_PREFIX = "reference_"
"""Prefix of the reference generator's arrays in a model file."""
FORMAT_VERSION = 1
N_FEATURES = 4


# ---------------------------------------------------------------------------------------------
# Compiled core: HKB step, reward, state index, greedy choice, one Q-learning session.


@njit(cache=True)
def integrate_hkb(
    x: float, v: float, u: float, hkb: Array, period: float, n_substeps: int
) -> tuple[float, float]:
    """Advance the HKB end effector by one control period with u held constant (RK4).

    Parameters
    ----------
    x, v
        Position (units) and velocity (units/s) at the start of the period.
    u
        Acceleration input (units/s²), held over the period.
    hkb
        ``[alpha, beta, gamma, omega]``, shape (4,).
    period
        Control period T (s).
    n_substeps
        Number of RK4 steps of length T / n_substeps.

    Returns
    -------
    tuple of float
        Position and velocity at the end of the period; the position is clipped to [-0.5, 0.5]
        and an outward velocity at the boundary is set to zero.
    """
    h = period / n_substeps
    alpha, beta, gamma, omega = hkb[0], hkb[1], hkb[2], hkb[3]
    for _ in range(n_substeps):
        a1 = hkb_acceleration(x, v, u, alpha, beta, gamma, omega)
        x2, v2 = x + 0.5 * h * v, v + 0.5 * h * a1
        a2 = hkb_acceleration(x2, v2, u, alpha, beta, gamma, omega)
        x3, v3 = x + 0.5 * h * v2, v + 0.5 * h * a2
        a3 = hkb_acceleration(x3, v3, u, alpha, beta, gamma, omega)
        x4, v4 = x + h * v3, v + h * a3
        a4 = hkb_acceleration(x4, v4, u, alpha, beta, gamma, omega)
        x += h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4)
        v += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    return clip_to_range(x, v)


@njit(cache=True)
def compute_reward(x: float, v: float, xt: float, vt: float, u: float, eta: float) -> float:
    """Reward ``-(x - x_t)² - 0.1 (x' - x_t')² - eta u²`` (METHODS section 7).

    Parameters
    ----------
    x, v
        The avatar's position (units) and velocity (units/s).
    xt, vt
        The target player's position and velocity at the same time.
    u
        The acceleration just applied (units/s²).
    eta
        Weight of the control effort (the paper's eta = 1e-4).

    Returns
    -------
    float
        The reward (<= 0).
    """
    return -((x - xt) ** 2) - VELOCITY_WEIGHT * (v - vt) ** 2 - eta * u * u


@njit(cache=True)
def _bin(value: float, edges: Array, start: int, stop: int) -> int:
    return int(np.searchsorted(edges[start:stop], value, side="right"))


@njit(cache=True)
def _features(
    x: float, v: float, xp: float, vp: float, r: float, mode: int
) -> tuple[float, float, float, float]:
    if mode == ABSOLUTE:
        return x, v, xp, vp
    if mode == RELATIVE:
        return x - xp, v - vp, xp, vp
    return x - xp, v - r, x, r


@njit(cache=True)
def _state_index(
    x: float,
    v: float,
    xp: float,
    vp: float,
    r: float,
    mode: int,
    edges: Array,
    offsets: NDArray[np.int64],
) -> int:
    index = 0
    for d, value in enumerate(_features(x, v, xp, vp, r, mode)):
        start, stop = offsets[d], offsets[d + 1]
        index = index * (stop - start + 1) + _bin(value, edges, start, stop)
    return index


@njit(cache=True)
def choose_action(q: Array, s: int, epsilon: float, rng: np.random.Generator) -> int:
    """Epsilon-greedy choice in state ``s``: a uniform random action with probability epsilon.

    Draws ``rng.random()`` first, then ``rng.integers(0, n_actions)`` only when exploring.
    """
    if rng.random() < epsilon:
        return int(rng.integers(0, q.shape[1]))
    return int(np.argmax(q[s]))


@njit(cache=True)
def update_q(
    q: Array, s: int, a: int, r: float, s_next: int, learning_rate: float, discount: float
) -> None:
    """Q-learning update ``Q(s,a) += alpha [r + gamma max_a' Q(s',a') - Q(s,a)]``, in place."""
    q[s, a] += learning_rate * (r + discount * np.max(q[s_next]) - q[s, a])


@njit(cache=True)
def _greedy_action(
    q: Array,
    x: float,
    v: float,
    xp: float,
    vp: float,
    r: float,
    mode: int,
    edges: Array,
    offsets: NDArray[np.int64],
) -> int:
    return int(np.argmax(q[_state_index(x, v, xp, vp, r, mode, edges, offsets)]))


@njit(cache=True)
def _greedy_step(
    q: Array,
    x: float,
    v: float,
    xp: float,
    vp: float,
    r: float,
    mode: int,
    edges: Array,
    offsets: NDArray[np.int64],
    actions: Array,
    hkb: Array,
    period: float,
    n_substeps: int,
) -> tuple[float, float]:
    u = actions[_greedy_action(q, x, v, xp, vp, r, mode, edges, offsets)]
    return integrate_hkb(x, v, u, hkb, period, n_substeps)


@njit(cache=True)
def run_q_session(
    q: Array,
    partner_x: Array,
    partner_v: Array,
    target_x: Array,
    target_v: Array,
    target_r: Array,
    mode: int,
    edges: Array,
    offsets: NDArray[np.int64],
    actions: Array,
    hkb: Array,
    period: float,
    n_substeps: int,
    eta: float,
    learning_rate: float,
    discount: float,
    epsilon: float,
    rng: np.random.Generator,
) -> tuple[float, float]:
    """Play one session against a partner and Q-learn from it, updating ``q`` in place.

    The avatar starts at the target's initial state; at each sample k it observes its own state
    and the partner's, picks an action epsilon-greedily, integrates its HKB over one period and is
    rewarded against the target at k + 1. With ``learning_rate = 0`` and ``epsilon = 0`` this is a
    greedy evaluation that leaves ``q`` unchanged.

    Parameters
    ----------
    q
        Q-table, shape (n_states, n_actions), updated in place.
    partner_x, partner_v, target_x, target_v
        Partner and target positions (units) and velocities (units/s), shape (n,) each, sampled
        at the control period.
    target_r
        The target's reference velocity (units/s), shape (n,): the avatar's own reference in
        ``"reference"`` features, unused otherwise.
    mode, edges, offsets
        The state discretisation (`Discretisation.mode`, ``flat_edges``, ``offsets``).
    actions
        Accelerations (units/s²), shape (n_actions,).
    hkb, period, n_substeps
        The end effector (see `integrate_hkb`).
    eta
        Control-effort weight of the reward.
    learning_rate, discount, epsilon
        Q-learning step size, discount factor and exploration probability.
    rng
        Random generator for exploration.

    Returns
    -------
    reward_sum : float
        Sum of the n - 1 rewards.
    rms : float
        Root mean square of the avatar's position minus the target's over samples 1..n-1 (units).
    """
    x, v = target_x[0], target_v[0]
    s = _state_index(x, v, partner_x[0], partner_v[0], target_r[0], mode, edges, offsets)
    reward_sum = 0.0
    squares = 0.0
    for k in range(partner_x.size - 1):
        a = choose_action(q, s, epsilon, rng)
        u = actions[a]
        x, v = integrate_hkb(x, v, u, hkb, period, n_substeps)
        r = compute_reward(x, v, target_x[k + 1], target_v[k + 1], u, eta)
        s_next = _state_index(
            x, v, partner_x[k + 1], partner_v[k + 1], target_r[k + 1], mode, edges, offsets
        )
        update_q(q, s, a, r, s_next, learning_rate, discount)
        s = s_next
        reward_sum += r
        squares += (x - target_x[k + 1]) ** 2
    return reward_sum, math.sqrt(squares / max(partner_x.size - 1, 1))


# ---------------------------------------------------------------------------------------------
# State discretisation.


@dataclass(frozen=True, eq=False)
class Discretisation:
    """How the continuous state is cut into the cells of the Q-table.

    Parameters
    ----------
    features
        ``"absolute"``: features ``[x, x', x_p, x_p']``; ``"relative"``: ``[x - x_p, x' - x_p',
        x_p, x_p']``; ``"reference"``: ``[x - x_p, x' - r_s, x, r_s]`` with r_s the avatar's
        own reference velocity (positions in units, velocities in units/s).
    edges
        Four increasing arrays of interior bin edges, one per feature; feature d has
        ``len(edges[d]) + 1`` bins, the outer two open-ended (values beyond the range fall in
        the end bins).
    """

    features: Features
    edges: tuple[Array, ...]

    def __post_init__(self) -> None:
        if self.features not in FEATURES:
            raise InputError("features", f"must be one of {FEATURES}, not {self.features!r}")
        edges = tuple(np.asarray(e, dtype=np.float64).ravel() for e in self.edges)
        if len(edges) != N_FEATURES:
            raise InputError("edges", f"need {N_FEATURES} arrays of bin edges, got {len(edges)}")
        for d, e in enumerate(edges):
            if not np.all(np.isfinite(e)) or np.any(np.diff(e) <= 0):
                raise InputError("edges", f"edges of feature {d} must be finite and increasing")
        object.__setattr__(self, "edges", edges)

    @classmethod
    def uniform(
        cls,
        features: Features,
        ranges: Iterable[tuple[float, float]],
        n_bins: Iterable[int],
    ) -> Discretisation:
        """Equal-width bins: feature d has ``n_bins[d]`` bins over ``ranges[d]`` (plus tails)."""
        edges = tuple(
            np.linspace(lo, hi, n + 1)[1:-1] for (lo, hi), n in zip(ranges, n_bins, strict=True)
        )
        return cls(features, edges)

    @property
    def mode(self) -> int:
        """Compiled code of the feature set: `ABSOLUTE`, `RELATIVE` or `REFERENCE`."""
        return FEATURES.index(self.features)

    @property
    def needs_reference(self) -> bool:
        """True when the state includes the avatar's own reference velocity."""
        return self.features == "reference"

    @property
    def shape(self) -> tuple[int, ...]:
        """Number of bins per feature."""
        return tuple(e.size + 1 for e in self.edges)

    @property
    def n_states(self) -> int:
        """Number of cells (rows of the Q-table)."""
        return math.prod(self.shape)

    @cached_property
    def flat_edges(self) -> Array:
        """All interior edges, concatenated feature after feature."""
        return np.concatenate(self.edges)

    @cached_property
    def offsets(self) -> NDArray[np.int64]:
        """Start of each feature's edges in `flat_edges`, then the total, shape (5,)."""
        return np.concatenate([[0], np.cumsum([e.size for e in self.edges])]).astype(np.int64)

    def index(self, x: float, v: float, xp: float, vp: float, r: float = 0.0) -> int:
        """Return the cell of a state.

        The state is own position, velocity, partner's position, velocity and own reference
        velocity (``r`` only matters for ``"reference"`` features).
        """
        return int(_state_index(x, v, xp, vp, r, self.mode, self.flat_edges, self.offsets))


def make_default_discretisation(features: Features = "relative") -> Discretisation:
    """Make the default discretisation of a feature set (**choice**), finer near zero.

    Parameters
    ----------
    features
        ``"relative"`` (default; 10 x 8 x 6 x 7 = 3360 cells), ``"absolute"`` (8 x 8 x 6 x 7 =
        2688 cells) or ``"reference"`` (10 x 10 x 8 x 12 = 9600 cells: ``x - x_p`` and
        ``x' - r_s`` symmetric about 0 with edges at ±0.02, 0.05, 0.1, 0.2 units and ±0.05,
        0.1, 0.2, 0.4 units/s, ``x`` in 8 bins over ±0.4 units, ``r_s`` with edges at 0, ±0.05,
        0.15, 0.3, 0.5, 0.8 units/s).
    """
    if features == "reference":
        return Discretisation(
            features,
            (
                symmetric_edges(0.02, 0.05, 0.1, 0.2),
                symmetric_edges(0.05, 0.1, 0.2, 0.4),
                np.linspace(-0.4, 0.4, 7),
                symmetric_edges(0.05, 0.15, 0.3, 0.5, 0.8),
            ),
        )
    partner = (np.linspace(-0.4, 0.4, 5), np.array([-0.5, -0.2, -0.05, 0.05, 0.2, 0.5]))
    if features == "relative":
        own = (symmetric_edges(0.02, 0.05, 0.1, 0.2), symmetric_edges(0.1, 0.25, 0.5))
    else:
        own = (np.linspace(-0.45, 0.45, 7), symmetric_edges(0.1, 0.25, 0.5))
    return Discretisation(features, own + partner)


def symmetric_edges(*positive: float) -> Array:
    """Bin edges ``-positive[::-1], 0, positive``."""
    edges = np.asarray(positive, dtype=np.float64)
    return np.concatenate([-edges[::-1], [0.0], edges])


# ---------------------------------------------------------------------------------------------
# The cyber player.


class CyberPlayer:
    """A Q-learning avatar; implements the `mirror_avatar.players.Player` protocol (greedy).

    Parameters
    ----------
    discretisation
        State discretisation; default `make_default_discretisation()` (relative features).
    actions
        Accelerations (units/s²) to choose from, default `DEFAULT_ACTIONS`.
    alpha, beta, gamma, omega
        HKB parameters of the avatar's own end effector (METHODS section 5; omega is a
        **choice**, rad/s).
    eta
        Control-effort weight in the reward.
    period
        Control period T (s).
    n_substeps
        RK4 substeps per period.
    initial_position
        Position (units) returned by `reset`; the avatar starts at rest.
    reference
        The avatar's own motion source for ``"reference"`` features: an `IMSGenerator` (a
        reference velocity is drawn at each `reset` from its seed, as a virtual trainer does) or
        a recorded `Trial`. Unused by the other feature sets.

    Attributes
    ----------
    q_table_ : ndarray, shape (n_states, n_actions)
        The learned action values; set by `initialise_q` or a trainer, or by `load`.
    training_ : dict
        Summary of how the Q-table was trained (seed, sessions, hyper-parameters, last scores).
    last_reference : float
        Own reference velocity (units/s) of the last step; NaN without ``"reference"`` features.
    label : str
        A name for the player (recorded in sessions).
    """

    q_table_: Array
    training_: dict[str, Any]
    label = "cyber player"
    last_reference = math.nan

    def __init__(
        self,
        discretisation: Discretisation | None = None,
        actions: ArrayLike = DEFAULT_ACTIONS,
        *,
        alpha: float = 1.0,
        beta: float = 2.0,
        gamma: float = -1.0,
        omega: float = 0.1,
        eta: float = 1e-4,
        period: float = CONTROL_PERIOD,
        n_substeps: int = 3,
        initial_position: float = 0.0,
        reference: IMSGenerator | Trial | None = None,
    ) -> None:
        self.discretisation = discretisation
        self.actions = actions
        self.alpha = alpha
        self.beta = beta
        self.gamma = gamma
        self.omega = omega
        self.eta = eta
        self.period = period
        self.n_substeps = n_substeps
        self.initial_position = initial_position
        self.reference = reference

    @property
    def stochastic(self) -> bool:
        """True when every `reset` draws a fresh reference from a generator."""
        return self.discretisation_.needs_reference and isinstance(self.reference, IMSGenerator)

    @cached_property
    def discretisation_(self) -> Discretisation:
        """The discretisation in use (the default one when none was given), fixed on first use."""
        return self.discretisation or make_default_discretisation()

    @property
    def actions_(self) -> Array:
        """The action set as a float array, shape (n_actions,)."""
        actions = np.asarray(self.actions, dtype=np.float64)
        if actions.ndim != 1 or actions.size == 0 or not np.all(np.isfinite(actions)):
            raise InputError("actions", "must be a non-empty list of finite accelerations")
        return actions

    @property
    def hkb_(self) -> Array:
        """``[alpha, beta, gamma, omega]`` of the avatar's end effector."""
        return np.array([self.alpha, self.beta, self.gamma, self.omega], dtype=np.float64)

    def parameters(self) -> dict[str, float | int]:
        """Return the dynamics parameters, as saved in a model file."""
        return {
            "alpha": float(self.alpha),
            "beta": float(self.beta),
            "gamma": float(self.gamma),
            "omega": float(self.omega),
            "eta": float(self.eta),
            "period": float(self.period),
            "n_substeps": int(self.n_substeps),
            "initial_position": float(self.initial_position),
        }

    def initialise_q(self, random_state: int | np.random.Generator | None, scale: float) -> None:
        """Fill `q_table_` with independent uniform values in [-scale, 0] (seeded)."""
        rng = np.random.default_rng(random_state)
        shape = (self.discretisation_.n_states, self.actions_.size)
        self.q_table_ = -scale * rng.random(shape)

    def session_arguments(self) -> tuple[Any, ...]:
        """Discretisation and dynamics arguments of `run_q_session`, in order."""
        if not (self.period > 0 and self.n_substeps >= 1):
            raise InputError("cyber player", "period must be > 0 s and n_substeps >= 1")
        disc = self.discretisation_
        return (
            disc.mode,
            disc.flat_edges,
            disc.offsets,
            self.actions_,
            self.hkb_,
            float(self.period),
            int(self.n_substeps),
            float(self.eta),
        )

    def decide(self, x: float, v: float, xp: float, vp: float, r: float = 0.0) -> int:
        """Index of the greedy action in the state (own x, x', partner's x, x', own reference)."""
        disc = self.discretisation_
        return int(
            _greedy_action(self.q_table_, x, v, xp, vp, r, disc.mode, disc.flat_edges, disc.offsets)
        )

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start a trial at rest at `initial_position`.

        The greedy policy is deterministic; with ``"reference"`` features the reference velocity
        is drawn from ``seed`` (fresh entropy if None), otherwise ``seed`` changes nothing.
        """
        if not hasattr(self, "q_table_"):
            raise InputError("cyber player", "has no Q-table: train it or load one first")
        self._policy = (self.q_table_, *self.session_arguments()[:-1])
        self._references = self._reference_track(seed)
        self._k = 0
        self._state = (float(self.initial_position), 0.0)
        return self._state

    def _reference_track(self, seed: int | None) -> ReferenceTrack | None:
        if not self.discretisation_.needs_reference:
            return None
        if self.reference is None:
            raise InputError("cyber player", "reference features need a reference generator")
        return ReferenceTrack(self.reference, float(self.period), seed)

    def step(self, partner_position: float, partner_velocity: float) -> tuple[float, float]:
        """Observe the partner, apply the greedy acceleration for one period, return (x, x')."""
        q, mode, edges, offsets, actions, hkb, period, n_substeps = self._policy
        x, v = self._state
        if self._references is None:
            r = 0.0
        else:
            r = self.last_reference = self._references[self._k]
        self._k += 1
        self._state = _greedy_step(
            q,
            x,
            v,
            float(partner_position),
            float(partner_velocity),
            r,
            mode,
            edges,
            offsets,
            actions,
            hkb,
            period,
            n_substeps,
        )
        return self._state

    def evaluate(self, sessions: Iterable[Any]) -> tuple[Array, Array]:
        """Play each session greedily (no learning) against its partner.

        Parameters
        ----------
        sessions
            Chunks of sessions as accepted by `iter_sessions`.

        Returns
        -------
        mean_reward, rms : ndarray, shape (n_sessions,)
            Mean reward per step and RMS position error to the target (units) per session.
        """
        rng = np.random.default_rng(0)
        scores = [
            self.play_session(session, 0.0, 0.0, 0.0, rng)
            for session in iter_sessions(sessions, self.period)
        ]
        return np.array([r for r, _ in scores]), np.array([e for _, e in scores])

    def play_session(
        self,
        session: tuple[Array, Array, Array, Array, Array],
        learning_rate: float,
        discount: float,
        epsilon: float,
        rng: np.random.Generator,
    ) -> tuple[float, float]:
        """Play one session with `run_q_session`, updating `q_table_` when learning_rate > 0.

        Parameters
        ----------
        session
            ``(partner_x, partner_v, target_x, target_v, target_r)``, shape (n,) each, at the
            control period (as `iter_sessions` yields them; ``target_r`` may be NaN when the
            features do not use it).
        learning_rate, discount, epsilon, rng
            As in `run_q_session`.

        Returns
        -------
        mean_reward, rms : float
            Mean reward per step and RMS position error to the target (units).

        Raises
        ------
        InputError
            If the features need the target's reference velocity and the session has none.
        """
        if self.discretisation_.needs_reference and not np.all(np.isfinite(session[4])):
            raise InputError(
                "sessions", "reference features need the target's reference velocities"
            )
        total, rms = run_q_session(  # type: ignore[call-arg]
            self.q_table_,
            *session,
            *self.session_arguments(),
            learning_rate,
            discount,
            epsilon,
            rng,
        )
        return total / max(session[0].size - 1, 1), rms

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the model to one ``.npz`` file atomically (see `save_cyber_player`)."""
        return save_cyber_player(self, path)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> CyberPlayer:
        """Read a model written by `save` (see `load_cyber_player`)."""
        return load_cyber_player(path)


# ---------------------------------------------------------------------------------------------
# Sessions: chunks of arrays (k, 2, n) of positions and velocities.


def iter_sessions(
    chunks: Iterable[Any], period: float | None = None
) -> Iterator[tuple[Array, Array, Array, Array, Array]]:
    """Yield ``(partner_x, partner_v, target_x, target_v, target_r)`` for each session in chunks.

    Parameters
    ----------
    chunks
        Iterable of chunks. A chunk has positions and velocities of shape (k, 2, n) (k sessions,
        player 0 the partner, player 1 the target, n samples at the control period) or (2, n) for
        one session, given as an object with ``positions`` and ``velocities`` attributes, a
        mapping with those keys, or a ``(positions, velocities)`` pair. A chunk may also carry
        its sampling period (s) as a ``period`` attribute or key, and the players' reference
        velocities (units/s, same shape) as ``references`` (a
        `mirror_avatar.batch.SessionBatch` does): ``target_r`` is the target's, its trailing
        NaN (no reference after the last step) replaced by the one before; all NaN without
        references.
    period
        The control period (s) the sessions must be sampled at, checked against a chunk's own
        ``period`` when it has one.

    Raises
    ------
    InputError
        If a chunk has another form, shape, sampling period, or non-finite values.
    """
    for chunk in chunks:
        own = _chunk_field(chunk, "period")
        if period is not None and own is not None and not math.isclose(own, period):
            raise InputError("sessions", f"sampled every {own} s, not every {period} s")
        positions, velocities = _chunk_arrays(chunk)
        references = _target_references(chunk, positions.shape)
        for session_x, session_v, session_r in zip(positions, velocities, references, strict=True):
            yield session_x[0], session_v[0], session_x[1], session_v[1], session_r


def _chunk_field(chunk: Any, name: str) -> Any:
    """Return a chunk's optional field ``name`` (a mapping key or an attribute), or None."""
    return chunk.get(name) if isinstance(chunk, Mapping) else getattr(chunk, name, None)


def _target_references(chunk: Any, shape: tuple[int, ...]) -> Array:
    """Return the target's reference velocities of a chunk, shape (k, n); NaN if it has none."""
    found = _chunk_field(chunk, "references")
    if found is None:
        return np.full((shape[0], shape[2]), np.nan)
    references = np.asarray(found, dtype=np.float64)
    references = references[np.newaxis] if references.ndim == 2 else references
    if references.shape != shape:
        raise InputError("sessions", f"references {references.shape} do not match {shape}")
    target = references[:, 1].copy()
    target[:, -1] = np.where(np.isnan(target[:, -1]), target[:, -2], target[:, -1])
    return target


def make_follower_sessions(
    trials: Iterable[Trial], lag: float = 0.3, period: float = CONTROL_PERIOD
) -> tuple[Array, Array]:
    """Build follower sessions from recorded trials: a task with a known answer.

    Each trial, resampled to 1 / period, is the partner; the target is the same motion ``lag``
    seconds later (a perfect follower with a fixed delay). Trials are cut to the shortest one.

    Parameters
    ----------
    trials
        Recorded trials (any rate).
    lag
        Delay of the target behind the partner (s), rounded to whole periods (at least one).
    period
        Control period (s).

    Returns
    -------
    positions, velocities : ndarray, shape (k, 2, n)
        A chunk (see `iter_sessions`): player 0 the partner, player 1 the delayed target.
    """
    shift = max(round(lag / period), 1)
    positions, velocities = [], []
    for trial in trials:
        uniform = trial.resampled(1.0 / period)
        x, v = uniform.positions, uniform.velocity()
        positions.append(np.stack([x[shift:], x[:-shift]]))
        velocities.append(np.stack([v[shift:], v[:-shift]]))
    if not positions:
        raise InputError("trials", "no trials to build sessions from")
    n = min(p.shape[1] for p in positions)
    return np.stack([p[:, :n] for p in positions]), np.stack([v[:, :n] for v in velocities])


def _chunk_arrays(chunk: Any) -> tuple[Array, Array]:
    if isinstance(chunk, Mapping):
        pair = (chunk.get("positions"), chunk.get("velocities"))
    elif hasattr(chunk, "positions") and hasattr(chunk, "velocities"):
        pair = (chunk.positions, chunk.velocities)
    elif isinstance(chunk, tuple | list) and len(chunk) == 2:
        pair = (chunk[0], chunk[1])
    else:
        pair = (None, None)
    if pair[0] is None or pair[1] is None:
        raise InputError("sessions", "a chunk must hold positions and velocities")
    try:
        arrays = [np.asarray(a, dtype=np.float64) for a in pair]
    except (TypeError, ValueError):
        raise InputError("sessions", "positions and velocities must be numeric arrays") from None
    arrays = [a[np.newaxis] if a.ndim == 2 else a for a in arrays]
    positions, velocities = arrays
    if positions.ndim != 3 or positions.shape[1] != 2 or positions.shape[2] < 2:
        raise InputError("sessions", f"positions must have shape (k, 2, n), got {positions.shape}")
    if velocities.shape != positions.shape:
        raise InputError(
            "sessions", f"velocities {velocities.shape} do not match positions {positions.shape}"
        )
    if not (np.all(np.isfinite(positions)) and np.all(np.isfinite(velocities))):
        raise InputError("sessions", "positions and velocities must be finite")
    return positions, velocities


# ---------------------------------------------------------------------------------------------
# Training.


@dataclass(frozen=True)
class ExponentialEpsilon:
    """Exploration probability decaying from ``start`` towards ``end``: strictly decreasing.

    ``epsilon(i) = end + (start - end) * 0.5 ** (i / half_life)`` for session i = 0, 1, ...
    (**choice**; any callable from session index to probability can be given to `QLearner`).
    """

    start: float = 0.5
    end: float = 0.01
    half_life: float = 30.0

    def __post_init__(self) -> None:
        if not (0.0 <= self.end < self.start <= 1.0 and self.half_life > 0):
            raise InputError("epsilon", "need 0 <= end < start <= 1 and half_life > 0")

    def __call__(self, session: int) -> float:
        """Epsilon for session ``session`` (counted from 0)."""
        return self.end + (self.start - self.end) * 0.5 ** (session / self.half_life)


@dataclass
class LearningCurve:
    """Mean reward per step and RMS to the target, averaged over blocks of training sessions.

    Attributes
    ----------
    sessions
        Number of sessions trained at the end of each block.
    mean_reward
        Mean reward per step over the block.
    rms
        Mean over the block of each session's RMS position error to the target (units).
    epsilon
        Exploration probability of the block's last session.
    """

    sessions: list[int] = field(default_factory=list)
    mean_reward: list[float] = field(default_factory=list)
    rms: list[float] = field(default_factory=list)
    epsilon: list[float] = field(default_factory=list)

    def as_rows(self) -> list[dict[str, float]]:
        """One dict per block."""
        columns = ("sessions", "mean_reward", "rms", "epsilon")
        return [
            dict(zip(columns, values, strict=True))
            for values in zip(*self.as_columns(), strict=True)
        ]

    def as_columns(self) -> tuple[list[Any], ...]:
        """Return the columns sessions, mean_reward, rms and epsilon."""
        return (self.sessions, self.mean_reward, self.rms, self.epsilon)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the curve as CSV (``.csv``) or JSON (any other suffix), atomically."""
        path = Path(path)
        if path.suffix.lower() == ".csv":
            buffer = io.StringIO()
            writer = csv.DictWriter(
                buffer, fieldnames=["sessions", "mean_reward", "rms", "epsilon"]
            )
            writer.writeheader()
            writer.writerows(self.as_rows())
            data = buffer.getvalue().encode()
        else:
            data = json.dumps(self.as_rows(), indent=1).encode()
        write_atomic_bytes(path, data)
        return path


class QLearner:
    """Tabular Q-learning of a `CyberPlayer` from a stream of sessions.

    Parameters
    ----------
    learning_rate
        Step size alpha of the Q update (**choice**).
    discount
        Discount factor gamma (**choice**; 0.95 looks about 20 periods = 0.6 s ahead).
    epsilon
        Callable giving the exploration probability of session i; must not increase with i.
        Default `ExponentialEpsilon()`.
    q_init_scale
        Initial Q values are uniform in [-q_init_scale, 0] (**choice**).
    block_size
        Sessions per point of the learning curve.
    checkpoint_every, checkpoint_path
        Save the player to ``checkpoint_path`` every ``checkpoint_every`` sessions (and at the end).
    progress
        Show a tqdm progress bar: True, False, or None (only on a terminal).
    random_state
        Seed of the initial Q-table and of exploration; the same seed and sessions give the same
        Q-table. None draws fresh entropy (recorded in ``player.training_["seed"]``).

    Attributes
    ----------
    learning_curve_ : LearningCurve
        Scores per block of sessions.
    n_sessions_ : int
        Sessions trained so far (training continues where it stopped on the next `train` call).
    epsilon_ : float
        Exploration probability of the last session trained (1 before training).
    seed_ : int
        The entropy the random generators were seeded from.
    """

    learning_curve_: LearningCurve
    n_sessions_: int
    epsilon_: float
    seed_: int
    rng_: np.random.Generator

    def __init__(
        self,
        learning_rate: float = 0.1,
        discount: float = 0.95,
        epsilon: Callable[[int], float] | None = None,
        q_init_scale: float = 1e-3,
        block_size: int = 10,
        checkpoint_every: int | None = None,
        checkpoint_path: str | os.PathLike[str] | None = None,
        progress: bool | None = None,
        random_state: int | None = None,
    ) -> None:
        self.learning_rate = learning_rate
        self.discount = discount
        self.epsilon = epsilon
        self.q_init_scale = q_init_scale
        self.block_size = block_size
        self.checkpoint_every = checkpoint_every
        self.checkpoint_path = checkpoint_path
        self.progress = progress
        self.random_state = random_state

    def train(
        self, player: CyberPlayer, sessions: Iterable[Any], total: int | None = None
    ) -> QLearner:
        """Q-learn ``player`` from a stream of sessions, one compiled session at a time.

        Parameters
        ----------
        player
            The cyber player. On the first call its Q-table is created (seeded) unless it has
            one already (a loaded checkpoint: training then continues from it, counting
            sessions, and so epsilon, from the checkpoint's ``training_["n_sessions"]``).
        sessions
            Iterable of chunks (see `iter_sessions`), consumed lazily: only one chunk is held.
        total
            Expected number of sessions, for the progress bar only.

        Returns
        -------
        QLearner
            ``self``, with `learning_curve_` and `n_sessions_` updated and ``player.training_``
            summarising the training.
        """
        self._validate()
        if not hasattr(self, "n_sessions_"):
            self._start(player)
        schedule = self.epsilon or ExponentialEpsilon()
        block: list[tuple[float, float]] = []
        disable = None if self.progress is None else not self.progress
        with tqdm(total=total, disable=disable, unit="session") as bar:
            for session in iter_sessions(sessions, player.period):
                eps = self._epsilon(schedule)
                block.append(
                    player.play_session(session, self.learning_rate, self.discount, eps, self.rng_)
                )
                self.n_sessions_ += 1
                if len(block) == self.block_size:
                    self._close_block(block)
                self._maybe_checkpoint(player)
                bar.update()
        if block:
            self._close_block(block)
        player.training_ = self.summary()
        if self.checkpoint_path is not None:
            player.save(self.checkpoint_path)
        return self

    def summary(self) -> dict[str, Any]:
        """JSON-serialisable summary of the training so far (saved with the model)."""
        curve = self.learning_curve_
        return {
            "seed": self.seed_,
            "n_sessions": self.n_sessions_,
            "learning_rate": self.learning_rate,
            "discount": self.discount,
            "epsilon": repr(self.epsilon or ExponentialEpsilon()),
            "q_init_scale": self.q_init_scale,
            "final_mean_reward": curve.mean_reward[-1] if curve.mean_reward else None,
            "final_rms": curve.rms[-1] if curve.rms else None,
        }

    def _epsilon(self, schedule: Callable[[int], float]) -> float:
        eps = float(schedule(self.n_sessions_))
        if not 0.0 <= eps <= self.epsilon_:
            raise InputError(
                "epsilon",
                f"schedule gave {eps} at session {self.n_sessions_}: "
                "epsilon must lie in [0, 1] and never increase",
            )
        self.epsilon_ = eps
        return eps

    def _validate(self) -> None:
        if not 0.0 < self.learning_rate <= 1.0:
            raise InputError("learning_rate", f"must be in (0, 1], got {self.learning_rate}")
        if not 0.0 <= self.discount < 1.0:
            raise InputError("discount", f"must be in [0, 1), got {self.discount}")
        if self.block_size < 1:
            raise InputError("block_size", f"must be at least 1, got {self.block_size}")
        if self.checkpoint_every is not None and self.checkpoint_path is None:
            raise InputError("checkpoint_every", "needs a checkpoint_path")

    def _start(self, player: CyberPlayer) -> None:
        sequence = np.random.SeedSequence(self.random_state)
        self.seed_ = int(sequence.entropy)  # type: ignore[arg-type]
        q_seed, explore_seed = sequence.spawn(2)
        if not hasattr(player, "q_table_"):
            player.initialise_q(np.random.default_rng(q_seed), self.q_init_scale)
        self.rng_ = np.random.default_rng(explore_seed)
        self.n_sessions_ = int(getattr(player, "training_", {}).get("n_sessions", 0))
        self.epsilon_ = 1.0
        self.learning_curve_ = LearningCurve()

    def _close_block(self, block: list[tuple[float, float]]) -> None:
        rewards, rms = np.array(block).T
        curve = self.learning_curve_
        curve.sessions.append(self.n_sessions_)
        curve.mean_reward.append(float(rewards.mean()))
        curve.rms.append(float(rms.mean()))
        curve.epsilon.append(self.epsilon_)
        block.clear()

    def _maybe_checkpoint(self, player: CyberPlayer) -> None:
        if self.checkpoint_every and self.n_sessions_ % self.checkpoint_every == 0:
            player.training_ = self.summary()
            player.save(self.checkpoint_path)  # type: ignore[arg-type]


# ---------------------------------------------------------------------------------------------
# Persistence: one .npz file, no pickle.


def save_cyber_player(player: CyberPlayer, path: str | os.PathLike[str]) -> Path:
    """Write a trained player to ``path`` (one ``.npz``), atomically.

    The file holds arrays ``q_table`` (n_states, n_actions), ``edges`` (all interior bin edges),
    ``edge_counts`` (4,), ``actions`` (n_actions,) and the JSON metadata of
    `mirror_avatar.model_files.save_model`: format name and version, the dynamics parameters, the
    discretisation, the training summary and its seed. A player with ``"reference"`` features
    also stores its reference generator (arrays prefixed ``reference_``, metadata
    ``reference``), so the file alone plays.

    Raises
    ------
    InputError
        If a player with ``"reference"`` features has no `IMSGenerator` as its reference.
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
    if disc.needs_reference:
        if not isinstance(player.reference, IMSGenerator):
            raise InputError(path, "only a reference IMS generator can be saved with the player")
        reference_arrays, metadata["reference"] = player.reference.to_arrays()
        arrays |= {f"{REFERENCE_PREFIX}{k}": a for k, a in reference_arrays.items()}
    return save_model(path, FORMAT_NAME, FORMAT_VERSION, arrays, metadata)


def load_cyber_player(path: str | os.PathLike[str]) -> CyberPlayer:
    """Read a player written by `save_cyber_player`.

    Raises
    ------
    InputError
        ``path: problem`` when the file is missing, not a readable ``.npz`` (corrupt or
        truncated), of another format or version, or internally inconsistent (for instance a
        Q-table whose shape does not match the discretisation and action set).
    """
    arrays, metadata = load_model(
        path, FORMAT_NAME, FORMAT_VERSION, ("q_table", "edges", "edge_counts", "actions")
    )
    counts = arrays["edge_counts"]
    if counts.shape != (N_FEATURES,) or np.any(counts < 0) or counts.sum() != arrays["edges"].size:
        raise InputError(path, "bin edge counts do not match the bin edges")
    edges = np.split(arrays["edges"].astype(np.float64), np.cumsum(counts)[:-1])
    try:
        disc = Discretisation(metadata["discretisation"]["features"], tuple(edges))
        player = CyberPlayer(disc, arrays["actions"], **metadata["parameters"])
        actions = player.actions_
    except (InputError, KeyError, TypeError) as error:
        raise InputError(path, f"invalid model description ({error})") from None
    q = arrays["q_table"]
    if q.shape != (disc.n_states, actions.size):
        raise InputError(
            path,
            f"Q-table shape {q.shape} does not match {disc.n_states} states x "
            f"{actions.size} actions",
        )
    if q.dtype.kind != "f" or not np.all(np.isfinite(q)):
        raise InputError(path, "Q-table must hold finite floating-point values")
    player.q_table_ = q.astype(np.float64)
    player.training_ = metadata.get("training", {})
    if disc.needs_reference:
        if not isinstance(metadata.get("reference"), dict):
            raise InputError(path, "reference features but no reference generator in the file")
        prefixed = {
            k.removeprefix(REFERENCE_PREFIX): a
            for k, a in arrays.items()
            if k.startswith(REFERENCE_PREFIX)
        }
        player.reference = IMSGenerator.from_arrays(prefixed, metadata["reference"], path)
    return player
