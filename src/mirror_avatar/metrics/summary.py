"""The one summary of a session's coordination, composed from the metric functions.

`session_metrics` is what the command line, the experiments, the report and live play all call.
Its keys depend on the number of players:

- every session: ``emd_reference_<i>``, each player's velocity IMS against the IMS of its own
  reference velocities (None for a player without references), and ``emd_target_<i>`` for each
  player trained to imitate someone (a cyber player: ``target_ims`` in its description in the
  session's metadata), its velocity IMS against its target's;
- two players (METHODS section 6; relative phase and time lag of player 0 with respect to player
  1, positive when player 0 is ahead): ``rmse`` (units), ``phase_locking`` (the mean
  resultant length of the relative phase, 1 = phase locked: the paper's "circular variance", CV),
  ``mean_relative_phase`` and ``sd_relative_phase`` (circular SD) (rad), ``time_lag`` (s) and
  ``emd_players`` (between the two players' velocity IMS);
- three or more (METHODS section 8): ``group_synchronisation`` (time mean of rho_g) and its SD,
  ``kuramoto_order`` (time mean of r), and ``players``: for each, ``synchronisation`` (rho_k),
  ``relative_phase_to_group`` (phibar_k, rad) and, against the mean position of its neighbours,
  ``phase_locking``, ``rmse``, ``time_lag`` and ``max_cross_correlation``.

A player that does not move has no phase: its phase-based metrics are NaN.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.metrics.coordination import (
    compute_circular_sd,
    compute_cross_correlation_peak,
    compute_mean_relative_phase,
    compute_phase,
    compute_phase_locking,
    compute_relative_phase,
    compute_rmse,
)
from mirror_avatar.metrics.group import compute_cluster_phase
from mirror_avatar.session import Session
from mirror_avatar.signature import compute_emd, compute_ims

Array = NDArray[np.float64]

TRIM = 1.0
"""Seconds of start-up transient the toolkit leaves out of a session's metrics by default
(**choice**: the players start at rest in the middle of the range)."""


def session_metrics(session: Session, trim: float = 0.0) -> dict[str, Any]:
    """All coordination metrics of a session of any number of players (see the module docstring).

    Parameters
    ----------
    session
        The session.
    trim
        Seconds dropped at the start (transient), a **choice**.
    """
    if trim > 0:
        session = session.trimmed(trim)
    metrics: dict[str, Any] = {}
    if session.n_players == 2:
        metrics = _dyad_metrics(session)
    elif session.n_players > 2:
        metrics = _group_metrics(session)
    ims = [compute_ims(v) for v in session.velocities]
    for i, references in enumerate(session.references):
        finite = references[np.isfinite(references)]
        metrics[f"emd_reference_{i}"] = (
            compute_emd(ims[i], compute_ims(finite)) if finite.size else None
        )
    for i, description in enumerate(session.metadata.get("players", [])[: session.n_players]):
        if isinstance(description, dict) and "target_ims" in description:
            target = np.asarray(description["target_ims"], dtype=np.float64)
            metrics[f"emd_target_{i}"] = compute_emd(ims[i], target)
    return metrics


def _rate(session: Session) -> float:
    return 1.0 / float(np.median(np.diff(session.times)))


def _moves(x: Array) -> bool:
    return bool(np.ptp(x) > 0.0)


def _pair_metrics(x0: Array, x1: Array, rate: float) -> dict[str, float]:
    """RMSE, phase locking and cross-correlation of two position series (NaN without motion)."""
    out = {"rmse": compute_rmse(x0, x1)}
    if not (_moves(x0) and _moves(x1)):
        nan = float("nan")
        return out | {
            "phase_locking": nan,
            "mean_relative_phase": nan,
            "sd_relative_phase": nan,
            "time_lag": nan,
            "max_cross_correlation": nan,
        }
    dphi = compute_relative_phase(x0, x1)
    cv = compute_phase_locking(dphi)
    lag, peak = compute_cross_correlation_peak(x0, x1, rate)
    return out | {
        "phase_locking": cv,
        "mean_relative_phase": compute_mean_relative_phase(dphi),
        "sd_relative_phase": compute_circular_sd(cv),
        "time_lag": lag,
        "max_cross_correlation": peak,
    }


def _dyad_metrics(session: Session) -> dict[str, Any]:
    x, v = session.positions, session.velocities
    pair = _pair_metrics(x[0], x[1], _rate(session))
    keys = ("rmse", "phase_locking", "mean_relative_phase", "sd_relative_phase", "time_lag")
    return {key: pair[key] for key in keys} | {
        "emd_players": compute_emd(compute_ims(v[0]), compute_ims(v[1]))
    }


def _group_metrics(session: Session) -> dict[str, Any]:
    x, rate = session.positions, _rate(session)
    players: list[dict[str, Any]] = []
    for k in range(session.n_players):
        neighbours = np.flatnonzero(session.graph[k])
        row: dict[str, Any] = {"label": session.labels[k], "neighbours": neighbours.tolist()}
        if neighbours.size:
            pair = _pair_metrics(x[k], x[neighbours].mean(axis=0), rate)
            keys = ("phase_locking", "rmse", "time_lag", "max_cross_correlation")
            row |= {key: pair[key] for key in keys}
        players.append(row)
    nan = float("nan")
    out: dict[str, Any] = {
        "group_synchronisation": nan,
        "group_synchronisation_sd": nan,
        "kuramoto_order": nan,
    }
    if all(_moves(row) for row in x):
        cluster = compute_cluster_phase(np.array([compute_phase(row) for row in x]))
        out = {
            "group_synchronisation": float(cluster.group.mean()),
            "group_synchronisation_sd": float(cluster.group.std()),
            "kuramoto_order": float(cluster.kuramoto.mean()),
        }
        for row, rho, phase in zip(
            players, cluster.individual, cluster.mean_relative_phases, strict=True
        ):
            row |= {"synchronisation": float(rho), "relative_phase_to_group": float(phase)}
    for key in ("phase_locking", "rmse"):
        values = [row[key] for row in players if key in row]
        out[f"mean_{key}"] = float(np.mean(values)) if values else nan
    return out | {"players": players}
