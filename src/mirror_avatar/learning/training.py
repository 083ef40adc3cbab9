"""Training a cyber player: the `QLearner` estimator, its exploration schedule and learning curve.

The learner consumes recorded sessions (`mirror_avatar.sessions.session.Session`, streamed: only
one is held at a time) in which a **target player** plays with its neighbours; in each, the avatar
takes the target's place and learns off-policy from what the target did (`learn_session`). As in
scikit-learn's ``MiniBatchKMeans``, `QLearner.fit` (a fresh start) and `QLearner.partial_fit` (more
sessions) share one per-session step, and the learner owns its state (trailing underscores).
Exploration decreases monotonically from session to session; the Q-table starts random (seeded).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple, Self

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.progress import progress_bar
from mirror_avatar.files.atomic import write_atomic_bytes
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.learning.discretisation import REFERENCE
from mirror_avatar.learning.kernels import draw_exploration, learn_session, mean_track
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.signature import DEFAULT_BINS, count_velocities

Array = NDArray[np.float64]


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


CURVE_COLUMNS = ("sessions", "mean_reward", "rms", "epsilon")


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
        columns = (self.sessions, self.mean_reward, self.rms, self.epsilon)
        return [
            dict(zip(CURVE_COLUMNS, values, strict=True)) for values in zip(*columns, strict=True)
        ]

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the curve as CSV (``.csv``) or JSON (any other suffix), atomically."""
        path = Path(path)
        if path.suffix.lower() == ".csv":
            buffer = io.StringIO()
            writer = csv.DictWriter(buffer, fieldnames=CURVE_COLUMNS)
            writer.writeheader()
            writer.writerows(self.as_rows())
            data = buffer.getvalue().encode()
        else:
            data = json.dumps(self.as_rows(), indent=1).encode()
        write_atomic_bytes(path, data)
        return path


@dataclass(frozen=True, eq=False)
class ImitationTask:
    """One session seen from the avatar in the target's place: arrays at the control period.

    Attributes
    ----------
    partner_x, partner_v
        Mean position (units) and velocity (units/s) of the target's neighbours, shape (n,).
    neighbour_x, neighbour_v
        The neighbours' own positions and velocities, shape (m, n).
    target_x, target_v, target_r
        The target's positions, velocities and reference velocities (units/s; its last,
        undefined reference repeats the one before; NaN throughout when it has none).
    """

    partner_x: Array
    partner_v: Array
    neighbour_x: Array
    neighbour_v: Array
    target_x: Array
    target_v: Array
    target_r: Array

    @classmethod
    def from_session(cls, session: Session, target: int, period: float) -> ImitationTask:
        """Take the target's place in ``session``.

        Raises
        ------
        InputError
            If the session is sampled at another period, has no player ``target``, the target
            has no neighbour, or positions and velocities are not finite.
        """
        if not math.isclose(session.period, period):
            raise InputError("sessions", f"sampled every {session.period} s, not every {period} s")
        if not 0 <= target < session.n_players:
            raise InputError("sessions", f"no player {target} in a session of {session.n_players}")
        neighbours = np.flatnonzero(session.graph[target])
        if neighbours.size == 0:
            raise InputError("sessions", f"the target (player {target}) observes no one")
        m, n = neighbours.size, session.n_samples
        rows = np.empty((2 * m + 5, n))
        if not _fill_task(
            rows, session.positions, session.velocities, session.references, neighbours, target
        ):
            raise InputError("sessions", "positions and velocities must be finite")
        return cls(rows[0], rows[1], rows[2 : 2 + m], rows[2 + m : 2 + 2 * m], *rows[2 + 2 * m :])


