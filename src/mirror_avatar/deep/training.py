"""DQN training of a deep cyber player from recorded sessions (METHODS sections 7-8).

As the tabular learner does (`mirror_avatar.learning.training`), the avatar takes the target's
place in each recorded session, sees the target's neighbours as they were recorded, moves its own
end effector epsilon-greedily and is rewarded for matching the target,
``rho = -(x - x_t)² - 0.1 (x' - x_t')² - eta u²`` (off-policy: the session does not react to
it). Instead of a table it trains a Q-network with DQN (Mnih et al. 2015): every transition goes
into a replay buffer, and every `DQNLearner.train_every` transitions a minibatch drawn uniformly
from the buffer takes one Adam step on the Huber loss against the targets
``r + gamma max_a' Q_target(s', a')`` of a target network, copied from the online network every
`DQNLearner.target_every` updates. METHODS section 8 gives the defaults: hidden layers
100-50-50, discount 0.95, minibatch 32, buffer 200 000, target copied every 150 steps, epsilon
from 1 multiplied by 0.9 per session down to 0.1 (`GeometricEpsilon`). The **choice**s it leaves
open are `DQNLearner`'s other parameters. A whole session runs in one compiled call
(`dqn_session`); single-threaded linear algebra makes training reproducible bit for bit on a
machine.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, Self

import numpy as np
from numba import njit
from numpy.typing import NDArray
from threadpoolctl import threadpool_limits

from mirror_avatar.common.errors import InputError
from mirror_avatar.deep.features import encode
from mirror_avatar.deep.network import adam_step, batch_q_values, greedy_action, loss_gradient
from mirror_avatar.deep.player import DeepCyberPlayer
from mirror_avatar.dynamics import Record, advance_hkb
from mirror_avatar.learning.kernels import compute_reward, draw_exploration
from mirror_avatar.learning.training import ImitationTask, SessionLearner
from mirror_avatar.sessions.session import Session

Array = NDArray[np.float64]
Ints = NDArray[np.int64]


@dataclass(frozen=True)
class GeometricEpsilon:
    """Exploration ``max(end, start * factor ** i)`` for session i = 0, 1, ... (METHODS 8)."""

    start: float = 1.0
    factor: float = 0.9
    end: float = 0.1

    def __post_init__(self) -> None:
        if not (0.0 <= self.end <= self.start <= 1.0 and 0.0 < self.factor < 1.0):
            raise InputError("epsilon", "need 0 <= end <= start <= 1 and 0 < factor < 1")

    def __call__(self, session: int) -> float:
        """Epsilon for session ``session`` (counted from 0)."""
        return max(self.end, self.start * self.factor**session)


@dataclass(frozen=True, eq=False)
class ReplayBuffer:
    """Transitions ``(s, a, r, s')`` in a ring of ``capacity`` (the oldest overwritten).

    Attributes
    ----------
    inputs, next_inputs
        Encoded states before and after, shape (capacity, n_features).
    actions
        Action indices, shape (capacity,).
    rewards
        Scaled rewards, shape (capacity,).
    counters
        Transitions ever stored, gradient updates made, shape (2,).
    """

    inputs: Array
    actions: Ints
    rewards: Array
    next_inputs: Array
    counters: Ints

    @classmethod
    def empty(cls, capacity: int, n_features: int) -> ReplayBuffer:
        """Make an empty buffer."""
        return cls(
            np.zeros((capacity, n_features)),
            np.zeros(capacity, dtype=np.int64),
            np.zeros(capacity),
            np.zeros((capacity, n_features)),
            np.zeros(2, dtype=np.int64),
        )

    @property
    def size(self) -> int:
        """Transitions held."""
        return int(min(self.counters[0], self.actions.size))


@njit(cache=True, nogil=True)
def _store(
    buffer: tuple[Array, Ints, Array, Array, Ints], s: Array, a: int, r: float, s2: Array
) -> int:
    """Store one transition; return how many the buffer holds."""
    inputs, actions, rewards, next_inputs, counters = buffer
    capacity = actions.size
    slot = counters[0] % capacity
    inputs[slot] = s
    actions[slot] = a
    rewards[slot] = r
    next_inputs[slot] = s2
    counters[0] += 1
    return min(counters[0], capacity)


@njit(cache=True, nogil=True)
def _update(
    online: Array,
    target: Array,
    sizes: Ints,
    adam: tuple[Array, Array, Array],
    buffer: tuple[Array, Ints, Array, Array, Ints],
    held: int,
    batch_size: int,
    discount: float,
    learning_rate: float,
    batch_draws: Array,
) -> int:
    """One DQN minibatch update of ``online`` (Adam); return the number of updates made so far.

    The minibatch is transitions ``floor(batch_draws * held)`` of the buffer, ``batch_draws``
    uniform on [0, 1), shape (batch_size,).
    """
    inputs, actions, rewards, next_inputs, counters = buffer
    first, second, gradient = adam
    picks = np.minimum((batch_draws * held).astype(np.int64), held - 1)
    batch_inputs = inputs[picks]
    next_values = batch_q_values(target, sizes, next_inputs[picks])
    targets = np.empty(batch_size)
    for b in range(batch_size):
        targets[b] = rewards[picks[b]] + discount * next_values[b].max()
    loss_gradient(online, sizes, batch_inputs, actions[picks], targets, gradient)
    counters[1] += 1
    adam_step(online, gradient, first, second, counters[1], learning_rate)
    return int(counters[1])


@njit(cache=True, nogil=True)
def dqn_session(
    online: Array,
    target: Array,
    sizes: Ints,
    adam: tuple[Array, Array, Array],
    buffer: tuple[Array, Ints, Array, Array, Ints],
    neighbour_x: Array,
    neighbour_v: Array,
    target_x: Array,
    target_v: Array,
    target_r: Array,
    layout: tuple[int, bool],
    actions: Array,
    p: Record,
    n_substeps: int,
    rates: tuple[float, float, float, float],
    schedule: tuple[int, int, int, int],
    learn: bool,
    exploration: tuple[Array, Ints],
    batch_draws: Array,
) -> tuple[float, float]:
    """Play one recorded session in the target's place, learning by DQN when ``learn``.

    Parameters
    ----------
    online, target, sizes
        The online and target networks' parameters (updated in place) and layer widths.
    adam
        Adam's first and second moments and a gradient buffer, each shaped like ``online``.
    buffer
        The replay buffer's arrays (`ReplayBuffer`), updated in place.
    neighbour_x, neighbour_v
        The target's neighbours' positions (units) and velocities (units/s), shape (n, m).
    target_x, target_v, target_r
        The target's positions, velocities and reference velocities, shape (n,).
    layout
        Neighbour slots and whether the reference velocity is an input.
    actions
        Accelerations (units/s²), shape (sizes[-1],).
    p, n_substeps
        The avatar's end effector; ``p.eta`` weighs the control effort in the reward.
    rates
        Epsilon, discount, Adam's learning rate and the factor on rewards.
    schedule
        Minibatch size, transitions per update, updates per target copy, transitions stored
        before the first update.
    learn
        False plays greedily (with epsilon 0) and changes nothing.
    exploration
        The exploration's random numbers (`mirror_avatar.learning.kernels.draw_exploration`),
        each of shape (n - 1,): step k explores with ``exploration[1][k]`` when
        ``exploration[0][k] < epsilon``.
    batch_draws
        Uniform on [0, 1), shape (at least the number of updates, batch size): row j picks
        the minibatch of the session's update j (`draw_batches`).

    Returns
    -------
    reward_sum : float
        Sum of the n - 1 rewards (unscaled).
    rms : float
        RMS of the avatar's position minus the target's over samples 1..n-1 (units).
    """
    epsilon, discount, learning_rate, reward_scale = rates
    batch_size, train_every, target_every, learning_starts = schedule
    n_slots, use_reference = layout
    n = target_x.size
    state = np.empty(sizes[0])
    following = np.empty(sizes[0])
    x, v = target_x[0], target_v[0]
    encode(x, v, target_r[0], neighbour_x[0], neighbour_v[0], n_slots, use_reference, state)
    draws, random_actions = exploration
    n_updates = 0
    reward_sum = 0.0
    squares = 0.0
    for k in range(n - 1):
        a = int(random_actions[k]) if draws[k] < epsilon else greedy_action(online, sizes, state)
        u = actions[a]
        x, v = advance_hkb(x, v, u, p.alpha, p.beta, p.gamma, p.omega, p.period, n_substeps)
        r = compute_reward(x, v, target_x[k + 1], target_v[k + 1], u, p.eta)
        encode(
            x,
            v,
            target_r[k + 1],
            neighbour_x[k + 1],
            neighbour_v[k + 1],
            n_slots,
            use_reference,
            following,
        )
        if learn:
            held = _store(buffer, state, a, r * reward_scale, following)
            if held >= learning_starts and buffer[4][0] % train_every == 0:
                updates = _update(
                    online,
                    target,
                    sizes,
                    adam,
                    buffer,
                    held,
                    batch_size,
                    discount,
                    learning_rate,
                    batch_draws[n_updates],
                )
                n_updates += 1
                if updates % target_every == 0:
                    target[:] = online
        state[:] = following
        reward_sum += r
        squares += (x - target_x[k + 1]) ** 2
    return reward_sum, math.sqrt(squares / max(n - 1, 1))


class DQNLearner(SessionLearner):
    """DQN training of a `DeepCyberPlayer` from a stream of sessions (module docstring).

    Parameters
    ----------
    player
        The deep cyber player to train, in place (its network is its policy).
    target
        Index of the target player in every session.
    learning_rate
        Adam's step size (**choice**).
    discount
        Discount factor gamma (METHODS section 8: 0.95).
    epsilon
        Exploration schedule; default `GeometricEpsilon()` (METHODS section 8).
    batch_size, buffer_size
        Minibatch and replay buffer sizes (METHODS section 8: 32 and 200 000).
    target_every
        Gradient updates between copies of the online network into the target network
        (METHODS section 8: 150 steps; with ``train_every = 1`` an update is a step).
    train_every
        Transitions per gradient update (**choice**: 1, an update per step).
    learning_starts
        Transitions stored before the first update (**choice**).
    reward_scale
        Factor on rewards before they enter the network's targets (**choice**: the rewards of
        a close imitation are of order 1e-3).
    block_size, checkpoint_every, checkpoint_path, progress, random_state
        As in `mirror_avatar.learning.training.SessionLearner`. The replay buffer, target
        network and Adam's moments live in the learner: training resumed from a checkpoint
        file continues from its network with them fresh.

    Attributes
    ----------
    learning_curve_, n_sessions_, epsilon_, seed_
        As in `SessionLearner`.
    replay_ : ReplayBuffer
        The transitions held.
    target_weights_ : ndarray
        The target network's parameters.
    """

    replay_: ReplayBuffer
    target_weights_: Array

    def __init__(
        self,
        player: DeepCyberPlayer,
        target: int = 1,
        learning_rate: float = 1e-3,
        discount: float = 0.95,
        epsilon: Callable[[int], float] | None = None,
        batch_size: int = 32,
        buffer_size: int = 200_000,
        target_every: int = 150,
        train_every: int = 1,
        learning_starts: int = 1000,
        reward_scale: float = 100.0,
        block_size: int = 10,
        checkpoint_every: int | None = None,
        checkpoint_path: str | os.PathLike[str] | None = None,
        progress: bool | None = None,
        random_state: int | None = None,
    ) -> None:
        super().__init__(
            player,
            target,
            epsilon or GeometricEpsilon(),
            block_size,
            checkpoint_every,
            checkpoint_path,
            progress,
            random_state,
        )
        self.learning_rate = learning_rate
        self.discount = discount
        self.batch_size = batch_size
        self.buffer_size = buffer_size
        self.target_every = target_every
        self.train_every = train_every
        self.learning_starts = learning_starts
        self.reward_scale = reward_scale

    def partial_fit(self, sessions: Iterable[Session], total: int | None = None) -> Self:
        """Learn from more sessions (see `SessionLearner.partial_fit`), single-threaded."""
        with threadpool_limits(1):
            return super().partial_fit(sessions, total)

    def _check(self) -> None:
        if not 0.0 < self.learning_rate <= 1.0:
            raise InputError("learning_rate", f"must be in (0, 1], got {self.learning_rate}")
        if not 0.0 <= self.discount < 1.0:
            raise InputError("discount", f"must be in [0, 1), got {self.discount}")
        for name in ("batch_size", "buffer_size", "target_every", "train_every"):
            if getattr(self, name) < 1:
                raise InputError(name, f"must be at least 1, got {getattr(self, name)}")
        if not self.batch_size <= self.learning_starts <= self.buffer_size:
            raise InputError("learning_starts", "must lie between batch_size and buffer_size")
        if not self.reward_scale > 0:
            raise InputError("reward_scale", f"must be positive, got {self.reward_scale}")

    def _initialise(self, seed: np.random.SeedSequence) -> None:
        if not hasattr(self.player, "weights_"):
            self.player.initialise_policy(np.random.default_rng(seed))
        self.target_weights_ = self.player.weights_.copy()
        self.replay_ = ReplayBuffer.empty(self.buffer_size, int(self.player.sizes_[0]))
        weights = self.player.weights_
        self._adam = (np.zeros_like(weights), np.zeros_like(weights), np.zeros_like(weights))

    def _begin(self) -> None:
        self._policy = self.player.policy_
        self._record = self.player.params.record()

    def _play(self, task: ImitationTask, epsilon: float) -> tuple[float, float]:
        return play_deep_task(self, task, epsilon, True, self.rng_)

    def _hyperparameters(self) -> dict[str, Any]:
        return {
            "agent": "dqn",
            "learning_rate": self.learning_rate,
            "discount": self.discount,
            "batch_size": self.batch_size,
            "buffer_size": self.buffer_size,
            "target_every": self.target_every,
            "train_every": self.train_every,
            "learning_starts": self.learning_starts,
            "reward_scale": self.reward_scale,
            "updates": int(self.replay_.counters[1]),
        }


def play_deep_task(
    learner: DQNLearner,
    task: ImitationTask,
    epsilon: float,
    learn: bool,
    rng: np.random.Generator,
) -> tuple[float, float]:
    """Run `dqn_session` on one task with the learner's networks, buffer and settings.

    ``rng`` draws the exploration (`mirror_avatar.learning.kernels.draw_exploration`), then the
    minibatches (`draw_batches`).

    Returns
    -------
    mean_reward, rms : float
        Mean reward per step and RMS position error to the target (units).
    """
    policy = learner._policy
    if policy.use_reference and not np.all(np.isfinite(task.target_r)):
        raise InputError("sessions", "reference features need the target's reference velocities")
    replay = learner.replay_
    n_steps = task.target_x.size - 1
    total, rms = dqn_session(
        policy.weights,
        learner.target_weights_,
        policy.sizes,
        learner._adam,
        (replay.inputs, replay.actions, replay.rewards, replay.next_inputs, replay.counters),
        np.ascontiguousarray(task.neighbour_x.T),
        np.ascontiguousarray(task.neighbour_v.T),
        task.target_x,
        task.target_v,
        task.target_r,
        (policy.n_slots, policy.use_reference),
        policy.actions,
        learner._record[0],
        policy.n_substeps,
        (epsilon, learner.discount, learner.learning_rate, learner.reward_scale),
        (learner.batch_size, learner.train_every, learner.target_every, learner.learning_starts),
        learn,
        draw_exploration(rng, n_steps, policy.actions.size),
        draw_batches(rng, n_steps, learner, learn),
    )
    return total / max(n_steps, 1), rms


def draw_batches(rng: np.random.Generator, n_steps: int, learner: DQNLearner, learn: bool) -> Array:
    """Draw the minibatches of a session of ``n_steps`` transitions, uniform on [0, 1).

    Shape (updates, batch size): one row for each update the session can make, one every
    ``train_every`` transitions stored; none when it does not ``learn``.
    """
    n_updates = -(-n_steps // learner.train_every) if learn else 0
    return rng.random((n_updates, learner.batch_size))


def greedy_deep(player: DeepCyberPlayer) -> Callable[[ImitationTask], tuple[float, float]]:
    """Return how a deep player plays a task greedily with its network: no learning.

    The function returned plays one task in the target's place and returns its mean reward per
    step and RMS position error to the target (units), as
    `mirror_avatar.learning.training.score_tasks` wants. It plays through a learner of one
    transition's buffer that never learns, so the player's network is left as it is.
    """
    learner = DQNLearner(player, batch_size=1, buffer_size=1, learning_starts=1)
    learner._initialise(np.random.SeedSequence(learner.random_state))
    learner._begin()
    rng = np.random.default_rng(0)
    return lambda task: play_deep_task(learner, task, 0.0, False, rng)
