"""The deep avatar's input: its own state, its neighbours' ("dynamic input", METHODS section 8).

The network sees a fixed-length vector built every period from the avatar's own position x and
velocity x', optionally its own reference velocity r_s (an avatar that leads, as the tabular
leader's ``"reference"`` features), and its neighbours' states (**choice**, scaled so that every
feature is of order 1):

- ``x * POSITION_SCALE``, ``x' * VELOCITY_SCALE`` and, when used, ``r_s * VELOCITY_SCALE``;
- the neighbours' mean (the partner of METHODS section 7) relative to itself:
  ``(m - x) * RELATIVE_POSITION_SCALE``, ``(m' - x') * RELATIVE_VELOCITY_SCALE``;
- ``n_slots`` slots for the neighbours themselves, each ``(x_j - x, x_j' - x')`` scaled as the
  mean and a 1 saying the slot holds a neighbour. The slots are sorted by relative position, so
  the input does not depend on how the neighbours are numbered; empty slots are padded with the
  avatar's own state (zeros relative to itself, and 0 for presence), so the same network plays
  whatever the number of neighbours. With more neighbours than slots, the nearest fill them.

A dyad needs no slot (its one neighbour is the mean); a group of N uses N - 1.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

Array = NDArray[np.float64]

POSITION_SCALE = 2.0
"""Factor on own position (units): the playing range maps to [-1, 1]."""

VELOCITY_SCALE = 1.0
"""Factor on own and reference velocity (units/s)."""

RELATIVE_POSITION_SCALE = 10.0
"""Factor on a neighbour's position relative to the avatar's (units)."""

RELATIVE_VELOCITY_SCALE = 2.0
"""Factor on a neighbour's velocity relative to the avatar's (units/s)."""

SLOT_WIDTH = 3
"""Features per neighbour slot: relative position, relative velocity, presence."""


def count_features(n_slots: int, use_reference: bool) -> int:
    """Length of the input vector for ``n_slots`` neighbour slots, with or without r_s."""
    return 4 + int(use_reference) + SLOT_WIDTH * n_slots


@njit(cache=True, nogil=True)
def encode(
    x: float,
    v: float,
    reference: float,
    positions: Array,
    velocities: Array,
    n_slots: int,
    use_reference: bool,
    out: Array,
) -> None:
    """Write the input vector of one state into ``out`` (see the module docstring).

    Parameters
    ----------
    x, v
        Own position (units) and velocity (units/s).
    reference
        Own reference velocity (units/s), read when ``use_reference``.
    positions, velocities
        The neighbours' positions and velocities, shape (m,); m = 0 for a player alone.
    n_slots, use_reference
        The input layout.
    out
        Receives the features, shape (`count_features`,).
    """
    out[0] = x * POSITION_SCALE
    out[1] = v * VELOCITY_SCALE
    i = 2
    if use_reference:
        out[i] = reference * VELOCITY_SCALE
        i += 1
    m = positions.size
    mean_x, mean_v = x, v
    if m > 0:
        mean_x = positions.sum() / m
        mean_v = velocities.sum() / m
    out[i] = (mean_x - x) * RELATIVE_POSITION_SCALE
    out[i + 1] = (mean_v - v) * RELATIVE_VELOCITY_SCALE
    i += 2
    out[i:] = 0.0
    if n_slots == 0 or m == 0:
        return
    relative = positions - x
    chosen = np.argsort(np.abs(relative))[:n_slots]
    ordered = chosen[np.argsort(relative[chosen])]
    for s in range(ordered.size):
        j = ordered[s]
        out[i + SLOT_WIDTH * s] = relative[j] * RELATIVE_POSITION_SCALE
        out[i + SLOT_WIDTH * s + 1] = (velocities[j] - v) * RELATIVE_VELOCITY_SCALE
        out[i + SLOT_WIDTH * s + 2] = 1.0
