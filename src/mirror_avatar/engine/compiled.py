"""One compiled loop for a whole session of built-in players (virtual trainer, recording, avatars).

Each player's `mirror_avatar.players.base.PlayerPlan` is packed into arrays (`pack_session`);
`run_packed` then advances all players sample by sample in compiled code, calling each kind's own
step kernel (`recorded_step`, `cyber_step`, `deep_step`: the kernels the players' Python ``step``
methods call) with the neighbours gathered by `gather_neighbours`. The virtual trainers' problems
of a period (`virtual_trainer_problem`) are solved together, in lockstep
(`mirror_avatar.dynamics.optimal_control_steps`, the solver `VirtualTrainer.step` calls for one),
which gives each the result it would have alone. The loop records into one array exactly what
`mirror_avatar.engine.loop.Engine` records.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mirror_avatar.deep.player import NetworkPolicy, deep_step
from mirror_avatar.dynamics import (
    PROBLEM_COLUMNS,
    coupling_rate,
    optimal_control_steps,
    records,
)
from mirror_avatar.errors import InputError
from mirror_avatar.graphs import Graph
from mirror_avatar.learning.agent import GreedyPolicy, cyber_step
from mirror_avatar.players.base import (
    CYBER,
    DEEP,
    RECORDED,
    VIRTUAL_TRAINER,
    PlayerPlan,
    gather_neighbours,
)
from mirror_avatar.players.recorded import recorded_step
from mirror_avatar.players.reference import draw_references
from mirror_avatar.players.virtual_trainer import virtual_trainer_problem

Array = NDArray[np.float64]
Ints = NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class PackedSession:
    """A session's players as the arrays `run_packed` reads (N players, C cyber, D deep players).

    Attributes
    ----------
    kinds
        Each player's kind code, shape (N,).
    params, param_rows
        The distinct HKB parameter sets, a record array of
        `mirror_avatar.dynamics.PARAMS_DTYPE`, shape (P,), and each player's row in it (N,).
    references
        Reference velocity per step (units/s), shape (N, n - 1); NaN for players without.
    tracks, track_lengths
        Recordings on the control grid, shape (N, 2, L), and each one's length, shape (N,).
    slots
        Each player's row in its kind's tables (cyber or deep; -1 for the others), shape (N,).
    q_tables, modes, edges, offsets, actions, n_actions, substeps
        The cyber policies: Q-tables padded with -inf to shape (C, S, A), feature codes (C,),
        bin edges (C, E), edge offsets (C, 5), actions (C, A), action counts (C,) and RK4
        substeps (C,).
    networks
        The deep policies (`pack_networks`).
    neighbour_index, neighbour_count
        Row k lists player k's neighbours in its first ``neighbour_count[k]`` entries, (N, N).
    starts
        Initial positions and velocities, shape (N, 2).
    """

    kinds: Ints
    params: NDArray[np.void]
    param_rows: Ints
    references: Array
    tracks: Array
    track_lengths: Ints
    slots: Ints
    q_tables: Array
    modes: Ints
    edges: Array
    offsets: Ints
    actions: Array
    n_actions: Ints
    substeps: Ints
    networks: PackedNetworks
    neighbour_index: Ints
    neighbour_count: Ints
    starts: Array


def pack_session(plans: Sequence[PlayerPlan], graph: Graph, n_steps: int) -> PackedSession:
    """Pack the players' plans and the graph for `run_packed` (``n_steps`` = samples - 1).

    The plans' references are drawn here, all together (`draw_references`).
    """
    n = len(plans)
    references = np.full((n, n_steps), np.nan)
    drawing = [(i, plan.reference) for i, plan in enumerate(plans) if plan.reference is not None]
    drawn = draw_references([draw for _, draw in drawing])
    for (i, _), reference in zip(drawing, drawn, strict=True):
        references[i] = reference[:n_steps]
    tracks, lengths = _pack_tracks(plans)
    policies = [plan.policy for plan in plans if plan.kind == CYBER]
    networks = [plan.policy for plan in plans if plan.kind == DEEP]
    slots = np.full(n, -1, dtype=np.int64)
    for kind in (CYBER, DEEP):
        of_kind = [i for i, plan in enumerate(plans) if plan.kind == kind]
        slots[of_kind] = np.arange(len(of_kind))
    distinct = list(dict.fromkeys(plan.params for plan in plans))
    neighbour_index = np.zeros((n, n), dtype=np.int64)
    neighbour_count = np.zeros(n, dtype=np.int64)
    for k in range(n):
        found = np.flatnonzero(graph[k])
        neighbour_index[k, : found.size] = found
        neighbour_count[k] = found.size
    return PackedSession(
        np.array([plan.kind for plan in plans], dtype=np.int64),
        records(distinct),
        np.array([distinct.index(plan.params) for plan in plans], dtype=np.int64),
        references,
        tracks,
        lengths,
        slots,
        *_pack_policies(policies),
        pack_networks(networks),
        neighbour_index,
        neighbour_count,
        np.array([plan.start for plan in plans], dtype=np.float64),
    )


def _pack_tracks(plans: Sequence[PlayerPlan]) -> tuple[Array, Ints]:
    lengths = np.array(
        [0 if plan.track is None else plan.track.shape[1] for plan in plans], dtype=np.int64
    )
    tracks = np.full((len(plans), 2, max(int(lengths.max()), 1)), np.nan)
    for i, plan in enumerate(plans):
        if plan.track is not None:
            tracks[i, :, : lengths[i]] = plan.track
    return tracks, lengths


def _pack_policies(
    policies: Sequence[GreedyPolicy],
) -> tuple[Array, Ints, Array, Ints, Array, Ints, Ints]:
    count = len(policies)
    n_states = max([p.q_table.shape[0] for p in policies], default=1)
    n_actions = np.array([p.actions.size for p in policies], dtype=np.int64)
    n_edges = max([p.discretisation.flat_edges.size for p in policies], default=1)
    q_tables = np.full((count, n_states, max(n_actions, default=1)), -np.inf)
    edges = np.zeros((count, n_edges))
    offsets = np.zeros((count, 5), dtype=np.int64)
    actions = np.zeros((count, q_tables.shape[2]))
    for c, policy in enumerate(policies):
        q = policy.q_table
        q_tables[c, : q.shape[0], : q.shape[1]] = q
        flat = policy.discretisation.flat_edges
        edges[c, : flat.size] = flat
        offsets[c] = policy.discretisation.offsets
        actions[c, : policy.actions.size] = policy.actions
    modes = np.array([p.discretisation.mode for p in policies], dtype=np.int64)
    substeps = np.array([p.n_substeps for p in policies], dtype=np.int64)
    return q_tables, modes, edges, offsets, actions, n_actions, substeps


class PackedNetworks(NamedTuple):
    """The deep policies of a session (D of them), each row padded past its own length.

    A named tuple, so compiled code takes it as one argument and unpacks it in this order.
    """

    weights: Array
    """Flat network parameters, shape (D, P)."""
    sizes: Ints
    """Layer widths, shape (D, L)."""
    n_sizes: Ints
    """How many layer widths each network has, shape (D,)."""
    n_slots: Ints
    """Neighbour slots of each input, shape (D,)."""
    use_reference: Ints
    """1 where the input holds the player's reference velocity, shape (D,)."""
    actions: Array
    """Accelerations (units/s²), shape (D, A)."""
    n_actions: Ints
    """How many actions each network has, shape (D,)."""
    substeps: Ints
    """RK4 substeps per control period, shape (D,)."""


