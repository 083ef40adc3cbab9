"""The registry of player kinds: what the compiled batch loop needs to run each kind of player.

A kind of player the batch engine runs registers itself, in the module that defines the player,
with a `PlayerKind`: how its players' plans (`mirror_avatar.players.base.PlayerPlan`, whose
``kind`` names it) are packed into arrays, and the compiled step that advances one of them by
one period. The engine names no kind: it writes its loop from the kinds a session holds
(`mirror_avatar.engine.dispatch`), as nengo builds its step functions from its operators.

A kind's compiled functions take its packed arrays first, the fields of the named tuple its
``pack`` returns in their order (``*state``: the loop unpacks them once, so the hot loop touches
no tuple), then the player's ``slot``, its row in them (players of the kind numbered in session
order):

- ``step(*state, slot, k, x, v, positions, velocities, previous, reference)``: the player's
  state at t_k, its neighbours' positions and velocities at t_k and positions at t_{k-1}, shape
  (m,), and its reference velocity (NaN for none); returns its position and velocity at
  t_k + T and its control (units/s², NaN for none).
- A kind whose players are solved together (the virtual trainers' problems of a period) also
  has ``solve(*state, k, out)``: its ``step`` only poses the player's problem and returns nothing,
  and ``solve``, called once all players have stepped, writes its players' positions and
  velocities at sample k + 1 and controls at sample k into ``out`` (4, N, n).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.dynamics import records
from mirror_avatar.players.base import PlayerPlan

Ints = NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class PlayerKind:
    """One kind of player of the compiled batch loop (see the module docstring).

    Attributes
    ----------
    name
        The name its plans carry (`PlayerPlan.kind`), a Python identifier.
    state
        The named tuple of arrays its compiled functions read (their first arguments).
    pack
        ``pack(plans, players)``: the session's plans of this kind in order and their rows in
        the session, shape (K,); returns its ``state``.
    step
        The compiled step, a module-level numba function (the engine imports it by name).
    solve
        The compiled solve of a kind solved together, else None.
    """

    name: str
    state: type[tuple[Any, ...]]
    pack: Callable[[Sequence[PlayerPlan], Ints], tuple[Any, ...]]
    step: Any
    solve: Any = None

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise ValueError(f"a player kind's name must be an identifier, got {self.name!r}")


_KINDS: dict[str, PlayerKind] = {}


def register_kind(kind: PlayerKind) -> PlayerKind:
    """Register ``kind`` under its name and return it; a name is taken by one module only."""
    known = _KINDS.get(kind.name)
    if known is not None and known.step.__module__ != kind.step.__module__:
        raise ValueError(f"the player kind {kind.name!r} is already registered by another module")
    _KINDS[kind.name] = kind
    return kind


def player_kind(name: str) -> PlayerKind:
    """Return the kind registered as ``name`` (its module registers it when imported)."""
    try:
        return _KINDS[name]
    except KeyError:
        raise ValueError(f"no player kind {name!r} is registered") from None


def parameter_table(plans: Sequence[PlayerPlan]) -> tuple[NDArray[np.void], Ints]:
    """Return the plans' distinct HKB parameters as records and each plan's row in them.

    The records are of `mirror_avatar.dynamics.PARAMS_DTYPE`, shape (P,); the rows, (K,).
    """
    distinct = list(dict.fromkeys(plan.params for plan in plans))
    rows = np.array([distinct.index(plan.params) for plan in plans], dtype=np.int64)
    return records(distinct), rows
