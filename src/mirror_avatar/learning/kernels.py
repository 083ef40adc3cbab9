"""Compiled Q-learning: reward, exploration, the update, and one learning session (METHODS 7).

During training the avatar is rewarded for matching the **target player** ``[x_t, x_t']`` (the
person it must imitate, who plays with the same neighbours):

    rho = -(x - x_t)² - 0.1 (x' - x_t')² - eta u²,

and learns by tabular Q-learning, ``Q(s,a) += alpha [r + gamma max_a' Q(s',a') - Q(s,a)]``, with
epsilon-greedy exploration. `learn_session` runs a whole recorded session in one compiled call:
the avatar takes the target's place, sees the target's neighbours as they were recorded, and
learns off-policy from what the target did.

The exploration's random numbers are drawn before the compiled call (`draw_exploration`), and
the kernels take them as arrays. A `numpy.random.Generator` is never an argument of a compiled
function: numba unboxes one by calling Python (``ctypes.cast``) on every call without checking
the result, so an interruption that raises there (Ctrl+C's `KeyboardInterrupt`, the console's
SIGTERM) crashes the process with a segmentation fault.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mirror_avatar.dynamics import Record, advance_hkb
from mirror_avatar.learning.discretisation import state_index

Array = NDArray[np.float64]
Ints = NDArray[np.int64]

VELOCITY_WEIGHT = 0.1
"""Weight of the velocity error in the reward (METHODS section 7)."""


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
def choose_action(q: Array, s: int, epsilon: float, draw: float, random_action: int) -> int:
    """Epsilon-greedy choice in state ``s``: ``random_action`` if ``draw < epsilon``, else greedy.

    ``draw`` is uniform on [0, 1) and ``random_action`` uniform over the actions
    (`draw_exploration`), so the random action comes with probability epsilon.
    """
    if draw < epsilon:
        return random_action
    return int(np.argmax(q[s]))


def draw_exploration(rng: np.random.Generator, n_steps: int, n_actions: int) -> tuple[Array, Ints]:
    """Draw the random numbers of ``n_steps`` epsilon-greedy choices among ``n_actions``.

    Returns
    -------
    draws : numpy.ndarray
        Uniform on [0, 1), shape (n_steps,), drawn first.
    random_actions : numpy.ndarray
        Uniform integers in [0, n_actions), shape (n_steps,).
    """
    return rng.random(n_steps), rng.integers(0, n_actions, n_steps)


@njit(cache=True)
def update_q(
    q: Array, s: int, a: int, r: float, s_next: int, learning_rate: float, discount: float
) -> None:
    """Q-learning update ``Q(s,a) += alpha [r + gamma max_a' Q(s',a') - Q(s,a)]``, in place."""
    q[s, a] += learning_rate * (r + discount * np.max(q[s_next]) - q[s, a])


@njit(cache=True)
def mean_track(neighbours: Array) -> Array:
    """Return the neighbours' mean at every sample, shape (n,), from tracks (m, n), m >= 1.

    Summed in the neighbours' order, as `mirror_avatar.players.base.neighbour_mean` sums them in
    play, so each sample's mean is the one a player sees.
    """
    means = neighbours[0].copy()
    for j in range(1, neighbours.shape[0]):
        means += neighbours[j]
    return means / neighbours.shape[0]


@njit(cache=True, nogil=True)
def learn_session(
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
    p: Record,
    n_substeps: int,
    learning_rate: float,
    discount: float,
    epsilon: float,
    draws: Array,
    random_actions: Ints,
) -> tuple[float, float]:
    """Play one recorded session in the target's place and Q-learn from it, updating ``q``.

    The avatar starts at the target's initial state; at each sample k it observes its own state
    and its partner's (the mean of the target's neighbours, `mean_track`), picks an action
    epsilon-greedily, integrates its HKB over one period and is rewarded against the target at
    k + 1. With ``learning_rate = 0`` and ``epsilon = 0`` this is a greedy evaluation that leaves
    ``q`` unchanged.

    Parameters
    ----------
    q
        Q-table, shape (n_states, n_actions), updated in place.
    partner_x, partner_v
        The mean position (units) and velocity (units/s) of the target's neighbours, shape (n,).
    target_x, target_v
        The target's positions and velocities, shape (n,).
    target_r
        The target's reference velocity (units/s), shape (n,): the avatar's own reference in
        ``"reference"`` features, unused otherwise.
    mode, edges, offsets
        The state discretisation (`Discretisation.mode`, ``flat_edges``, ``offsets``).
    actions
        Accelerations (units/s²), shape (n_actions,).
    p, n_substeps
        The avatar's end effector (see `mirror_avatar.dynamics.integrate_hkb`); ``p.eta`` weighs
        the control effort in the reward.
    learning_rate, discount, epsilon
        Q-learning step size, discount factor and exploration probability.
    draws, random_actions
        The exploration's random numbers (`draw_exploration`), shape (n - 1,): step k explores
        with ``random_actions[k]`` when ``draws[k] < epsilon``.

    Returns
    -------
    reward_sum : float
        Sum of the n - 1 rewards.
    rms : float
        Root mean square of the avatar's position minus the target's over samples 1..n-1 (units).
    """
    n = target_x.size
    alpha, beta, gamma, omega, period, eta = p.alpha, p.beta, p.gamma, p.omega, p.period, p.eta
    x, v = target_x[0], target_v[0]
    s = state_index(x, v, partner_x[0], partner_v[0], target_r[0], mode, edges, offsets)
    reward_sum = 0.0
    squares = 0.0
    for k in range(n - 1):
        a = choose_action(q, s, epsilon, draws[k], random_actions[k])
        u = actions[a]
        x, v = advance_hkb(x, v, u, alpha, beta, gamma, omega, period, n_substeps)
        r = compute_reward(x, v, target_x[k + 1], target_v[k + 1], u, eta)
        s_next = state_index(
            x, v, partner_x[k + 1], partner_v[k + 1], target_r[k + 1], mode, edges, offsets
        )
        update_q(q, s, a, r, s_next, learning_rate, discount)
        s = s_next
        reward_sum += r
        squares += (x - target_x[k + 1]) ** 2
    return reward_sum, math.sqrt(squares / max(n - 1, 1))
