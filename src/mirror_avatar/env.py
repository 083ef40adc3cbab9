"""A Gymnasium environment: the cyber player's view of a mirror-game session (METHODS section 7).

One episode is one session against a partner whose motion is given in advance (a recorded or
simulated trial), with the target player's trajectory supplying the reward. The agent drives the
same HKB end effector as `mirror_avatar.learning.CyberPlayer` with the same action set and reward,
computed by the same compiled functions, so any Gymnasium agent can be compared with the tabular
Q-learner. Needs the ``rl`` extra (gymnasium).

Seeding follows Gymnasium: ``reset(seed=s)`` reseeds ``self.np_random``, which picks the session
(from a given set of sessions) or is passed to a session-making callable.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from mirror_avatar.errors import InputError
from mirror_avatar.learning import CyberPlayer, compute_reward, integrate_hkb, iter_sessions
from mirror_avatar.trials import PLAYING_RANGE

VELOCITY_BOUND = 5.0
"""Velocities (units/s) in continuous observations are clipped to ±VELOCITY_BOUND."""

Array = NDArray[np.float64]
Session = tuple[Array, Array, Array, Array, Array]
"""``(partner_x, partner_v, target_x, target_v, target_r)`` as `iter_sessions` yields them."""


class MirrorGameEnv(gym.Env[Any, Any]):
    """The cyber player's session against a partner, rewarded for matching a target player.

    Parameters
    ----------
    sessions
        Where episodes come from. A chunk (positions and velocities of shape (k, 2, n) or (2, n),
        player 0 the partner, player 1 the target, sampled at the control period; see
        `mirror_avatar.learning.iter_sessions`): each reset picks one of its k sessions with
        ``self.np_random``. Or a callable taking ``self.np_random`` and returning such a chunk
        with one session. Or an iterator of such chunks, advanced at each reset.
    player
        Supplies the dynamics, actions, reward weight and discretisation; default
        ``CyberPlayer()``.
    observation
        ``"continuous"``: ``[x, x', x_p, x_p']`` as float32 (velocities clipped to
        ±`VELOCITY_BOUND`); ``"discrete"``: the Q-table cell of that state (with the target's
        reference velocity as the avatar's own for ``"reference"`` features).

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
        sessions: Any,
        player: CyberPlayer | None = None,
        observation: Literal["continuous", "discrete"] = "continuous",
    ) -> None:
        self.player = player or CyberPlayer()
        self.observation = observation
        self._source = sessions
        self._fixed: list[Session] = (
            []
            if callable(sessions) or isinstance(sessions, Iterator)
            else _sessions(sessions, self.player.period)
        )
        self._actions = self.player.actions_
        self._hkb = self.player.hkb_
        self.action_space = spaces.Discrete(self._actions.size)
        if observation == "continuous":
            low, high = PLAYING_RANGE
            self.observation_space = spaces.Box(
                np.array([low, -VELOCITY_BOUND, low, -VELOCITY_BOUND], dtype=np.float32),
                np.array([high, VELOCITY_BOUND, high, VELOCITY_BOUND], dtype=np.float32),
                dtype=np.float32,
            )
        elif observation == "discrete":
            self.observation_space = spaces.Discrete(self.player.discretisation_.n_states)
        else:
            raise InputError(
                "observation", f"must be 'continuous' or 'discrete', not {observation!r}"
            )

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Start an episode on the next session; return the first observation and info."""
        super().reset(seed=seed)
        self._session = self._next_session()
        self._k = 0
        _, _, target_x, target_v, _ = self._session
        self._state = (float(target_x[0]), float(target_v[0]))
        return self._observe(), self._info()

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Apply acceleration ``actions[action]`` for one period."""
        u = float(self._actions[int(action)])
        x, v = self._state
        player = self.player
        x, v = integrate_hkb(x, v, u, self._hkb, float(player.period), int(player.n_substeps))
        self._state = (x, v)
        self._k += 1
        _, _, target_x, target_v, _ = self._session
        reward = compute_reward(x, v, target_x[self._k], target_v[self._k], u, float(player.eta))
        truncated = self._k == target_x.size - 1
        return self._observe(), float(reward), False, truncated, self._info()

    def _next_session(self) -> Session:
        if self._fixed:
            return self._fixed[int(self.np_random.integers(len(self._fixed)))]
        chunk = self._source(self.np_random) if callable(self._source) else next(self._source)
        sessions = _sessions(chunk, self.player.period)
        if len(sessions) != 1:
            raise InputError("sessions", f"expected one session per episode, got {len(sessions)}")
        return sessions[0]

    def _observe(self) -> Any:
        partner_x, partner_v, _, _, target_r = self._session
        x, v = self._state
        xp, vp = float(partner_x[self._k]), float(partner_v[self._k])
        if self.observation == "discrete":
            return self.player.discretisation_.index(x, v, xp, vp, float(target_r[self._k]))
        box = self.observation_space
        assert isinstance(box, spaces.Box)
        return np.clip(np.array([x, v, xp, vp], dtype=np.float32), box.low, box.high)

    def _info(self) -> dict[str, Any]:
        _, _, target_x, target_v, _ = self._session
        return {"target": (float(target_x[self._k]), float(target_v[self._k]))}


def _sessions(chunk: Any, period: float) -> list[Session]:
    return list(iter_sessions([chunk], period))
