"""The adaptive partner's position error on the bundled leaders, before and after (METHODS 13).

Each of the 18 bundled trials (`mirror_avatar.datasets.load_zhai2017`, resampled to 100 Hz as
``mirror-avatar benchmark`` reads them) leads the ``adaptive`` player open-loop on the control
grid. Value = the default player (controller sampled every control period, as the public
MirrorGame loop samples on every pass); baseline = the previous default (``sampling=0.1``: held
over 0.09 s). Rows per leader: the largest and the RMS position error after the 1 s transient
(`mirror_avatar.experiments.partner_benchmark.TRIM`). The largest-error row's note says where
the errors come from: the largest error outside the half second after each tracking drop-out
(`mirror_avatar.files.trials.Trial.held_runs` of the recording), the share of errors over Zhai et
al.'s 0.2 that fall there, and the share of the time the leader moves faster than the player's
own top speed in that trial. ``quick`` runs one fast and one slow leader.
"""

from __future__ import annotations

import numpy as np

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.engine.loop import play
from mirror_avatar.experiments.partner_benchmark import PUBLISHED_ADAPTIVE_BOUNDS, TRIM
from mirror_avatar.files.trials import Trial
from mirror_avatar.players import RecordedPlayer
from mirror_avatar.players.adaptive import AdaptivePlayer
from mirror_avatar.sessions.session import Session

AFTER_DROP_OUT = 0.5
"""Seconds after a drop-out's last held sample counted as its effect."""

PREVIOUS = {"sampling": 0.1}
"""The previous default: the paper's sampling time, rounded to three control periods."""


def follow(native: Trial, options: dict[str, float]) -> Session:
    """Let the adaptive player follow a bundled trial replayed at 100 Hz."""
    leader = RecordedPlayer(native.resampled(100.0), CONTROL_PERIOD)
    duration = (leader.track.shape[1] - 1) * CONTROL_PERIOD
    return play([leader, AdaptivePlayer(options)], duration=duration, seed=0)


def where_errors_come_from(native: Trial, session: Session) -> str:
    """Say where a leader's largest errors come from (see the module docstring)."""
    times = np.arange(session.positions.shape[1]) * CONTROL_PERIOD
    error = np.abs(session.positions[1] - session.positions[0])
    kept = times >= TRIM
    near = np.zeros(times.shape, dtype=bool)
    for start, stop in native.held_runs():
        near |= (times >= start) & (times <= stop + AFTER_DROP_OUT)
    over = kept & (error > PUBLISHED_ADAPTIVE_BOUNDS["position"])
    top_speed = np.abs(session.velocities[1]).max()
    outrun = np.abs(session.velocities[0][kept]) > top_speed
    share = (over & near).sum() / max(over.sum(), 1)
    return (
        f"{len(native.held_runs())} drop-outs, largest error outside them "
        f"{error[kept & ~near].max():.3f}; "
        f"errors > 0.2 at drop-outs {share:.0%}; leader faster than the player's top speed "
        f"({top_speed:.2f} units/s) {outrun.mean():.0%} of the time"
    )


def run(quick: bool) -> list[dict[str, object]]:
    leaders = load_zhai2017()
    if quick:
        leaders = [leaders[0], leaders[-1]]
    rows: list[dict[str, object]] = []
    for native in leaders:
        after, before = follow(native, {}), follow(native, PREVIOUS)
        errors = [
            np.abs(s.positions[1] - s.positions[0])[round(TRIM / CONTROL_PERIOD) :]
            for s in (after, before)
        ]
        for measure, reduce, note in (
            ("max", np.max, where_errors_come_from(native, after)),
            ("RMS", lambda e: np.sqrt(np.mean(e**2)), ""),
        ):
            value, baseline = float(reduce(errors[0])), float(reduce(errors[1]))
            rows.append(
                {
                    "name": f"{native.label}: {measure} position error after {TRIM:g} s",
                    "value": value,
                    "unit": "units",
                    "baseline": baseline,
                    "ratio": value / baseline,
                    "note": note,
                }
            )
    return rows
