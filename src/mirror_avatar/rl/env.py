"""A Gymnasium environment: the cyber player's view of a recorded session (METHODS section 7).

One episode is one recorded `mirror_avatar.sessions.session.Session` in which the agent takes the
place of
the **target player**: the other players replay what they did (`RecordedPlayer.on_grid`), the
agent drives the same HKB end effector as `mirror_avatar.learning.agent.CyberPlayer` with the same
action set, and is rewarded for matching what the target did, with the same compiled reward.
Episodes run on the engine's own step loop (`mirror_avatar.engine.loop.Engine`) with the session's
graph, so the agent observes the mean of the target's neighbours as every player does, or, in a
group, each neighbour ("dynamic input", the deep cyber player's input). Any Gymnasium agent can
thus be compared with the tabular and the deep cyber players. Needs the ``rl`` extra.

Seeding follows Gymnasium: ``reset(seed=s)`` reseeds ``self.np_random``, which picks the session
(from a given list) or is passed to a session-making callable.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from typing import Any, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from mirror_avatar.common.errors import InputError
from mirror_avatar.deep.features import count_features, encode
from mirror_avatar.dynamics import integrate_hkb
from mirror_avatar.engine.loop import Engine
from mirror_avatar.files.trials import PLAYING_RANGE
from mirror_avatar.learning.acceleration_player import AccelerationPlayer
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.learning.kernels import compute_reward
from mirror_avatar.players.base import Observation, Player, partner_state
from mirror_avatar.players.recorded import RecordedPlayer
from mirror_avatar.sessions.session import Session

VELOCITY_BOUND = 5.0
"""Velocities (units/s) in continuous observations are clipped to ±VELOCITY_BOUND."""

DYNAMIC_BOUND = 100.0
"""``"dynamic"`` observations (scaled features of order 1) are clipped to ±DYNAMIC_BOUND."""

SessionSource = Sequence[Session] | Callable[[np.random.Generator], Session] | Iterator[Session]


class ActionPlayer(Player):
    """The agent's avatar: the cyber player's end effector driven by the action it is given.

    Parameters
    ----------
    player
        Supplies the end effector, the action set and the period.
    """

    def __init__(self, player: AccelerationPlayer) -> None:
        self.period = player.period
        self.label = "agent"
        self.actions = player.actions_
        self.n_substeps = int(player.n_substeps)
        self._record = player.params.record()
        self.start = (0.0, 0.0)
        self.state = self.start
        self.action = 0

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start at `start` (the target's initial state, set by the environment)."""
        self.state = self.start
        return self.state

    def step(self, observation: Observation) -> tuple[float, float]:
        """Apply ``actions[action]`` for one period."""
        self.last_control = float(self.actions[self.action])
        x, v = self.state
        self.state = integrate_hkb(x, v, self.last_control, self._record[0], self.n_substeps)
        return self.state