@njit(cache=True, nogil=True)
def _fill_task(
    rows: Array,
    positions: Array,
    velocities: Array,
    references: Array,
    neighbours: NDArray[np.int64],
    target: int,
) -> bool:
    """Fill ``rows`` (2 m + 5, n) with the fields of `ImitationTask`, in their order.

    ``positions``, ``velocities`` and ``references`` are a session's, shape (N, n), and
    ``neighbours`` the target's (m,); the neighbours' means are taken by `mean_track`. One
    block of rows filled in place, not seven arrays returned: each array handed back from
    compiled code costs a conversion. Returns False if a position or velocity is not finite.
    """
    m = neighbours.size
    for j in range(m):
        rows[2 + j] = positions[neighbours[j]]
        rows[2 + m + j] = velocities[neighbours[j]]
    rows[2 + 2 * m] = positions[target]
    rows[3 + 2 * m] = velocities[target]
    for value in rows[2 : 4 + 2 * m].ravel():
        if not np.isfinite(value):
            return False
    rows[0] = mean_track(rows[2 : 2 + m])
    rows[1] = mean_track(rows[2 + m : 2 + 2 * m])
    reference = rows[4 + 2 * m]
    reference[:] = references[target]
    if reference.size > 1 and np.isnan(reference[-1]):
        reference[-1] = reference[-2]
    return True


class PolicyArguments(NamedTuple):
    """A cyber player's arguments of `learn_session`, in its order."""

    q_table: Array
    """The Q-table, shape (cells, actions), updated in place."""
    mode: int
    """The feature code of its cells (`mirror_avatar.learning.discretisation`)."""
    edges: Array
    """The cells' bin edges, flat."""
    offsets: NDArray[np.int64]
    """Where each feature's edges start in ``edges``."""
    actions: Array
    """Accelerations (units/s²), shape (actions,)."""
    record: Any
    """The end effector, a record of `mirror_avatar.dynamics.PARAMS_DTYPE`."""
    n_substeps: int
    """RK4 substeps per control period."""


def policy_arguments(player: CyberPlayer) -> PolicyArguments:
    """Return the player's arguments of `learn_session` (its Q-table is updated in place)."""
    policy = player.policy_
    disc = policy.discretisation
    return PolicyArguments(
        policy.q_table,
        disc.mode,
        disc.flat_edges,
        disc.offsets,
        policy.actions,
        player.params.record()[0],
        policy.n_substeps,
    )


def play_task(
    policy: PolicyArguments,
    task: ImitationTask,
    learning_rate: float,
    discount: float,
    epsilon: float,
    rng: np.random.Generator,
) -> tuple[float, float]:
    """Play one task with `learn_session`, updating the Q-table when ``learning_rate`` > 0.

    Parameters
    ----------
    policy
        `policy_arguments` of the player.
    task
        The session, seen from the target's place.
    learning_rate, discount, epsilon
        As in `learn_session`.
    rng
        Draws the exploration (`draw_exploration`).

    Returns
    -------
    mean_reward, rms : float
        Mean reward per step and RMS position error to the target (units).

    Raises
    ------
    InputError
        If the player's features need the target's reference velocity and the task has none.
    """
    q, mode, edges, offsets, actions, record, n_substeps = policy
    if mode == REFERENCE and not np.all(np.isfinite(task.target_r)):
        raise InputError("sessions", "reference features need the target's reference velocities")
    total, rms = learn_session(
        q,
        task.partner_x,
        task.partner_v,
        task.target_x,
        task.target_v,
        task.target_r,
        mode,
        edges,
        offsets,
        actions,
        record,
        n_substeps,
        learning_rate,
        discount,
        epsilon,
        *draw_exploration(rng, task.target_x.size - 1, actions.size),
    )
    return total / max(task.target_x.size - 1, 1), rms


def greedy_tabular(player: CyberPlayer) -> Callable[[ImitationTask], tuple[float, float]]:
    """Return how a tabular player plays a task greedily: no learning, no exploration.

    The function returned plays one task in the target's place and returns its mean reward per
    step and RMS position error to the target (units), as `score_tasks` wants.
    """
    rng = np.random.default_rng(0)
    policy = policy_arguments(player)
    return lambda task: play_task(policy, task, 0.0, 0.0, 0.0, rng)


def score_tasks(
    play: Callable[[ImitationTask], tuple[float, float]],
    sessions: Iterable[Session],
    target: int,
    period: float,
) -> tuple[Array, Array]:
    """Score ``play`` (mean reward and RMS of one task) on each session in ``target``'s place.

    Returns
    -------
    mean_reward, rms : ndarray, shape (n_sessions,)
    """
    scores = [play(ImitationTask.from_session(s, target, period)) for s in sessions]
    return np.array([r for r, _ in scores]), np.array([e for _, e in scores])


