"""The learning agents a cyber player can be, in one registry: ``"tabular"`` and ``"dqn"``.

Each `AgentKind` says how its kind is made, trained, scored and read back from a file: the
tabular cyber player (`mirror_avatar.learning.agent.CyberPlayer`, a Q-table learnt by
`mirror_avatar.learning.training.QLearner`) and the deep one
(`mirror_avatar.deep.player.DeepCyberPlayer`, a Q-network learnt by
`mirror_avatar.deep.training.DQNLearner`). Everything that chooses between them (the paper's
set-up, avatar files, the command line) asks `agent_kind` or `kind_of`, so a new agent is one
entry in `AGENT_KINDS`.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from mirror_avatar.common.errors import InputError
from mirror_avatar.deep.player import DeepCyberPlayer, deep_player_from_arrays
from mirror_avatar.deep.training import DQNLearner, greedy_deep
from mirror_avatar.files.importing import excerpt
from mirror_avatar.learning.acceleration_player import AccelerationPlayer, Agent
from mirror_avatar.learning.agent import CyberPlayer, cyber_player_from_arrays
from mirror_avatar.learning.discretisation import Discretisation
from mirror_avatar.learning.training import (
    ExponentialEpsilon,
    ImitationTask,
    QLearner,
    SessionLearner,
    greedy_tabular,
)

EPSILON_HALF_LIVES = 8.0
"""Half-lives of a tabular player's exploration over a training run (**choice**): epsilon decays
from 0.5 to about 0.01 over the run, whatever its length."""


@dataclass(frozen=True)
class AgentKind:
    """One kind of learning agent: its player, its learner, its scores and its file.

    Attributes
    ----------
    name
        The name the command line and files use (``"tabular"``, ``"dqn"``).
    description
        How reports name the cyber player it trains.
    player_class
        The player it trains.
    make_player
        ``make_player(cells, n_slots, **options)``: an untrained player. ``cells`` makes the
        state cells of a tabular player; ``n_slots`` is the number of neighbours a deep player
        sees one by one (0: their mean); ``options`` are the player's keyword arguments
        (``actions``, ``params``, ``reference``, ``label``).
    make_learner
        ``make_learner(player, n_sessions, **options)``: its learner for a run of
        ``n_sessions``; ``options`` are `SessionLearner`'s keyword arguments.
    greedy
        ``greedy(player)``: how the player plays a task greedily, learning nothing: a function
        of an `mirror_avatar.learning.training.ImitationTask` returning the mean reward per step
        and the RMS to the target (units) (`mirror_avatar.training.imitation.score_avatar`).
    from_arrays
        ``from_arrays(arrays, metadata, path)``: the player rebuilt from its part of a file.
    """

    name: Agent
    description: str
    player_class: type[AccelerationPlayer]
    make_player: Callable[..., AccelerationPlayer]
    make_learner: Callable[..., SessionLearner]
    greedy: Callable[[Any], Callable[[ImitationTask], tuple[float, float]]]
    from_arrays: Callable[[dict[str, Any], dict[str, Any], str | os.PathLike[str]], Any]


def _tabular_player(
    cells: Callable[[], Discretisation], n_slots: int, **options: Any
) -> CyberPlayer:
    return CyberPlayer(cells(), **options)


def _deep_player(
    cells: Callable[[], Discretisation], n_slots: int, **options: Any
) -> DeepCyberPlayer:
    """Make a deep player that also sees its own reference velocity (a **departure**).

    As the tabular leader's features: see `mirror_avatar.training.imitation.make_cyber_player`.
    """
    return DeepCyberPlayer(n_slots=n_slots, use_reference=True, **options)


def _q_learner(player: CyberPlayer, n_sessions: int, **options: Any) -> QLearner:
    """Make a `QLearner` whose exploration decays with the length of the run.

    Epsilon halves every ``n_sessions / EPSILON_HALF_LIVES`` sessions, from 0.5 to 0.01
    (**choice**s scaled to the run's length); learning rate 0.1 and discount 0.95 are
    `QLearner`'s defaults.
    """
    half_life = max(n_sessions / EPSILON_HALF_LIVES, 1.0)
    return QLearner(player, epsilon=ExponentialEpsilon(half_life=half_life), **options)


def _dqn_learner(player: DeepCyberPlayer, n_sessions: int, **options: Any) -> DQNLearner:
    """Make a `DQNLearner` with METHODS section 8's defaults."""
    return DQNLearner(player, **options)


AGENT_KINDS: dict[Agent, AgentKind] = {
    "tabular": AgentKind(
        "tabular",
        "tabular cyber player (a Q-table)",
        CyberPlayer,
        _tabular_player,
        _q_learner,
        greedy_tabular,
        cyber_player_from_arrays,
    ),
    "dqn": AgentKind(
        "dqn",
        "deep cyber player (a Q-network trained by DQN)",
        DeepCyberPlayer,
        _deep_player,
        _dqn_learner,
        greedy_deep,
        deep_player_from_arrays,
    ),
}
"""Every agent a cyber player can be, by name."""

AGENTS: tuple[Agent, ...] = tuple(AGENT_KINDS)
"""The agents' names (the command line's ``--agent`` choices)."""

AGENT_NAMES: dict[Agent, str] = {name: kind.description for name, kind in AGENT_KINDS.items()}
"""How reports name the cyber player each agent trains."""


def agent_kind(agent: object, where: str | os.PathLike[str] = "agent") -> AgentKind:
    """Return the registered agent named ``agent``.

    Raises
    ------
    InputError
        ``where: problem`` when no agent has that name.
    """
    if not isinstance(agent, str) or agent not in AGENT_KINDS:
        names = " or ".join(repr(name) for name in AGENTS)
        raise InputError(where, f"agent {excerpt(agent)} is not one of {names}")
    return AGENT_KINDS[agent]


def kind_of(player: object, doing: str = "train") -> AgentKind:
    """Return the agent kind of a cyber player.

    Raises
    ------
    InputError
        When ``player`` is no registered agent's player (``doing`` says what was asked of it).
    """
    for kind in AGENT_KINDS.values():
        if isinstance(player, kind.player_class):
            return kind
    raise InputError("player", f"cannot {doing} a {type(player).__name__}")
