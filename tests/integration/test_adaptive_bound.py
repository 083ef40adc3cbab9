"""The adaptive player against Zhai et al.'s bound of 0.2 on the bundled leaders.

Zhai et al. (2017, section 6.3.1): with their adaptive player following a person, the position
error never exceeded 0.2. On the bundled slow leaders it holds after the one-second transient
except in the half second after a tracking drop-out (a run of identical recorded samples: the
leader stands still, then jumps). The fast leaders outrun the player (METHODS section 13).
"""

from __future__ import annotations

import numpy as np

from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.engine.loop import play
from mirror_avatar.experiments.partner_benchmark import PUBLISHED_ADAPTIVE_BOUNDS, TRIM
from mirror_avatar.files.trials import Trial
from mirror_avatar.players import RecordedPlayer
from mirror_avatar.players.adaptive import AdaptivePlayer

AFTER_DROP_OUT = 0.5
"""Seconds after a drop-out's last held sample counted as its effect."""


def near_drop_outs(trial: Trial, times: np.ndarray) -> np.ndarray:
    """Which of ``times`` (s from the trial's start) lie in a drop-out or just after one.

    A drop-out (`Trial.held_runs`) covers its run's first to last sample and `AFTER_DROP_OUT`
    seconds more.
    """
    near = np.zeros(times.shape, dtype=bool)
    for start, stop in trial.held_runs():
        near |= (times >= start) & (times <= stop + AFTER_DROP_OUT)
    return near


def test_held_runs_and_near_drop_outs_by_hand() -> None:
    trial = Trial(np.arange(6.0), np.array([0.0, 0.1, 0.1, 0.1, 0.2, 0.3]))
    assert trial.held_runs().tolist() == [[1.0, 3.0]]
    ends = Trial(np.arange(5.0) + 2.0, np.array([0.2, 0.2, 0.1, 0.3, 0.3]))
    assert ends.held_runs().tolist() == [[0.0, 1.0], [3.0, 4.0]]
    times = np.array([0.5, 1.0, 2.5, 3.4, 3.6, 5.0])
    assert near_drop_outs(trial, times).tolist() == [False, True, True, True, False, False]


def test_adaptive_player_keeps_zhais_bound_on_slow_leaders_away_from_drop_outs(
    zhai_trials: list[Trial],
) -> None:
    """Largest position error after the transient, outside drop-outs: at most 0.2 (0.19995 on
    slow-3, the closest); slow-2 exceeds it (0.262) only in the half second after a drop-out."""
    bound = PUBLISHED_ADAPTIVE_BOUNDS["position"]
    for native in (trial for trial in zhai_trials if trial.group == "slow"):
        leader = RecordedPlayer(native.resampled(100.0), CONTROL_PERIOD)
        duration = (leader.track.shape[1] - 1) * CONTROL_PERIOD
        session = play([leader, AdaptivePlayer()], duration=duration, seed=0)
        times = np.arange(session.positions.shape[1]) * CONTROL_PERIOD
        error = np.abs(session.positions[1] - session.positions[0])
        kept = (times >= TRIM) & ~near_drop_outs(native, times)
        assert error[kept].max() <= bound, native.label
