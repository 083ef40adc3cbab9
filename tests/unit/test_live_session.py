"""Live trials: sample timing, what the avatar observes, streaming files and their sidecar."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.files.trials import make_trial
from mirror_avatar.live.messages import StartRequest
from mirror_avatar.live.session import (
    compute_trial_metrics,
    compute_trial_traces,
    start_trial,
)
from mirror_avatar.metrics import session_metrics
from mirror_avatar.players import Player
from mirror_avatar.realtime.latency import RoundTrips
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.sessions.session import Session

T = CONTROL_PERIOD


class Echo(Player):
    """Moves to where its partner was: its state at t_{k+1} is the partner's state at t_k."""

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        return -0.4, 0.0

    def step(self, observation) -> tuple[float, float]:
        return float(observation.positions[0]), float(observation.velocities[0])


def echo_factory(mode: str) -> Echo:
    return Echo()


def read(path: Path) -> tuple[str, np.ndarray]:
    text = path.read_text()
    return text.splitlines()[0], np.genfromtxt(path, delimiter=",", skip_header=1, ndmin=2)


def sidecar(trial) -> dict:
    return json.loads(trial.session_path.with_suffix(".json").read_text())


def test_samples_are_on_the_control_clock_and_the_avatar_sees_the_person(tmp_path):
    request = StartRequest(mode="avatar_follows", participant="P1", duration=0.3, seed=5)
    trial = start_trial(tmp_path, request, echo_factory, "echo")
    person = [0.0, 0.1, 0.25, 0.25, 0.2, -0.1, -0.3, -0.3, 0.0, 0.05, 0.1]
    for x in person:
        trial.update_person(x, rtt_ms=2.0)
        trial.tick()
    assert trial.finished and trial.n_ticks == 11
    session = load_session(trial.session_path)
    np.testing.assert_allclose(session.times, np.arange(11) * T, atol=1e-12)
    np.testing.assert_array_equal(session.positions[0], person)
    # the avatar's sample k is where the person was at k - 1 (it started at -0.4)
    np.testing.assert_array_equal(session.positions[1], [-0.4, *person[:-1]])
    summary = trial.finish(True, "completed")
    assert summary["complete"] and summary["n_samples"] == 11 and summary["seed"] == 5
    assert summary["round_trip_ms"]["n"] == 10  # the first report precedes any sample
    assert summary["avatar_role"] == "follower" and summary["avatar"] == "echo"
    assert sidecar(trial)["metadata"] | {"n_samples": 11, "traces": {}} == summary  # too short
    assert load_session(trial.session_path).roles == ("leader", "follower")


def test_the_avatar_is_given_the_persons_finite_difference_velocity(tmp_path):
    watchers = []

    class Watcher(Echo):
        def __init__(self) -> None:
            self.seen: list[float] = []
            watchers.append(self)

        def step(self, observation) -> tuple[float, float]:
            self.seen.append(float(observation.velocities[0]))
            return super().step(observation)

    request = StartRequest(mode="joint", participant="P1", duration=0.09)
    trial = start_trial(tmp_path, request, lambda mode: Watcher(), "watcher")
    live, spare = watchers
    assert trial.avatar is live and spare.seen == [0.0]  # the spare one compiled the step
    for x in (0.1, 0.13, 0.19, 0.19):
        trial.update_person(x, None)
        trial.tick()
    np.testing.assert_allclose(live.seen, [0.0, 0.03 / T, 0.06 / T])
    summary = trial.finish(True, "completed")
    assert 0 <= summary["seed"] < 2**63
    np.testing.assert_allclose(load_session(trial.session_path).velocities[0, 1:], [1, 2, 0])


def test_files_are_readable_while_the_trial_runs(tmp_path):
    request = StartRequest(mode="solo", participant="P2", duration=10.0)
    trial = start_trial(tmp_path, request, None, None)
    assert trial.avatar_x is None
    assert sidecar(trial)["metadata"]["complete"] is False
    assert sidecar(trial)["metadata"]["mode"] == "solo"
    assert sidecar(trial)["metadata"]["sampling_rate_hz"] == pytest.approx(1 / T)
    for k in range(25):
        trial.update_person(0.2 * math.sin(k / 5), None)
        trial.tick()
    header, data = read(trial.person_path)  # nothing closed or finished yet
    assert header == "time,position" and data.shape == (25, 2)
    make_trial(data[:, 0], data[:, 1])  # a valid trial as it stands
    running = load_session(trial.session_path)
    assert running.n_players == 1 and running.n_samples == 25
    summary = trial.finish(False, "connection closed")
    assert not summary["complete"] and summary["end_reason"] == "connection closed"
    assert summary["metrics"]["person_ims"] and "rmse" not in summary["metrics"]


def test_a_live_recording_is_evaluated_like_any_session(tmp_path):
    request = StartRequest(mode="avatar_leads", participant="P3", duration=3.0, seed=1)
    trial = start_trial(tmp_path, request, echo_factory, "echo")
    while not trial.finished:
        trial.update_person(0.3 * math.sin(trial.k * T * 2.0), None)
        trial.tick()
    summary = trial.finish(True, "completed")
    session = load_session(trial.session_path)
    assert session.n_samples == 101 and session.metadata["complete"]
    metrics = session_metrics(session)
    for key in ("rmse", "phase_locking", "mean_relative_phase", "time_lag"):
        assert metrics[key] == summary["metrics"][key]
    assert metrics["mean_relative_phase"] > 0  # the person is ahead of the echo


def test_trials_never_overwrite(tmp_path):
    request = StartRequest(mode="solo", participant="P4", duration=1.0)
    first = start_trial(tmp_path, request, None, None)
    first.finish(True, "completed")
    with pytest.raises(FileExistsError):
        type(first)(request, first.session_path.with_name(first.person_path.stem),
                    {}, None, 0)  # fmt: skip


def test_too_short_trials_have_no_metrics(tmp_path):
    trial = start_trial(tmp_path, StartRequest("solo", "P5", 1.0), None, None)
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
    velocity = 0.3 * np.pi * np.cos(2 * np.pi * 0.5 * times)
    nan = np.full((1, times.size), np.nan)
    metrics = compute_trial_metrics(Session(times, person[None], velocity[None], nan, nan))
    # mean |v| of A sin(2 pi f t) over whole periods is 4 A f
    assert metrics["person_speed"] == pytest.approx(4 * 0.3 * 0.5, rel=0.01)
    assert sum(metrics["person_ims"]) == pytest.approx(1.0)
    assert len(metrics["velocity_bins"]) == len(metrics["person_ims"])


def test_traces_are_decimated_for_the_results_screen():
    t = np.arange(1500) * T
    x = np.vstack([0.3 * np.sin(t), 0.3 * np.sin(t - 0.2)])
    nan = np.full_like(x, np.nan)
    traces = compute_trial_traces(Session(t, x, np.gradient(x, T, axis=1), nan, nan))
    assert len(traces["times"]) == 500 and traces["times"][1] == pytest.approx(3 * T)
    np.testing.assert_array_equal(traces["positions"], x[:, ::3])
    assert np.median(traces["relative_phase"]) == pytest.approx(0.2, abs=0.01)  # person ahead
    still = np.vstack([x[0], np.zeros_like(t)])
    assert "relative_phase" not in compute_trial_traces(Session(t, still, still, nan, nan))
