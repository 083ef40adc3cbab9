"""The quantities a session's metrics and measures share, each computed once on first use.

A session's relative phase gives its phase locking, mean relative phase, circular SD and
synchrony episodes; its cross-correlation peak gives both the time lag and the peak; its
players' phases give the group's cluster phase and the weak-null test; their velocities' IMS
give the EMD between them and to their references. `Quantities` holds the
positions and velocities of one session (or one surrogate of it) and computes each such
quantity the first time a metric or measure asks for it, so that
`mirror_avatar.metrics.summary.session_metrics` and
`mirror_avatar.metrics.measures.session_measures` compose the same numbers instead of computing
them twice.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.metrics.analysis_rate import session_rate
from mirror_avatar.metrics.coordination import (
    compute_cross_correlation_peak,
    compute_phase,
    compute_phase_locking,
    compute_relative_phase,
    compute_rmse,
)
from mirror_avatar.metrics.group import ClusterPhase, compute_cluster_phase
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.signature import compute_ims

Array = NDArray[np.float64]


class Quantities:
    """The shared quantities of one session's players.

    Parameters
    ----------
    positions, velocities
        Shape (N, n): positions (units) and velocities (units/s), uniform at ``rate``.
    rate
        Sampling rate (Hz).
    """

    def __init__(self, positions: Array, velocities: Array, rate: float) -> None:
        self.positions = positions
        self.velocities = velocities
        self.rate = rate

    @classmethod
    def of(cls, session: Session) -> Quantities:
        """Return the quantities of a session, at its rate (one over its median interval)."""
        return cls(session.positions, session.velocities, session_rate(session))

    @cached_property
    def moving(self) -> bool:
        """Whether every player moves (a player that does not has no phase)."""
        return all(bool(np.ptp(row) > 0.0) for row in self.positions)

    @cached_property
    def ims(self) -> list[Array]:
        """Each player's velocity IMS (`mirror_avatar.signatures.signature.compute_ims`)."""
        return [compute_ims(row) for row in self.velocities]

    @cached_property
    def phases(self) -> Array:
        """Each player's phase (rad), shape (N, n)."""
        return np.array([compute_phase(row) for row in self.positions])

    @cached_property
    def cluster(self) -> ClusterPhase:
        """The cluster phase of the players (three or more)."""
        return compute_cluster_phase(self.phases)

    @cached_property
    def relative_phase(self) -> Array:
        """Relative phase (rad) of player 0 with respect to player 1 (a pair)."""
        return compute_relative_phase(self.positions[0], self.positions[1])

    @cached_property
    def phase_locking(self) -> float:
        """Mean resultant length of the relative phase (a pair; the field's CV)."""
        return compute_phase_locking(self.relative_phase)

    @cached_property
    def cross_correlation_peak(self) -> tuple[float, float]:
        """Lag (s; positive: player 0 ahead) and value of the positions' cross-correlation peak."""
        return compute_cross_correlation_peak(self.positions[0], self.positions[1], self.rate)

    @cached_property
    def rmse(self) -> float:
        """RMS of the difference of the two players' positions (units)."""
        return compute_rmse(self.positions[0], self.positions[1])
