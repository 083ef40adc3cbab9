"""Live trials: sample timing, what the avatar observes, streaming files and their sidecar."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.live.protocol import StartRequest
from mirror_avatar.live.session import (
    LiveTrial,
    RoundTrips,
    TrialRecorder,
    compute_trial_metrics,
    start_trial,
)
from mirror_avatar.players import CONTROL_PERIOD
from mirror_avatar.trials import make_trial

T = CONTROL_PERIOD


class Echo:
    """A player that moves to where its partner was: its position at t_{k+1} is the partner's
    position at t_k, its velocity the partner's velocity then."""

    period = T

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        return -0.4, 0.0

    def step(self, partner_position: float, partner_velocity: float) -> tuple[float, float]:
        return partner_position, partner_velocity


def echo_factory(mode: str, seed: int) -> Echo:
    return Echo()


def read(path: Path) -> tuple[str, np.ndarray]:
    text = path.read_text()
    return text.splitlines()[0], np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def test_samples_are_on_the_control_clock_and_the_avatar_sees_the_person(tmp_path):
    request = StartRequest(mode="avatar_follows", participant="P1", duration=0.3, seed=5)
    trial = start_trial(tmp_path, request, echo_factory, "echo")
    person = [0.0, 0.1, 0.25, 0.25, 0.2, -0.1, -0.3, -0.3, 0.0, 0.05, 0.1]
    for x in person:
        trial.update_person(x, rtt_ms=2.0)
        trial.tick()
    assert trial.finished and trial.n_ticks == 11
    header, data = read(trial.recorder.session_path)
    assert header == "time,person,avatar"
    np.testing.assert_allclose(data[:, 0], np.arange(11) * T, atol=1e-9)
    np.testing.assert_allclose(data[:, 1], person, atol=1e-6)
    # the avatar's sample k is where the person was at k - 1 (it started at -0.4)
    np.testing.assert_allclose(data[:, 2], [-0.4, *person[:-1]], atol=1e-6)
    summary = trial.finish(True, "completed")
    assert summary["complete"] and summary["n_samples"] == 11 and summary["seed"] == 5
    assert summary["round_trip_ms"]["n"] == 10  # the first report precedes any sample
    assert summary["avatar_role"] == "follower" and summary["avatar"] == "echo"
    assert json.loads(trial.recorder.sidecar_path.read_text()) == summary


def test_the_avatar_is_given_the_persons_finite_difference_velocity(tmp_path):
    watchers = []

    class Watcher(Echo):
        def __init__(self) -> None:
            self.seen: list[float] = []
            watchers.append(self)

        def step(self, partner_position: float, partner_velocity: float) -> tuple[float, float]:
            self.seen.append(partner_velocity)
            return super().step(partner_position, partner_velocity)

    request = StartRequest(mode="joint", participant="P1", duration=0.09)
    trial = start_trial(tmp_path, request, lambda mode, seed: Watcher(), "watcher")
    live, spare = watchers
    assert trial.avatar is live and spare.seen == [0.0]  # the spare one compiled the step
    for x in (0.1, 0.13, 0.19, 0.19):
        trial.update_person(x, None)
        trial.tick()
    np.testing.assert_allclose(live.seen, [0.0, 0.03 / T, 0.06 / T, 0.0])
    assert 0 <= trial.finish(True, "completed")["seed"] < 2**63


def test_files_are_readable_while_the_trial_runs(tmp_path):
    request = StartRequest(mode="solo", participant="P2", duration=10.0)
    trial = start_trial(tmp_path, request, None, None)
    assert trial.recorder.session_path is None and trial.avatar_x is None
    sidecar = json.loads(trial.recorder.sidecar_path.read_text())
    assert sidecar["complete"] is False and sidecar["mode"] == "solo"
    assert sidecar["sampling_rate_hz"] == pytest.approx(1 / T)
    for k in range(25):
        trial.update_person(0.2 * math.sin(k / 5), None)
        trial.tick()
    header, data = read(trial.recorder.person_path)  # nothing closed or finished yet
    assert header == "time,position" and data.shape == (25, 2)
    make_trial(data[:, 0], data[:, 1])  # a valid trial as it stands
    summary = trial.finish(False, "connection closed")
    assert not summary["complete"] and summary["end_reason"] == "connection closed"
    assert summary["metrics"]["person_ims"] and "rmse" not in summary["metrics"]


def test_recorder_never_overwrites(tmp_path):
    TrialRecorder(tmp_path, "same", {}, with_avatar=False).finish(True, {})
    with pytest.raises(FileExistsError):
        TrialRecorder(tmp_path, "same", {}, with_avatar=False)


def test_too_short_trials_have_no_metrics(tmp_path):
    trial = LiveTrial("solo", 1.0, TrialRecorder(tmp_path, "s", {}, False), None, 0)
    trial.tick()
    summary = trial.finish(False, "stopped by the participant")
    assert summary["metrics"] == {} and summary["n_samples"] == 1


def test_round_trip_summary():
    trips = RoundTrips()
    assert trips.summary()["n"] == 0 and trips.summary()["median"] is None
    for value in range(1, 101):
        trips.add(float(value))
    summary = trips.summary()
    assert summary["n"] == 100 and summary["mean"] == 50.5 and summary["median"] == 50.5
    assert summary["max"] == 100.0 and summary["p95"] == pytest.approx(95.05)


def test_solo_metrics_of_a_sine():
    times = np.arange(0, 20.0 + T / 2, T)
    person = 0.3 * np.sin(2 * np.pi * 0.5 * times)
    metrics = compute_trial_metrics(times, person, None)
    # mean |v| of A sin(2 pi f t) over whole periods is 4 A f
    assert metrics["person_speed"] == pytest.approx(4 * 0.3 * 0.5, rel=0.01)
    assert sum(metrics["person_ims"]) == pytest.approx(1.0)
    assert len(metrics["velocity_bins"]) == len(metrics["person_ims"])
