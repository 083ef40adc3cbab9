"""A PettingZoo parallel environment: several learning agents playing in one group.

The group plays live on the engine's own step loop (`mirror_avatar.engine.loop.Engine`, METHODS
section 8): the first players are the agents, each driving the cyber player's HKB end effector
with an acceleration chosen from the cyber player's action set (as `mirror_avatar.rl.env.
ActionPlayer`), the others are any players given (virtual trainers, recordings, trained cyber
players), and everyone observes the players the graph links it to, a new connected graph for
each episode by default. All agents act at once, once per control period.

Observations, per agent: ``[x, x', x_n, x_n']`` as float32, its own state and the mean of its
neighbours' (velocities clipped to ±`mirror_avatar.rl.env.VELOCITY_BOUND`), as `MirrorGameEnv`'s
continuous observation. Rewards (**choice**: METHODS section 8 rewards a cyber player for
matching a target it imitates; agents learning together have no target, so each is rewarded
for coordinating with those it sees): the cyber player's reward of METHODS section 7 against
the mean of its neighbours after the step, ``-(x - x_n)² - 0.1 (x' - x_n')² - eta u²``. An
episode ends, truncated for every agent, when the session's duration is played. Needs the ``rl``
extra (pettingzoo).

Seeding: ``reset(seed=s)`` seeds the environment's generator, which draws the agents' starting
positions and the session's seed (the partners' references and the graph come from it), so the
same seed and the same actions replay the same episode.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.engine.loop import Engine, count_samples
from mirror_avatar.files.trials import PLAYING_RANGE
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.learning.kernels import compute_reward
from mirror_avatar.players.base import Player, partner_state
from mirror_avatar.rl.env import VELOCITY_BOUND, ActionPlayer
from mirror_avatar.sessions.graphs import GraphSource, random_connected_graph
from mirror_avatar.sessions.session import Session

START_SPREAD = 0.2
"""Agents start at rest at positions drawn uniformly in ±START_SPREAD units."""


class MirrorGroupEnv(ParallelEnv[str, np.ndarray, int]):
    """Learning agents and other players in one group, on one clock (see the module docstring).

    Parameters
    ----------
    n_agents
        Number of learning agents (players 0 .. n_agents - 1), named ``agent_0``...
    partners
        The other players of the group (players n_agents ...), stepped by the engine.
    graph
        Who observes whom: an adjacency matrix or a function drawing one per episode
        (`mirror_avatar.sessions.graphs.GraphSource`); default a new random connected graph each
        episode.
    duration
        Episode length (s).
    player
        Supplies the agents' end effector, action set and control weight; default
        ``CyberPlayer()``.
    """

    metadata: dict[str, Any] = {"name": "mirror_group_v0", "render_modes": []}

    def __init__(
        self,
        n_agents: int = 2,
        partners: Sequence[Player] = (),
        graph: GraphSource = random_connected_graph,
        duration: float = 60.0,
        player: CyberPlayer | None = None,
    ) -> None:
        if n_agents < 1 or n_agents + len(partners) < 2:
            raise InputError("agents", "a group needs at least one agent and two players")
        self.player = player or CyberPlayer()
        self.partners = list(partners)
        self.graph = graph
        self.n_samples = count_samples(duration, CONTROL_PERIOD)
        self.possible_agents = [f"agent_{i}" for i in range(n_agents)]
        self.agents: list[str] = []
        self._index = {name: i for i, name in enumerate(self.possible_agents)}
        self._avatars = {name: ActionPlayer(self.player) for name in self.possible_agents}
        low, high = PLAYING_RANGE
        self._observation_space = spaces.Box(
            np.array([low, -VELOCITY_BOUND, low, -VELOCITY_BOUND], dtype=np.float32),
            np.array([high, VELOCITY_BOUND, high, VELOCITY_BOUND], dtype=np.float32),
            dtype=np.float32,
        )
        self._action_space = spaces.Discrete(len(self.player.actions_))
        self.np_random, _ = seeding.np_random(None)

    def observation_space(self, agent: str) -> spaces.Box:
        """Return the observation space: ``[x, x', x_n, x_n']``, own state, neighbours' mean."""
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Discrete:
        """Return the action space: an index into the cyber player's accelerations."""
        return self._action_space

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        """Start an episode: agents at rest at random positions, a new session seed and graph."""
        if seed is not None:
            self.np_random, _ = seeding.np_random(seed)
        self.agents = list(self.possible_agents)
        for avatar in self._avatars.values():
            avatar.start = (float(self.np_random.uniform(-START_SPREAD, START_SPREAD)), 0.0)
            avatar.action = 0
        players: list[Player] = [*self._avatars.values(), *self.partners]
        self._engine = Engine(players, self.graph)
        self._engine.reset(int(self.np_random.integers(2**63)), self.n_samples)
        return self._observations(), {name: {} for name in self.agents}

    def step(
        self, actions: dict[str, int]
    ) -> tuple[
        dict[str, np.ndarray],
        dict[str, float],
        dict[str, bool],
        dict[str, bool],
        dict[str, dict[str, Any]],
    ]:
        """Apply every agent's acceleration for one period; everyone advances together."""
        for name in self.agents:
            self._avatars[name].action = int(actions[name])
        self._engine.step()
        observations = self._observations()
        eta = float(self.player.params.eta)
        rewards = {}
        for name in self.agents:
            x, v, xn, vn = self._states(self._index[name])
            u = self._avatars[name].last_control
            rewards[name] = float(compute_reward(x, v, xn, vn, u, eta))
        over = self._engine.k == self.n_samples - 1
        truncations = dict.fromkeys(self.agents, over)
        terminations = dict.fromkeys(self.agents, False)
        infos: dict[str, dict[str, Any]] = {name: {} for name in self.agents}
        if over:
            self._engine.finish()
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def session(self) -> Session:
        """Return the episode so far as a session (agents first), for the toolkit's metrics."""
        return self._engine.session()

    def _states(self, i: int) -> tuple[float, float, float, float]:
        x, v = self._engine.state(i)
        seen = self._engine.observe(i)
        xn, vn, _ = partner_state(seen.positions, seen.velocities, seen.previous_positions, x, v)
        return x, v, xn, vn

    def _observations(self) -> dict[str, np.ndarray]:
        box = self._observation_space
        return {
            name: np.clip(
                np.array(self._states(self._index[name]), dtype=np.float32), box.low, box.high
            )
            for name in self.agents
        }
