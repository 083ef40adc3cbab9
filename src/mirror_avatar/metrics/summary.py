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

from mirror_avatar.metrics.coordination import compute_circular_sd, compute_mean_relative_phase
from mirror_avatar.metrics.quantities import Quantities
from mirror_avatar.metrics.registry import GROUP_PLAYER
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.signature import compute_emd, compute_ims

Array = NDArray[np.float64]

TRIM = 1.0
"""Seconds of start-up transient the toolkit leaves out of a session's metrics by default
(**choice**: the players start at rest in the middle of the range)."""


def session_metrics(
    session: Session, trim: float = 0.0, quantities: Quantities | None = None
) -> dict[str, Any]:
    """All coordination metrics of a session of any number of players (see the module docstring).

    Parameters
    ----------
    session
        The session.
    trim
        Seconds dropped at the start (transient), a **choice**.
    quantities
        The session's shared quantities (after the trim), when its measures use them too.
    """
    if trim > 0:
        session = session.trimmed(trim)
    q = quantities or Quantities.of(session)
    metrics: dict[str, Any] = {}
    if session.n_players == 2:
        metrics = _dyad_metrics(q)
    elif session.n_players > 2:
        metrics = _group_metrics(session, q)
    ims = q.ims
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


def _with_neighbours(
    k: int, neighbours: NDArray[np.intp], x: Array, v: Array
) -> tuple[Array, Array]:
    """Return player k and the mean of its neighbours as a pair: positions, velocities."""
    return (np.array([x[k], x[neighbours].mean(axis=0)]),
            np.array([v[k], v[neighbours].mean(axis=0)]))  # fmt: skip


def _pair_metrics(q: Quantities) -> dict[str, float]:
    """RMSE, phase locking and cross-correlation of two players (NaN without motion)."""
    out = {"rmse": q.rmse}
    if not q.moving:
        nan = float("nan")
        return out | {
            "phase_locking": nan,
            "mean_relative_phase": nan,
            "sd_relative_phase": nan,
            "time_lag": nan,
            "max_cross_correlation": nan,
        }
    lag, peak = q.cross_correlation_peak
    return out | {
        "phase_locking": q.phase_locking,
        "mean_relative_phase": compute_mean_relative_phase(q.relative_phase),
        "sd_relative_phase": compute_circular_sd(q.phase_locking),
        "time_lag": lag,
        "max_cross_correlation": peak,
    }


def _dyad_metrics(q: Quantities) -> dict[str, Any]:
    pair = _pair_metrics(q)
    keys = ("rmse", "phase_locking", "mean_relative_phase", "sd_relative_phase", "time_lag")
    return {key: pair[key] for key in keys} | {"emd_players": compute_emd(q.ims[0], q.ims[1])}


def _group_metrics(session: Session, q: Quantities) -> dict[str, Any]:
    x, v, rate = session.positions, session.velocities, q.rate
    players: list[dict[str, Any]] = []
    for k in range(session.n_players):
        neighbours = np.flatnonzero(session.graph[k])
        row: dict[str, Any] = {"label": session.labels[k], "neighbours": neighbours.tolist()}
        if neighbours.size:
            pair = _pair_metrics(Quantities(*_with_neighbours(k, neighbours, x, v), rate))
            row |= {key: pair[key] for key in GROUP_PLAYER if key in pair}
        players.append(row)
    nan = float("nan")
    out: dict[str, Any] = {
        "group_synchronisation": nan,
        "group_synchronisation_sd": nan,
        "kuramoto_order": nan,
    }
    if q.moving:
        cluster = q.cluster
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