def pack_networks(networks: Sequence[NetworkPolicy]) -> PackedNetworks:
    """Pack deep policies for `run_packed`, each row padded past its own length."""
    count = len(networks)
    weights = np.zeros((count, max([n.weights.size for n in networks], default=1)))
    sizes = np.zeros((count, max([n.sizes.size for n in networks], default=1)), dtype=np.int64)
    n_actions = np.array([n.actions.size for n in networks], dtype=np.int64)
    actions = np.zeros((count, max(n_actions, default=1)))
    for d, network in enumerate(networks):
        weights[d, : network.weights.size] = network.weights
        sizes[d, : network.sizes.size] = network.sizes
        actions[d, : network.actions.size] = network.actions
    return PackedNetworks(
        weights,
        sizes,
        np.array([n.sizes.size for n in networks], dtype=np.int64),
        np.array([n.n_slots for n in networks], dtype=np.int64),
        np.array([n.use_reference for n in networks], dtype=np.int64),
        actions,
        n_actions,
        np.array([n.n_substeps for n in networks], dtype=np.int64),
    )


def run_plans(plans: Sequence[PlayerPlan], graph: Graph, n_samples: int) -> Array:
    """Play a session of ``n_samples`` samples; return its channels, shape (4, N, n_samples).

    The channels are positions, velocities, controls and references, as recorded by
    `mirror_avatar.engine.loop.Engine`.
    """
    if n_samples < 2:
        raise InputError("duration", "a session needs at least two samples")
    packed = pack_session(plans, graph, n_samples - 1)
    out = np.empty((4, len(plans), n_samples))
    run_packed(
        packed.kinds,
        packed.params,
        packed.param_rows,
        packed.references,
        packed.tracks,
        packed.track_lengths,
        packed.slots,
        packed.q_tables,
        packed.modes,
        packed.edges,
        packed.offsets,
        packed.actions,
        packed.n_actions,
        packed.substeps,
        packed.networks,
        packed.neighbour_index,
        packed.neighbour_count,
        packed.starts,
        out,
    )
    return out


