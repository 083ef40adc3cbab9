"""One compiled loop for a whole session of built-in players (virtual trainer, recording, avatars).

Each player's `mirror_avatar.players.base.PlayerPlan` names its kind
(`mirror_avatar.players.kinds`); `pack_session` gives each kind its players' plans to pack and
packs what every player has (start, reference, neighbours). `run_plans` then advances all
players sample by sample in the compiled loop of the session's kinds
(`mirror_avatar.engine.dispatch.kind_loop`), which calls each kind's step (the kernels the
players' Python ``step`` methods call) with the neighbours gathered by `gather_neighbours`, and
once a sample the solve of a kind solved together (the virtual trainers' problems of a period,
in lockstep, which gives each the result it would have alone). The loop records into one array
exactly what `mirror_avatar.engine.loop.Engine` records. This module names no kind.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.engine.dispatch import kind_loop
from mirror_avatar.players.base import PlayerPlan
from mirror_avatar.players.kinds import player_kind
from mirror_avatar.players.reference import draw_references
from mirror_avatar.sessions.graphs import Graph

Array = NDArray[np.float64]
Ints = NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class PackedSession:
    """A session's N players as the compiled loop of its kinds reads them.

    Attributes
    ----------
    names
        The session's kinds, sorted; a kind's code is its position here.
    kinds
        Each player's kind code, shape (N,).
    slots
        Each player's row in its kind's packed state (players of a kind numbered in order), (N,).
    references
        Reference velocity per step (units/s), shape (N, n - 1); NaN for players without.
    neighbour_index, neighbour_count
        Row k lists player k's neighbours in its first ``neighbour_count[k]`` entries, (N, N).
    starts
        Initial positions and velocities, shape (N, 2).
    states
        Each kind's packed state (what its ``pack`` returns), in the order of ``names``.
    """

    names: tuple[str, ...]
    kinds: Ints
    slots: Ints
    references: Array
    neighbour_index: Ints
    neighbour_count: Ints
    starts: Array
    states: tuple[tuple[Any, ...], ...]


def pack_session(plans: Sequence[PlayerPlan], graph: Graph, n_steps: int) -> PackedSession:
    """Pack the players' plans and the graph for `run_plans` (``n_steps`` = samples - 1).

    The plans' references are drawn here, all together (`draw_references`).
    """
    n = len(plans)
    references = np.full((n, n_steps), np.nan)
    drawing = [(i, plan.reference) for i, plan in enumerate(plans) if plan.reference is not None]
    drawn = draw_references([draw for _, draw in drawing])
    for (i, _), reference in zip(drawing, drawn, strict=True):
        references[i] = reference[:n_steps]
    names = tuple(sorted({plan.kind for plan in plans}))
    kinds = np.array([names.index(plan.kind) for plan in plans], dtype=np.int64)
    slots = np.full(n, -1, dtype=np.int64)
    states = []
    for code, name in enumerate(names):
        players = np.flatnonzero(kinds == code)
        slots[players] = np.arange(players.size)
        states.append(player_kind(name).pack([plans[int(i)] for i in players], players))
    neighbour_index = np.zeros((n, n), dtype=np.int64)
    neighbour_count = np.zeros(n, dtype=np.int64)
    for k in range(n):
        found = np.flatnonzero(graph[k])
        neighbour_index[k, : found.size] = found
        neighbour_count[k] = found.size
    return PackedSession(
        names,
        kinds,
        slots,
        references,
        neighbour_index,
        neighbour_count,
        np.array([plan.start for plan in plans], dtype=np.float64),
        tuple(states),
    )


def run_plans(plans: Sequence[PlayerPlan], graph: Graph, n_samples: int) -> Array:
    """Play a session of ``n_samples`` samples; return its channels, shape (4, N, n_samples).

    The channels are positions, velocities, controls and references, as recorded by
    `mirror_avatar.engine.loop.Engine` (controls and references NaN at the last sample and for
    players without).
    """
    if n_samples < 2:
        raise InputError("duration", "a session needs at least two samples")
    packed = pack_session(plans, graph, n_samples - 1)
    out = np.empty((4, len(plans), n_samples))
    kind_loop(packed.names)(
        packed.kinds,
        packed.slots,
        packed.references,
        packed.neighbour_index,
        packed.neighbour_count,
        packed.starts,
        out,
        *packed.states,
    )
    return out