class MirrorGameEnv(gym.Env[Any, Any]):
    """The cyber player in the target's place in recorded sessions, rewarded for matching it.

    Parameters
    ----------
    sessions
        Where episodes come from: a list of sessions (each reset picks one with
        ``self.np_random``), a callable taking ``self.np_random`` and returning a session, or an
        iterator of sessions, advanced at each reset. Sessions are sampled at the control period.
    player
        Supplies the dynamics, actions and reward weight (and, for ``"discrete"``
        observations, the tabular player's discretisation); default ``CyberPlayer()``.
    observation
        ``"continuous"``: ``[x, x', x_p, x_p']`` as float32 (the partner is the mean of the
        target's neighbours; velocities clipped to ±`VELOCITY_BOUND`); ``"discrete"``: the
        Q-table cell of that state (with the target's reference velocity as the avatar's own for
        ``"reference"`` features); ``"dynamic"``: the deep cyber player's input
        (`mirror_avatar.deep.features.encode`: own state, the neighbours' mean and ``n_slots``
        neighbour slots) as float32, for groups whose graph changes from session to session.
    target
        Index of the target player in the sessions.
    n_slots
        Neighbour slots of ``"dynamic"`` observations (the most neighbours the target has).

    Notes
    -----
    The avatar starts each episode at the target's initial state. Step k applies action a for
    one period, rewards ``-(x - x_t)² - 0.1 (x' - x_t')² - eta u²`` against the target at k + 1
    and ends the episode (truncated) when the session's samples run out. ``info`` holds the
    target's position and velocity.
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(
        self,
        sessions: SessionSource,
        player: AccelerationPlayer | None = None,
        observation: Literal["continuous", "discrete", "dynamic"] = "continuous",
        target: int = 1,
        n_slots: int = 3,
    ) -> None:
        self.player = player or CyberPlayer()
        self.observation = observation
        self.target = target
        self.n_slots = n_slots
        self._source = sessions
        self._fixed = [] if callable(sessions) or isinstance(sessions, Iterator) else sessions
        if not (self._fixed or callable(sessions) or isinstance(sessions, Iterator)):
            raise InputError("sessions", "give sessions, a function making one, or an iterator")
        self._agent = ActionPlayer(self.player)
        self.action_space = spaces.Discrete(self._agent.actions.size)
        if observation == "continuous":
            low, high = PLAYING_RANGE
            self.observation_space = spaces.Box(
                np.array([low, -VELOCITY_BOUND, low, -VELOCITY_BOUND], dtype=np.float32),
                np.array([high, VELOCITY_BOUND, high, VELOCITY_BOUND], dtype=np.float32),
                dtype=np.float32,
            )
        elif observation == "discrete" and isinstance(self.player, CyberPlayer):
            self._cells = self.player.discretisation_
            self.observation_space = spaces.Discrete(self._cells.n_states)
        elif observation == "dynamic":
            size = count_features(n_slots, False)
            bound = DYNAMIC_BOUND
            self.observation_space = spaces.Box(-bound, bound, (size,), dtype=np.float32)
        else:
            raise InputError(
                "observation",
                f"must be 'continuous', 'discrete' (for a tabular player) or 'dynamic', not "
                f"{observation!r}",
            )

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Start an episode on the next session; return the first observation and info."""
        super().reset(seed=seed)
        session = self._next_session()
        self._session = session
        self._agent.start = (
            float(session.positions[self.target, 0]),
            float(session.velocities[self.target, 0]),
        )
        players: list[Player] = [
            RecordedPlayer.on_grid(x, v, session.period, label)
            for x, v, label in zip(
                session.positions, session.velocities, session.labels, strict=True
            )
        ]
        players[self.target] = self._agent
        self._engine = Engine(players, session.graph)
        self._engine.reset(0, session.n_samples)
        return self._observe(), self._info()

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Apply acceleration ``actions[action]`` for one period."""
        self._agent.action = int(action)
        self._engine.step()
        k = self._engine.k
        x, v = self._agent.state
        target_x, target_v = (
            self._session.positions[self.target],
            self._session.velocities[self.target],
        )
        reward = compute_reward(
            x, v, target_x[k], target_v[k], self._agent.last_control, float(self.player.params.eta)
        )
        truncated = k == self._session.n_samples - 1
        return self._observe(), float(reward), False, truncated, self._info()

    def _next_session(self) -> Session:
        if self._fixed:
            session = self._fixed[int(self.np_random.integers(len(self._fixed)))]
        elif callable(self._source):
            session = self._source(self.np_random)
        else:
            session = next(self._source)  # type: ignore[arg-type]
        if not isinstance(session, Session):
            raise InputError("sessions", f"expected a Session, got {type(session).__name__}")
        if not np.flatnonzero(session.graph[self.target]).size:
            raise InputError("sessions", f"the target (player {self.target}) observes no one")
        return session

    def _observe(self) -> Any:
        k = self._engine.k
        x, v = self._agent.state
        seen = self._engine.observe(self.target)
        xp, vp, _ = partner_state(seen.positions, seen.velocities, seen.previous_positions, x, v)
        if self.observation == "discrete":
            reference = float(
                self._session.references[self.target, min(k, self._session.n_samples - 2)]
            )
            return self._cells.index(x, v, xp, vp, reference)
        if self.observation == "dynamic":
            features = np.empty(count_features(self.n_slots, False))
            encode(x, v, 0.0, seen.positions, seen.velocities, self.n_slots, False, features)
            return np.clip(features, -DYNAMIC_BOUND, DYNAMIC_BOUND).astype(np.float32)
        box = self.observation_space
        assert isinstance(box, spaces.Box)
        return np.clip(np.array([x, v, xp, vp], dtype=np.float32), box.low, box.high)

    def _info(self) -> dict[str, Any]:
        k = self._engine.k
        return {
            "target": (
                float(self._session.positions[self.target, k]),
                float(self._session.velocities[self.target, k]),
            )
        }