@njit(cache=True, nogil=True)
def run_packed(
    kinds: Ints,
    params: NDArray[np.void],
    param_rows: Ints,
    references: Array,
    tracks: Array,
    track_lengths: Ints,
    slots: Ints,
    q_tables: Array,
    modes: Ints,
    edges: Array,
    offsets: Ints,
    actions: Array,
    n_actions: Ints,
    substeps: Ints,
    networks: PackedNetworks,
    neighbour_index: Ints,
    neighbour_count: Ints,
    starts: Array,
    out: Array,
) -> None:
    """Advance every player from sample 0 to the last, writing ``out`` (4, N, n) in place.

    Arguments are the fields of `PackedSession`; ``out`` receives positions, velocities,
    controls and references (the last two NaN at the last sample and for players without).
    """
    n_players, n = kinds.size, out.shape[2]
    out[2:, :, n - 1] = np.nan  # every other sample is written below
    for i in range(n_players):
        out[0, i, 0] = starts[i, 0]
        out[1, i, 0] = starts[i, 1]
    xs, vs, previous = np.empty(n_players), np.empty(n_players), np.empty(n_players)
    trainers = _stiffest_first(np.flatnonzero(kinds == VIRTUAL_TRAINER), params, param_rows)
    slot = np.empty(n_players, np.int64)
    slot[trainers] = np.arange(trainers.size)
    trainer_rows = param_rows[trainers]
    problems = np.empty((trainers.size, PROBLEM_COLUMNS))
    coupled = np.empty(trainers.size, np.bool_)
    solved = np.empty((trainers.size, 3))
    for k in range(n - 1):
        for i in range(n_players):
            m = neighbour_count[i]
            gather_neighbours(out[0], out[1], k, neighbour_index[i, :m], xs, vs, previous)
            x, v, reference = out[0, i, k], out[1, i, k], references[i, k]
            out[3, i, k] = reference
            if kinds[i] == VIRTUAL_TRAINER:
                t = slot[i]
                coupled[t] = virtual_trainer_problem(
                    x, v, xs[:m], vs[:m], previous[:m], reference, problems[t]
                )
                continue
            u = np.nan
            if kinds[i] == RECORDED:
                x, v = recorded_step(tracks[i, :, : track_lengths[i]], k)
            elif kinds[i] == DEEP:
                x, v, u = _deep_player_step(
                    networks, slots[i], params[param_rows[i]], x, v, xs[:m], vs[:m], reference
                )
            else:
                c = slots[i]
                x, v, u = cyber_step(
                    q_tables[c],
                    modes[c],
                    edges[c],
                    offsets[c],
                    actions[c, : n_actions[c]],
                    params[param_rows[i]],
                    substeps[c],
                    x,
                    v,
                    xs[:m],
                    vs[:m],
                    reference,
                )
            out[0, i, k + 1] = x
            out[1, i, k + 1] = v
            out[2, i, k] = u
        optimal_control_steps(problems, coupled, params, trainer_rows, solved)
        for t in range(trainers.size):
            out[0, trainers[t], k + 1] = solved[t, 0]
            out[1, trainers[t], k + 1] = solved[t, 1]
            out[2, trainers[t], k] = solved[t, 2]


@njit(cache=True, nogil=True)
def _stiffest_first(trainers: Ints, params: NDArray[np.void], param_rows: Ints) -> Ints:
    """Order the virtual trainers by their costate-control rate, fastest first (stable).

    The rate (`mirror_avatar.dynamics.coupling_rate`) sets a problem's fewest RK4 steps, and
    the lockstep shots stop at the last problem still stepping: problems with as many steps
    side by side waste none. Each problem's solution does not depend on the order.
    """
    rates = np.empty(trainers.size)
    for t in range(trainers.size):
        p = params[param_rows[trainers[t]]]
        rates[t] = coupling_rate(p, p.theta_p)
    return trainers[np.argsort(-rates, kind="mergesort")]


@njit(cache=True, nogil=True)
def _deep_player_step(
    networks: PackedNetworks,
    d: int,
    p: NDArray[np.void],
    x: float,
    v: float,
    positions: Array,
    velocities: Array,
    reference: float,
) -> tuple[float, float, float]:
    """`deep_step` of deep player ``d`` of the packed networks."""
    weights, sizes, n_sizes, n_slots, use_reference, actions, n_actions, substeps = networks
    return deep_step(
        weights[d],
        sizes[d, : n_sizes[d]],
        n_slots[d],
        use_reference[d] != 0,
        actions[d, : n_actions[d]],
        p,
        substeps[d],
        x,
        v,
        positions,
        velocities,
        reference,
    )
