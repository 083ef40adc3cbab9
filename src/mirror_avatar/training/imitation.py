"""The paper's training set-up: six virtual trainers and the cyber player's training driver.

The paper (METHODS section 7) fits one IMS generator per person, VT_1..VT_6, and teaches a cyber
player to imitate person 5: as a **follower**, VT_1..VT_4 (leader preset) lead sessions in which
VT_5 (follower preset) follows, and the cyber player, watching the leader, is rewarded for moving
like VT_5; **leader** training is symmetric (VT_5 with the leader preset, the partners with the
follower preset). VT_6 is never seen in training and serves as the unseen partner in validation.

The virtual "persons" and who plays what are made in `mirror_avatar.training.cast`.

`train_cyber_player` streams the batch engine's sessions (`mirror_avatar.engine.batch.run_sessions`)
straight into a learner's ``fit``: sessions are generated and learnt from chunk by chunk, never
all held in memory. The ``agent`` is ``"tabular"`` (a Q-table,
`mirror_avatar.learning.training.QLearner`) or ``"dqn"`` (a Q-network,
`mirror_avatar.deep.training.DQNLearner`), chosen in `mirror_avatar.training.agents`; both play
the same roles from the same sessions.
Player 0 of every session is the partner, player 1 the target. `train_group_cyber_player` does
the same in a group (METHODS section 8): the target is the last member, and every session has a
new random graph. Both go through `imitate`.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np

from mirror_avatar import dynamics
from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import draw_seeds
from mirror_avatar.engine.batch import run_sessions
from mirror_avatar.files.trials import Trial
from mirror_avatar.learning.acceleration_player import AccelerationPlayer, Agent
from mirror_avatar.learning.agent import DEFAULT_ACTIONS
from mirror_avatar.learning.discretisation import (
    Discretisation,
    make_default_discretisation,
    symmetric_edges,
)
from mirror_avatar.learning.training import LearningCurve, SessionLearner, score_tasks
from mirror_avatar.motion.models import MotionModel
from mirror_avatar.players.virtual_trainer import VirtualTrainer
from mirror_avatar.sessions.graphs import GraphSource, random_connected_graph
from mirror_avatar.sessions.session import Session
from mirror_avatar.training.agents import agent_kind, kind_of

Role = Literal["follower", "leader"]
Reference = MotionModel | Trial
"""What a virtual trainer draws its reference velocity from: a motion model or a recorded trial."""
TRAINING_ROLES: tuple[Role, ...] = ("follower", "leader")

CURVE_POINTS = 100
"""About how many points a learning curve has (sessions per point = n_sessions / CURVE_POINTS)."""

ACTION_SCALE = 4.0
"""Factor on `mirror_avatar.learning.agent.DEFAULT_ACTIONS` for the cyber player imitating a
virtual trainer (**choice**): accelerations 0, ±2, ±4, ±8, ±16 units/s², because the virtual
trainers' own controls reach far beyond the METHODS maximum of ±4 units/s² (the benchmark
``bench_learning`` compares the scales)."""

FOLLOWER_EDGES = (
    np.array([0.015, 0.03, 0.05, 0.07, 0.1, 0.14, 0.2, 0.3]),
    np.array([0.07, 0.15, 0.25, 0.35, 0.5, 0.8]),
)
"""Positive interior bin edges of the follower's own relative features ``x - x_p`` (units) and
``x' - x_p'`` (units/s); mirrored about an edge at 0 (**choice**, see
`make_role_discretisation`)."""


def make_role_discretisation(role: Role) -> Discretisation:
    """Make the state discretisation of a cyber player imitating VT5 in ``role`` (**choice**).

    The **follower** uses relative features ``[x - x_p, x' - x_p', x_p, x_p']`` with its own
    features cut finer than the default (`FOLLOWER_EDGES`: 18 x 14 bins instead of 10 x 8,
    10 584 cells; with the default bins the follower was more tightly coordinated with slow
    partners than VT5 is) and the partner's bins of
    `mirror_avatar.learning.discretisation.make_default_discretisation`. The finer follower
    needs more training sessions.

    The **leader** uses ``"reference"`` features ``[x - x_p, x' - r_s, x, r_s]`` (9600 cells), r_s
    its own reference velocity from VT5's generator (a **departure** from METHODS section 7). On
    the METHODS state a leader learns the conditional mean of VT5's motion given the two
    players' states; VT5's self-generated motion is not predictable from them, so such a leader
    partly follows its follower and does no better than copying it. The report's cyber-player
    section measures both roles against VT5.
    """
    if _check_role(role) == "leader":
        return make_default_discretisation("reference")
    own = tuple(symmetric_edges(*e) for e in FOLLOWER_EDGES)
    return Discretisation("relative", own + make_default_discretisation("relative").edges[2:])


def make_group_discretisation() -> Discretisation:
    """Make the state discretisation of a cyber player in a group (**choice**).

    Relative features ``[x - m, x' - m', m, m']`` with m the mean of its neighbours (the partner
    of METHODS section 8, for the tabular player), cut as the follower's
    (`make_role_discretisation`): a group member mostly follows its neighbours' mean (theta_p
    0.85). Features that add the avatar's own reference velocity (as the leader's do) imitated
    the target better open-loop but lagged the group more in closed loop.
    """
    return make_role_discretisation("follower")


def make_cyber_player(
    role: Role,
    reference: Reference | None = None,
    action_scale: float = ACTION_SCALE,
    agent: Agent = "tabular",
) -> AccelerationPlayer:
    """Make an untrained cyber player whose HKB end effector has the role preset's parameters.

    Follows METHODS section 7 with the virtual trainer's end-effector parameters of the same role
    (`mirror_avatar.dynamics.FOLLOWER` or ``LEADER``: omega 0.1 or 0.8 rad/s, alpha 1, beta 2,
    gamma -1, eta 1e-4) and the accelerations ``action_scale * DEFAULT_ACTIONS`` (units/s²;
    departs from METHODS' ±4 maximum, see `ACTION_SCALE`). A tabular player cuts its state as
    `make_role_discretisation` says; a deep one (``agent="dqn"``) sees its own state, its
    partner's and, in both roles, its own reference velocity (a **departure**, as the tabular
    leader's ``"reference"`` features: the virtual trainer it imitates moves partly with its own
    motion, theta_s > 0, and without it the deep follower was more tightly coordinated with
    slow partners than its target). ``reference`` is the motion source of a tabular leader and
    of a deep player: the generator (or trial) of the person it imitates.
    """
    role = _check_role(role)
    actions = tuple(action_scale * a for a in DEFAULT_ACTIONS)
    return agent_kind(agent).make_player(
        lambda: make_role_discretisation(role),
        0,
        actions=actions,
        params=dynamics.preset(role),
        reference=reference,
    )


def make_learner(
    player: AccelerationPlayer,
    n_sessions: int,
    random_state: int | None,
    checkpoint: str | os.PathLike[str] | None = None,
    checkpoint_every: int | None = None,
    progress: bool | None = None,
    target: int = 1,
) -> SessionLearner:
    """Make the learner for a run of ``n_sessions`` that imitates player ``target``.

    The learning curve has about `CURVE_POINTS` points; the player's agent kind makes the
    learner (`mirror_avatar.training.agents.AgentKind.make_learner`: a `QLearner` whose
    exploration decays over the run, or a `DQNLearner`).
    """
    common: dict[str, Any] = {
        "target": target,
        "block_size": max(n_sessions // CURVE_POINTS, 1),
        "checkpoint_every": checkpoint_every,
        "checkpoint_path": checkpoint,
        "progress": progress,
        "random_state": random_state,
    }
    return kind_of(player).make_learner(player, n_sessions, **common)


def make_pairs(
    target: Reference, partners: Sequence[Reference], role: Role
) -> list[tuple[VirtualTrainer, VirtualTrainer]]:
    """Training dyads ``(partner, target)``: the target takes ``role``, the partners the other.

    Parameters
    ----------
    target
        The generator (or recorded trial) of the person to imitate.
    partners
        Generators (or recorded trials) of the training partners.
    role
        The role the cyber player learns (``"follower"`` or ``"leader"``).
    """
    role = _check_role(role)
    if not partners:
        raise InputError("partners", "need at least one training partner")
    other = "leader" if role == "follower" else "follower"
    trainee = VirtualTrainer(dynamics.preset(role), target, label="target")
    return [
        (VirtualTrainer(dynamics.preset(other), p, label=f"partner {i + 1}"), trainee)
        for i, p in enumerate(partners)
    ]


def derive_seeds(seed: int | None) -> tuple[int, int]:
    """Independent seeds for the training sessions and for the learner, from one run seed."""
    sessions, learner = draw_seeds(seed, 2)
    return sessions, learner


def train_cyber_player(
    target: Reference,
    partners: Sequence[Reference],
    role: Role = "follower",
    n_sessions: int = 4000,
    seed: int | None = 0,
    duration: float = 60.0,
    scheduler: str | None = None,
    n_jobs: int = 2,
    chunk_size: int = 50,
    checkpoint: str | os.PathLike[str] | None = None,
    checkpoint_every: int | None = None,
    progress: bool | None = None,
    agent: Agent = "tabular",
) -> tuple[AccelerationPlayer, LearningCurve]:
    """Train a cyber player to imitate ``target`` in ``role`` with virtual-trainer sessions.

    Session i is played by ``partners[i % len(partners)]`` (player 0, the other role's preset)
    and the target (player 1, ``role``'s preset) on the batch engine, and the cyber player
    Q-learns from it as the chunks arrive (`imitate`), so memory stays flat whatever
    ``n_sessions``.

    Parameters
    ----------
    target, partners
        Motion models (stroke or IMS generators) or recorded trials of the person to imitate
        and of the partners.
    role
        ``"follower"`` or ``"leader"``.
    n_sessions, seed, duration, scheduler, n_jobs, chunk_size, checkpoint,
    checkpoint_every, progress
        As in `imitate`. A leader's file holds its motion source, so with a ``checkpoint``
        ``target`` must be a motion model (`mirror_avatar.motion.models.MotionModel`, checked
        before training).
    agent
        ``"tabular"`` or ``"dqn"`` (`make_cyber_player`).

    Returns
    -------
    player : CyberPlayer or DeepCyberPlayer
        The trained player (greedy at play time).
    curve : LearningCurve
        Mean reward per step and RMS to the target (units) per block of sessions.
    """
    player = make_cyber_player(role, target, agent=agent)
    if checkpoint is not None and player.needs_reference and not isinstance(target, MotionModel):
        raise InputError(
            "target",
            "a leader or a deep player saved to a file needs a motion model, not a trial",
        )
    player.label = f"cyber player ({role})"
    curve = imitate(
        player,
        make_pairs(target, partners, role),
        1,
        n_sessions=n_sessions,
        seed=seed,
        duration=duration,
        scheduler=scheduler,
        n_jobs=n_jobs,
        chunk_size=chunk_size,
        checkpoint=checkpoint,
        checkpoint_every=checkpoint_every,
        progress=progress,
        summary={"role": role, "n_partners": len(partners), "agent": agent},
    )
    return player, curve


def imitate(
    player: AccelerationPlayer,
    lineups: Sequence[Sequence[VirtualTrainer]],
    target: int,
    n_sessions: int = 4000,
    seed: int | None = 0,
    duration: float = 60.0,
    graph: GraphSource = None,
    scheduler: str | None = None,
    n_jobs: int = 2,
    chunk_size: int = 50,
    checkpoint: str | os.PathLike[str] | None = None,
    checkpoint_every: int | None = None,
    progress: bool | None = None,
    summary: dict[str, Any] | None = None,
) -> LearningCurve:
    """Teach ``player`` to move like player ``target`` of sessions the batch engine streams.

    Session i is played by ``lineups[i % len(lineups)]`` on ``graph``; the cyber player takes
    the target's place and learns from it as the chunks arrive (`make_learner`), so memory
    stays flat whatever ``n_sessions``.

    Parameters
    ----------
    player
        The cyber player (tabular or deep), trained in place.
    lineups
        The virtual trainers of each kind of session.
    target
        Index of the player to imitate in every lineup.
    n_sessions
        Number of training sessions (the paper: about 24 000).
    seed
        Run seed; the sessions' and the learner's seeds are derived from it (`derive_seeds`), so
        the same seed gives the same policy. Recorded in ``player.training_``.
    duration
        Session length (s).
    graph
        Who observes whom (`mirror_avatar.sessions.graphs.GraphSource`; a function draws a new
        graph for every session).
    scheduler, n_jobs, chunk_size
        Where the sessions are played (see `mirror_avatar.engine.batch.run_sessions`).
    checkpoint, checkpoint_every
        Save the player to ``checkpoint`` every ``checkpoint_every`` sessions and at the end.
    progress
        Progress bar: True, False, or None (a bar on a terminal, plain lines off one).
    summary
        More to record in ``player.training_``.

    Returns
    -------
    LearningCurve
        Mean reward per step and RMS to the target (units) per block of sessions.
    """
    session_seed, learner_seed = derive_seeds(seed)
    chunks = run_sessions(
        lineups,
        n_sessions,
        duration=duration,
        seed=session_seed,
        scheduler=scheduler,
        n_jobs=n_jobs,
        chunk_size=chunk_size,
        progress=False,
        graph=graph,
    )
    learner = make_learner(
        player, n_sessions, learner_seed, checkpoint, checkpoint_every, progress, target
    )
    learner.fit(itertools.chain.from_iterable(chunks), total=n_sessions)
    player.training_ |= {"run_seed": seed} | (summary or {})
    if checkpoint is not None:
        player.save(checkpoint)
    return learner.learning_curve_


def make_group(
    target: Reference, partners: Sequence[Reference], params: dynamics.HKBParams = dynamics.GROUP
) -> list[VirtualTrainer]:
    """Make a group of virtual trainers with the same parameters: the partners, the target."""
    if not partners:
        raise InputError("partners", "a group needs at least one partner")
    members = [VirtualTrainer(params, p, label=f"partner {i + 1}") for i, p in enumerate(partners)]
    return [*members, VirtualTrainer(params, target, label="target")]


def make_group_cyber_player(
    reference: Reference | None = None,
    action_scale: float = ACTION_SCALE,
    agent: Agent = "tabular",
    n_players: int = 4,
) -> AccelerationPlayer:
    """Make an untrained cyber player for a group of ``n_players`` (**choice**).

    Its end effector is `mirror_avatar.dynamics.GROUP`'s and its accelerations ``action_scale *
    DEFAULT_ACTIONS``. A tabular player's state is built from its own state and its neighbours'
    mean, cut as `make_group_discretisation` says. A deep player (``agent="dqn"``) sees its
    neighbours one by one in ``n_players - 1`` slots (METHODS section 8's dynamic input,
    `mirror_avatar.deep.features`) and also its own reference velocity, drawn from
    ``reference`` (a **departure**, as the tabular leader's features: the target moves partly
    with its own motion, theta_s 0.1, and without it the deep player followed its neighbours'
    mean more closely than the target does; `benchmarks/results.md`, section deep).
    """
    return agent_kind(agent).make_player(
        make_group_discretisation,
        n_players - 1,
        actions=tuple(action_scale * a for a in DEFAULT_ACTIONS),
        params=dynamics.GROUP,
        reference=reference,
        label="cyber player (group)",
    )


def train_group_cyber_player(
    target: Reference,
    partners: Sequence[Reference],
    n_sessions: int = 4000,
    seed: int | None = 0,
    duration: float = 60.0,
    graph: GraphSource = random_connected_graph,
    agent: Agent = "tabular",
    **options: Any,
) -> tuple[AccelerationPlayer, LearningCurve]:
    """Train a cyber player to imitate ``target`` in a group with ``partners`` (METHODS 8).

    Every session the partners and the target (the last player), all with the
    `mirror_avatar.dynamics.GROUP` parameters, improvise together on ``graph`` (by default a new
    random connected graph each session); the cyber player takes the target's place and learns
    from what it did (`imitate`).

    Parameters
    ----------
    target, partners
        Motion models (stroke or IMS generators) or recorded trials of the person to imitate
        and of the others.
    n_sessions, seed, duration, graph
        As in `imitate`.
    agent
        ``"tabular"`` or ``"dqn"`` (`make_group_cyber_player`).
    **options
        ``scheduler``, ``n_jobs``, ``chunk_size``, ``checkpoint``,
        ``checkpoint_every``, ``progress`` of `imitate`.

    Returns
    -------
    player : CyberPlayer or DeepCyberPlayer
        The trained player.
    curve : LearningCurve
        Mean reward per step and RMS to the target (units) per block of sessions.
    """
    group = make_group(target, partners)
    player = make_group_cyber_player(target, agent=agent, n_players=len(group))
    summary = {"role": "group", "n_players": len(group), "agent": agent}
    curve = imitate(
        player,
        [group],
        len(partners),
        n_sessions,
        seed,
        duration,
        graph,
        summary=summary,
        **options,
    )
    return player, curve


def score_avatar(
    player: AccelerationPlayer, sessions: Iterable[Session], target: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Play each session greedily in player ``target``'s place (open loop, no learning).

    Each task is played by the agent kind's greedy play (`mirror_avatar.training.agents.
    AgentKind.greedy`: `mirror_avatar.learning.training.greedy_tabular` for tabular players,
    `mirror_avatar.deep.training.greedy_deep` for deep ones), learning nothing.

    Returns
    -------
    mean_reward, rms : ndarray, shape (n_sessions,)
        Mean reward per step and RMS position error to the target (units) per session.
    """
    greedy = kind_of(player, "score").greedy(player)
    return score_tasks(greedy, sessions, target, player.period)


def checkpoint_path(policy: str | os.PathLike[str]) -> Path:
    """Where a training run toward ``POLICY.npz`` keeps its checkpoints: ``POLICY.checkpoint.npz``.

    Beside the policy, never over it: an interrupted run leaves an earlier finished policy and
    its learning curve as they were.
    """
    path = Path(policy)
    return path.with_name(f"{path.stem}.checkpoint.npz")


def learning_curve_path(policy: str | os.PathLike[str]) -> Path:
    """Where the learning curve of a policy file goes: ``POLICY.learning_curve.csv``."""
    path = Path(policy)
    return path.with_name(f"{path.stem}.learning_curve.csv")


def _check_role(role: str) -> Role:
    if role not in TRAINING_ROLES:
        raise InputError("role", f"must be 'follower' or 'leader', not {role!r}")
    return role