class SessionLearner:
    """What every learner from a stream of sessions shares (the tabular and the deep one).

    A subclass gives the policy's own steps: `_initialise` (a fresh policy, seeded),
    `_begin` (before a batch of sessions), `_play` (learn from one session in the target's
    place), `_hyperparameters` (recorded in the summary) and `_check` (its own options).

    Parameters
    ----------
    player
        The avatar to train, in place. Its policy is created (seeded) when training starts
        unless it has one (a loaded checkpoint: training then continues from it, counting
        sessions, and so epsilon, from its ``training_["n_sessions"]``).
    target
        Index of the target player in every session: the one the avatar learns to imitate.
    epsilon
        Callable giving the exploration probability of session i; must not increase with i.
    block_size
        Sessions per point of the learning curve.
    checkpoint_every, checkpoint_path
        Save the player to ``checkpoint_path`` every ``checkpoint_every`` sessions (and at the end).
    progress
        Show progress: True (a tqdm bar), False, or None (a tqdm bar on a terminal, plain lines
        off one; `mirror_avatar.common.progress.progress_bar`).
    random_state
        Seed of the initial policy and of exploration; the same seed and sessions give the same
        policy. None draws fresh entropy (recorded in ``player.training_["seed"]``).

    Attributes
    ----------
    learning_curve_ : LearningCurve
        Scores per block of sessions.
    n_sessions_ : int
        Sessions trained so far.
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
        player: Any,
        target: int,
        epsilon: Callable[[int], float],
        block_size: int,
        checkpoint_every: int | None,
        checkpoint_path: str | os.PathLike[str] | None,
        progress: bool | None,
        random_state: int | None,
    ) -> None:
        self.player = player
        self.target = target
        self.epsilon = epsilon
        self.block_size = block_size
        self.checkpoint_every = checkpoint_every
        self.checkpoint_path = checkpoint_path
        self.progress = progress
        self.random_state = random_state

    def fit(self, sessions: Iterable[Session], total: int | None = None) -> Self:
        """Start training afresh (seeded) and learn from ``sessions``; see `partial_fit`."""
        self._validate()
        self._start()
        return self.partial_fit(sessions, total)

    def partial_fit(self, sessions: Iterable[Session], total: int | None = None) -> Self:
        """Learn from more sessions, continuing where the last call stopped.

        Parameters
        ----------
        sessions
            Sessions, consumed lazily: only one is held at a time.
        total
            Expected number of sessions, for the progress bar only.

        Returns
        -------
        SessionLearner
            ``self``, with `learning_curve_` and `n_sessions_` updated and ``player.training_``
            summarising the training.
        """
        self._validate()
        if not hasattr(self, "n_sessions_"):
            self._start()
        self._begin()
        block: list[tuple[float, float]] = []
        with progress_bar(total, "training", "session", self.progress) as bar:
            for session in sessions:
                block.append(self._learn(session))
                if len(block) == self.block_size:
                    self._close_block(block)
                self._maybe_checkpoint()
                bar.update()
        if block:
            self._close_block(block)
        self.player.training_ = self.summary()
        if self.checkpoint_path is not None:
            self.player.save(self.checkpoint_path)
        return self

    def _learn(self, session: Session) -> tuple[float, float]:
        """Learn from one session: the step `fit` and `partial_fit` share."""
        task = ImitationTask.from_session(session, self.target, self.player.period)
        scores = self._play(task, self._epsilon(self.epsilon))
        self.player.target_counts_ += count_velocities(session.velocities[self.target])
        self.n_sessions_ += 1
        return scores

    def summary(self) -> dict[str, Any]:
        """JSON-serialisable summary of the training so far (saved with the model)."""
        curve = self.learning_curve_
        return (
            {"seed": self.seed_, "n_sessions": self.n_sessions_}
            | self._hyperparameters()
            | {
                "epsilon": repr(self.epsilon),
                "final_mean_reward": curve.mean_reward[-1] if curve.mean_reward else None,
                "final_rms": curve.rms[-1] if curve.rms else None,
            }
        )

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
        self._check()
        if self.block_size < 1:
            raise InputError("block_size", f"must be at least 1, got {self.block_size}")
        if self.checkpoint_every is not None and self.checkpoint_path is None:
            raise InputError("checkpoint_every", "needs a checkpoint_path")

    def _start(self) -> None:
        sequence = np.random.SeedSequence(self.random_state)
        self.seed_ = int(sequence.entropy)  # type: ignore[arg-type]
        policy_seed, explore_seed = sequence.spawn(2)
        self._initialise(policy_seed)
        if not hasattr(self.player, "target_counts_"):
            self.player.target_counts_ = np.zeros(DEFAULT_BINS.n)
        self.rng_ = np.random.default_rng(explore_seed)
        self.n_sessions_ = int(getattr(self.player, "training_", {}).get("n_sessions", 0))
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

    def _maybe_checkpoint(self) -> None:
        if self.checkpoint_every and self.n_sessions_ % self.checkpoint_every == 0:
            self.player.training_ = self.summary()
            self.player.save(self.checkpoint_path)

    def _check(self) -> None:
        """Refuse options out of range (raise `InputError`)."""
        raise NotImplementedError

    def _initialise(self, seed: np.random.SeedSequence) -> None:
        """Give the player a fresh policy from ``seed`` unless it has one."""
        raise NotImplementedError

    def _begin(self) -> None:
        """Prepare to learn from a batch of sessions."""
        raise NotImplementedError

    def _play(self, task: ImitationTask, epsilon: float) -> tuple[float, float]:
        """Learn from one session; return its mean reward per step and RMS to the target."""
        raise NotImplementedError

    def _hyperparameters(self) -> dict[str, Any]:
        """Return the learner's own settings, recorded in `summary`."""
        raise NotImplementedError


