"""Group synchronisation of N players (METHODS section 8), as functions on arrays of phases.

Cluster phase (Richardson et al. 2012; Alderisio et al. 2017): with each player's phase
theta_k(t) (`mirror_avatar.metrics.coordination.compute_phase`),

- cluster phase ``q(t) = (1/N) sum_k exp(i theta_k)``, ``Phi(t) = arg q(t)``;
- each player's phase relative to the group ``phi_k = wrap(theta_k - Phi)`` and its mean
  ``phibar_k = arg mean_t exp(i phi_k)``;
- individual synchronisation to the group ``rho_k = |mean_t exp(i (phi_k - phibar_k))|``;
- group synchronisation ``rho_g(t) = |(1/N) sum_k exp(i (phi_k(t) - phibar_k))|`` (1 = perfectly
  synchronised), reported as its time mean and SD;
- the Kuramoto order parameter ``r(t) = |q(t)|``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.metrics.coordination import wrap_phase

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ClusterPhase:
    """The cluster-phase analysis of N phase series of n samples.

    Attributes
    ----------
    cluster_phase
        Phi(t), shape (n,), radians.
    relative_phases
        phi_k(t), shape (N, n), radians in [-pi, pi].
    mean_relative_phases
        phibar_k, shape (N,), radians.
    individual
        rho_k, shape (N,), in [0, 1].
    group
        rho_g(t), shape (n,), in [0, 1].
    kuramoto
        r(t), shape (n,), in [0, 1].
    """

    cluster_phase: Array
    relative_phases: Array
    mean_relative_phases: Array
    individual: Array
    group: Array
    kuramoto: Array


def compute_cluster_phase(phases: ArrayLike) -> ClusterPhase:
    """Cluster-phase synchronisation of players with phases theta_k(t) (module docstring).

    Parameters
    ----------
    phases
        Each player's phase, shape (N, n), radians (wrapped or unwrapped), N >= 2.

    Raises
    ------
    InputError
        Fewer than two players or samples, or non-finite phases.
    """
    theta = np.asarray(phases, dtype=float)
    if theta.ndim != 2 or theta.shape[0] < 2 or theta.shape[1] < 2:
        raise InputError("phases", f"need shape (N >= 2, n >= 2), got {theta.shape}")
    if not np.all(np.isfinite(theta)):
        raise InputError("phases", "contain NaN or infinite values")
    q = np.mean(np.exp(1j * theta), axis=0)
    cluster = np.angle(q)
    relative = wrap_phase(theta - cluster)
    mean_relative = np.angle(np.mean(np.exp(1j * relative), axis=1))
    centred = np.exp(1j * (relative - mean_relative[:, None]))
    return ClusterPhase(
        cluster_phase=cluster,
        relative_phases=relative,
        mean_relative_phases=mean_relative,
        individual=np.abs(np.mean(centred, axis=1)),
        group=np.abs(np.mean(centred, axis=0)),
        kuramoto=np.abs(q),
    )
