"""How the cyber player's continuous state is cut into the cells of its Q-table (METHODS section 7).

The state is built from the avatar's own position x and velocity x', its partner's (the mean of
its neighbours, `mirror_avatar.players.base.partner_state`) x_p and x_p', and its own reference
velocity r_s. Three feature sets (**choice**, configurable):

- ``"absolute"``: ``[x, x', x_p, x_p']``, the METHODS state;
- ``"relative"``: ``[x - x_p, x' - x_p', x_p, x_p']`` (METHODS allows relative features);
- ``"reference"``: ``[x - x_p, x' - r_s, x, r_s]``, a **departure**: the avatar has a motion
  source of its own, as the person it imitates does (used for the leader, see
  `mirror_avatar.training.imitation.make_role_discretisation`).

Each feature is cut by its own increasing bin edges; `state_index` is the compiled cell lookup
used by play and training alike.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError

Array = NDArray[np.float64]
Features = Literal["absolute", "relative", "reference"]
FEATURES: tuple[Features, ...] = ("absolute", "relative", "reference")
"""The feature sets, in the order of their compiled codes `ABSOLUTE`, `RELATIVE`, `REFERENCE`."""
ABSOLUTE, RELATIVE, REFERENCE = range(3)
N_FEATURES = 4


@njit(cache=True, nogil=True, inline="always")
def _bin(value: float, edges: Array, start: int, stop: int) -> int:
    """Return ``searchsorted(edges[start:stop], value, side="right")`` (NaN past every edge).

    The edges are sorted, so this counts those that ``value`` is not below: a few comparisons
    without branches, which beat a binary search over so few edges.
    """
    count = 0
    for i in range(start, stop):
        count += not value < edges[i]
    return count


@njit(cache=True)
def compute_features(
    x: float, v: float, xp: float, vp: float, r: float, mode: int
) -> tuple[float, float, float, float]:
    """Return the four features of a state in feature set ``mode`` (module docstring)."""
    if mode == ABSOLUTE:
        return x, v, xp, vp
    if mode == RELATIVE:
        return x - xp, v - vp, xp, vp
    return x - xp, v - r, x, r


@njit(cache=True)
def state_index(
    x: float,
    v: float,
    xp: float,
    vp: float,
    r: float,
    mode: int,
    edges: Array,
    offsets: NDArray[np.int64],
) -> int:
    """Cell of a state: own x, x', partner's x_p, x_p', own reference r_s (units, units/s).

    ``mode``, ``edges`` and ``offsets`` are `Discretisation.mode`, ``flat_edges`` and ``offsets``.
    """
    index = 0
    for d, value in enumerate(compute_features(x, v, xp, vp, r, mode)):
        start, stop = offsets[d], offsets[d + 1]
        index = index * (stop - start + 1) + _bin(value, edges, start, stop)
    return index


@dataclass(frozen=True, eq=False)
class Discretisation:
    """The cells of the Q-table: a feature set and the bin edges of each feature.

    Parameters
    ----------
    features
        ``"absolute"``, ``"relative"`` or ``"reference"`` (see the module docstring; positions in
        units, velocities in units/s).
    edges
        Four increasing arrays of interior bin edges, one per feature; feature d has
        ``len(edges[d]) + 1`` bins, the outer two open-ended (values beyond the range fall in
        the end bins).
    """

    features: Features
    edges: tuple[Array, ...]

    def __post_init__(self) -> None:
        if self.features not in FEATURES:
            raise InputError("features", f"must be one of {FEATURES}, not {self.features!r}")
        edges = tuple(np.asarray(e, dtype=np.float64).ravel() for e in self.edges)
        if len(edges) != N_FEATURES:
            raise InputError("edges", f"need {N_FEATURES} arrays of bin edges, got {len(edges)}")
        for d, e in enumerate(edges):
            if not np.all(np.isfinite(e)) or np.any(np.diff(e) <= 0):
                raise InputError("edges", f"edges of feature {d} must be finite and increasing")
        object.__setattr__(self, "edges", edges)

    @classmethod
    def uniform(
        cls,
        features: Features,
        ranges: Iterable[tuple[float, float]],
        n_bins: Iterable[int],
    ) -> Discretisation:
        """Equal-width bins: feature d has ``n_bins[d]`` bins over ``ranges[d]`` (plus tails)."""
        edges = tuple(
            np.linspace(lo, hi, n + 1)[1:-1] for (lo, hi), n in zip(ranges, n_bins, strict=True)
        )
        return cls(features, edges)

    @property
    def mode(self) -> int:
        """Compiled code of the feature set: `ABSOLUTE`, `RELATIVE` or `REFERENCE`."""
        return FEATURES.index(self.features)

    @property
    def needs_reference(self) -> bool:
        """True when the state includes the avatar's own reference velocity."""
        return self.features == "reference"

    @property
    def shape(self) -> tuple[int, ...]:
        """Number of bins per feature."""
        return tuple(e.size + 1 for e in self.edges)

    @property
    def n_states(self) -> int:
        """Number of cells (rows of the Q-table)."""
        return math.prod(self.shape)

    @cached_property
    def flat_edges(self) -> Array:
        """All interior edges, concatenated feature after feature."""
        return np.concatenate(self.edges)

    @cached_property
    def offsets(self) -> NDArray[np.int64]:
        """Start of each feature's edges in `flat_edges`, then the total, shape (5,)."""
        return np.concatenate([[0], np.cumsum([e.size for e in self.edges])]).astype(np.int64)

    def index(self, x: float, v: float, xp: float, vp: float, r: float = 0.0) -> int:
        """Return the cell of a state (``r`` only matters for ``"reference"`` features)."""
        return int(state_index(x, v, xp, vp, r, self.mode, self.flat_edges, self.offsets))


def make_default_discretisation(features: Features = "relative") -> Discretisation:
    """Make the default discretisation of a feature set (**choice**), finer near zero.

    Parameters
    ----------
    features
        ``"relative"`` (default; 10 x 8 x 6 x 7 = 3360 cells), ``"absolute"`` (8 x 8 x 6 x 7 =
        2688 cells) or ``"reference"`` (10 x 10 x 8 x 12 = 9600 cells: ``x - x_p`` and
        ``x' - r_s`` symmetric about 0 with edges at ±0.02, 0.05, 0.1, 0.2 units and ±0.05,
        0.1, 0.2, 0.4 units/s, ``x`` in 8 bins over ±0.4 units, ``r_s`` with edges at 0, ±0.05,
        0.15, 0.3, 0.5, 0.8 units/s).
    """
    if features == "reference":
        return Discretisation(
            features,
            (
                symmetric_edges(0.02, 0.05, 0.1, 0.2),
                symmetric_edges(0.05, 0.1, 0.2, 0.4),
                np.linspace(-0.4, 0.4, 7),
                symmetric_edges(0.05, 0.15, 0.3, 0.5, 0.8),
            ),
        )
    partner = (np.linspace(-0.4, 0.4, 5), np.array([-0.5, -0.2, -0.05, 0.05, 0.2, 0.5]))
    if features == "relative":
        own = (symmetric_edges(0.02, 0.05, 0.1, 0.2), symmetric_edges(0.1, 0.25, 0.5))
    else:
        own = (np.linspace(-0.45, 0.45, 7), symmetric_edges(0.1, 0.25, 0.5))
    return Discretisation(features, own + partner)


def symmetric_edges(*positive: float) -> Array:
    """Bin edges ``-positive[::-1], 0, positive``."""
    edges = np.asarray(positive, dtype=np.float64)
    return np.concatenate([-edges[::-1], [0.0], edges])