class QLearner(SessionLearner):
    """Tabular Q-learning of a `CyberPlayer` from a stream of sessions.

    Parameters
    ----------
    player
        The cyber player to train, in place (its Q-table is its policy).
    target
        Index of the target player in every session.
    learning_rate
        Step size alpha of the Q update (**choice**).
    discount
        Discount factor gamma (**choice**; 0.95 looks about 20 periods = 0.6 s ahead).
    epsilon
        Exploration schedule; default `ExponentialEpsilon()`.
    q_init_scale
        Initial Q values are uniform in [-q_init_scale, 0] (**choice**).
    block_size, checkpoint_every, checkpoint_path, progress, random_state
        As in `SessionLearner`.

    Attributes
    ----------
    learning_curve_, n_sessions_, epsilon_, seed_
        As in `SessionLearner`.
    """

    def __init__(
        self,
        player: CyberPlayer,
        target: int = 1,
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
        super().__init__(
            player,
            target,
            epsilon or ExponentialEpsilon(),
            block_size,
            checkpoint_every,
            checkpoint_path,
            progress,
            random_state,
        )
        self.learning_rate = learning_rate
        self.discount = discount
        self.q_init_scale = q_init_scale

    def _check(self) -> None:
        if not 0.0 < self.learning_rate <= 1.0:
            raise InputError("learning_rate", f"must be in (0, 1], got {self.learning_rate}")
        if not 0.0 <= self.discount < 1.0:
            raise InputError("discount", f"must be in [0, 1), got {self.discount}")

    def _initialise(self, seed: np.random.SeedSequence) -> None:
        if not hasattr(self.player, "q_table_"):
            self.player.initialise_q(np.random.default_rng(seed), self.q_init_scale)

    def _begin(self) -> None:
        self._policy = policy_arguments(self.player)

    def _play(self, task: ImitationTask, epsilon: float) -> tuple[float, float]:
        return play_task(self._policy, task, self.learning_rate, self.discount, epsilon, self.rng_)

    def _hyperparameters(self) -> dict[str, Any]:
        return {
            "learning_rate": self.learning_rate,
            "discount": self.discount,
            "q_init_scale": self.q_init_scale,
        }
