"""One live trial: advancing the avatar, recording every sample to disk, and summing up.

A `LiveTrial` is driven by the server: `update_person` stores the pointer's latest position
whenever the browser sends one, and `tick` is called once per control period T (0.03 s,
`mirror_avatar.players.CONTROL_PERIOD`). Each tick records sample k at time ``t_k = k T`` (the
person's latest position and the avatar's position at t_k), then advances the avatar with the
engine's own `Player.step` (the same code the simulations run) given the person's position at
t_k and velocity ``(x_k - x_{k-1}) / T``. The trial's time axis is therefore the avatar's
simulation clock, uniform at 1/T Hz; how late the server's ticks really were is recorded.

Recording (`TrialRecorder`): samples are appended to CSV files and flushed on every tick, and a
JSON sidecar is written when the trial starts with ``"complete": false`` and rewritten (atomically)
when it ends. A crash, a dropped connection or a closed tab therefore leaves readable files that
say they are incomplete. File formats:

- ``<stem>.csv``: the person's trial, header ``time,position`` (the project's trial exchange
  format: solo trials feed ``mirror-avatar generator fit`` directly);
- ``<stem>_session.csv`` (avatar modes): both players, header ``time,person,avatar``;
- ``<stem>.json``: participant, mode, avatar spec, seed, sampling, timestamps, completeness,
  round-trip statistics and the trial's metrics.
"""

from __future__ import annotations

import json
import logging
import math
import os
import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from importlib.metadata import version
from pathlib import Path
from typing import IO, Any

import numpy as np

from mirror_avatar.live.protocol import StartRequest
from mirror_avatar.metrics import (
    compute_circular_variance,
    compute_mean_relative_phase,
    compute_relative_phase,
    compute_rmse,
)
from mirror_avatar.players import CONTROL_PERIOD, Player
from mirror_avatar.signature import DEFAULT_BINS, compute_emd, compute_ims
from mirror_avatar.trials import DEFAULT_RATE, MIN_SAMPLES, make_trial

logger = logging.getLogger(__name__)

AvatarFactory = Callable[[str, int], Player]
"""Builds the avatar for a trial from its mode and seed."""

AVATAR_ROLES = {"avatar_leads": "leader", "avatar_follows": "follower", "joint": "joint"}
"""The avatar's role in each avatar mode (``solo`` has no avatar)."""

DEFAULT_AVATAR = "bundled:slow"
"""Avatar spec used when none is given: a virtual trainer with a signature learned from the
bundled data (**choice**: the "slow" group)."""


def make_avatar_factory(spec: str = DEFAULT_AVATAR) -> AvatarFactory:
    """Return a factory building the avatar described by ``spec`` in each mode's role.

    Parameters
    ----------
    spec
        A player spec understood by `mirror_avatar.specs.load_player` (for instance
        ``bundled:slow``).

    Returns
    -------
    callable
        ``factory(mode, seed) -> Player``: the leader virtual trainer for ``avatar_leads``, the
        follower for ``avatar_follows`` and the joint-improvisation one for ``joint``.
    """
    from mirror_avatar.hkb import FOLLOWER, JOINT, LEADER
    from mirror_avatar.specs import load_player

    roles = {"leader": LEADER, "follower": FOLLOWER, "joint": JOINT}

    def factory(mode: str, seed: int) -> Player:
        return load_player(spec, roles[AVATAR_ROLES[mode]], seed)

    return factory


def start_trial(
    out_dir: Path,
    request: StartRequest,
    avatar_factory: AvatarFactory | None,
    avatar_spec: str | None,
    period: float = CONTROL_PERIOD,
) -> LiveTrial:
    """Build the avatar, open the trial's files and return the trial, ready to tick.

    Files go to ``out_dir/<participant>/<participant>_<mode>_<UTC timestamp>.*``.

    Parameters
    ----------
    out_dir
        Root directory of the recordings.
    request
        The browser's start request; without a seed, one is drawn and recorded.
    avatar_factory, avatar_spec
        How to build the avatar in avatar modes, and the spec recorded in the sidecar.
    period
        Control period T (s).
    """
    seed = secrets.randbits(63) if request.seed is None else request.seed
    with_avatar = request.mode != "solo"
    if with_avatar and avatar_factory is None:
        raise ValueError("an avatar mode needs an avatar factory")
    avatar = avatar_factory(request.mode, seed) if with_avatar and avatar_factory else None
    if avatar is not None and not math.isclose(avatar.period, period):
        raise ValueError(f"the avatar steps every {avatar.period} s, the server every {period} s")
    if with_avatar and avatar_factory:
        _warm_up(avatar_factory(request.mode, seed))
    now = datetime.now(UTC)
    stem = f"{request.participant}_{request.mode}_{now.strftime('%Y%m%dT%H%M%S%fZ')}"
    metadata = {
        "participant": request.participant,
        "mode": request.mode,
        "avatar": avatar_spec if with_avatar else None,
        "avatar_role": AVATAR_ROLES.get(request.mode),
        "avatar_player": None if avatar is None else type(avatar).__name__,
        "seed": seed,
        "duration_requested_s": request.duration,
        "period_s": period,
        "sampling_rate_hz": 1.0 / period,
        "time_axis": "avatar control clock: sample k at k * period_s",
        "created_utc": now.isoformat(),
        "software": f"mirror-avatar {version('mirror-avatar')}",
    }
    recorder = TrialRecorder(out_dir / request.participant, stem, metadata, with_avatar)
    return LiveTrial(request.mode, request.duration, recorder, avatar, seed, period)


def _warm_up(avatar: Player) -> None:
    """Step a spare avatar once, so compiling its step happens here, not on the live clock."""
    avatar.reset(seed=0)
    avatar.step(0.0, 0.0)


@dataclass
class RoundTrips:
    """Round-trip times (ms) reported by the browser during a trial."""

    samples: list[float] = field(default_factory=list)

    def add(self, rtt_ms: float) -> None:
        """Record one round trip (ms)."""
        self.samples.append(rtt_ms)

    def summary(self) -> dict[str, float | int | None]:
        """Count, mean, median, 95th percentile and maximum (ms); None when there are none."""
        if not self.samples:
            return {"n": 0, "mean": None, "median": None, "p95": None, "max": None}
        values = np.asarray(self.samples)
        return {
            "n": int(values.size),
            "mean": float(values.mean()),
            "median": float(np.median(values)),
            "p95": float(np.percentile(values, 95)),
            "max": float(values.max()),
        }


class TrialRecorder:
    """Write a trial's samples to disk as they arrive, with a JSON sidecar.

    Parameters
    ----------
    directory
        Where the files go (created if needed).
    stem
        File name stem shared by the trial's files.
    metadata
        What the sidecar records from the start (participant, mode, seeds, sampling...).
    with_avatar
        Whether to write the two-player session CSV as well.
    """

    def __init__(
        self, directory: Path, stem: str, metadata: dict[str, Any], with_avatar: bool
    ) -> None:
        directory.mkdir(parents=True, exist_ok=True)
        self.person_path = directory / f"{stem}.csv"
        self.session_path = directory / f"{stem}_session.csv" if with_avatar else None
        self.sidecar_path = directory / f"{stem}.json"
        self.metadata = dict(metadata)
        self.metadata["files"] = {
            "person": self.person_path.name,
            "session": None if self.session_path is None else self.session_path.name,
        }
        self.metadata["complete"] = False
        self.n_samples = 0
        self._person = self._open(self.person_path, "time,position")
        self._session = (
            None
            if self.session_path is None
            else self._open(self.session_path, "time,person,avatar")
        )
        self._write_sidecar()

    @staticmethod
    def _open(path: Path, header: str) -> IO[str]:
        handle = path.open("x", encoding="utf-8", newline="\n")
        handle.write(header + "\n")
        handle.flush()
        return handle

    def append(self, t: float, person: float, avatar: float | None) -> None:
        """Append one sample (s, units, units) and flush it to the operating system."""
        self._person.write(f"{t:.4f},{person:.6f}\n")
        self._person.flush()
        if self._session is not None:
            self._session.write(f"{t:.4f},{person:.6f},{avatar:.6f}\n")
            self._session.flush()
        self.n_samples += 1

    def finish(self, complete: bool, extra: dict[str, Any]) -> dict[str, Any]:
        """Close the CSV files and rewrite the sidecar with ``complete`` and ``extra``.

        Returns
        -------
        dict
            The sidecar's contents.
        """
        self._person.close()
        if self._session is not None:
            self._session.close()
        self.metadata.update(extra)
        self.metadata["complete"] = complete
        self.metadata["n_samples"] = self.n_samples
        self._write_sidecar()
        return self.metadata

    def _write_sidecar(self) -> None:
        partial = self.sidecar_path.with_suffix(".json.part")
        partial.write_text(json.dumps(self.metadata, indent=2) + "\n", encoding="utf-8")
        os.replace(partial, self.sidecar_path)


def compute_trial_metrics(
    times: np.ndarray, person: np.ndarray, avatar: np.ndarray | None
) -> dict[str, Any]:
    """Compute the end-of-trial numbers shown to the participant and stored in the sidecar.

    Both positions are resampled to `DEFAULT_RATE` (METHODS section 2) before velocities and
    phases are computed.

    Parameters
    ----------
    times
        Sample times (s), shape (n,).
    person, avatar
        Positions (units), shape (n,) each; ``avatar`` is None in solo mode.

    Returns
    -------
    dict
        ``velocity_bins`` (bin centres, units/s), ``person_ims`` and, with an avatar,
        ``avatar_ims`` (velocity PDFs over those bins), ``person_speed`` and ``avatar_speed``
        (mean |velocity|, units/s), ``emd`` (between the two PDFs), ``rmse`` (units),
        ``circular_variance`` (the paper's CV: mean resultant length of the relative phase) and
        ``relative_phase`` (mean of person minus avatar phase, rad; positive = person ahead).
        Empty when the trial is too short to analyse.
    """
    if times.size < MIN_SAMPLES:
        return {}
    person_trial = make_trial(times, person).resampled(DEFAULT_RATE)
    person_velocity = person_trial.velocity()
    person_ims = compute_ims(person_velocity)
    result: dict[str, Any] = {
        "velocity_bins": DEFAULT_BINS.centres.tolist(),
        "person_ims": person_ims.tolist(),
        "person_speed": float(np.mean(np.abs(person_velocity))),
    }
    if avatar is None:
        return result
    avatar_trial = make_trial(times, avatar).resampled(DEFAULT_RATE)
    avatar_velocity = avatar_trial.velocity()
    avatar_ims = compute_ims(avatar_velocity)
    phase = compute_relative_phase(person_trial.positions, avatar_trial.positions)
    result["avatar_ims"] = avatar_ims.tolist()
    result["avatar_speed"] = float(np.mean(np.abs(avatar_velocity)))
    result["emd"] = compute_emd(person_ims, avatar_ims)
    result["rmse"] = float(compute_rmse(person_trial.positions, avatar_trial.positions))
    result["circular_variance"] = float(compute_circular_variance(phase))
    result["relative_phase"] = compute_mean_relative_phase(phase)
    return result


class LiveTrial:
    """A trial in progress: the person's latest position, the avatar, and the recorder.

    Parameters
    ----------
    mode
        One of `mirror_avatar.live.protocol.MODES`.
    duration
        Trial length (s).
    recorder
        Where samples go.
    avatar
        The engine player, already built; None in solo mode.
    seed
        Seed passed to ``avatar.reset``.
    period
        Control period T (s).
    """

    def __init__(
        self,
        mode: str,
        duration: float,
        recorder: TrialRecorder,
        avatar: Player | None,
        seed: int,
        period: float = CONTROL_PERIOD,
    ) -> None:
        self.mode = mode
        self.duration = duration
        self.recorder = recorder
        self.avatar = avatar
        self.period = period
        self.n_ticks = int(round(duration / period)) + 1
        self.round_trips = RoundTrips()
        self.rejected_messages = 0
        self.person_x = 0.0
        self.avatar_x: float | None = None
        self.k = 0
        self.started_utc = datetime.now(UTC).isoformat()
        self._previous_person_x: float | None = None
        self._times: list[float] = []
        self._person: list[float] = []
        self._avatar: list[float] = []
        self._lateness: list[float] = []
        self.last_heard = time.monotonic()
        if avatar is not None:
            self.avatar_x, _ = avatar.reset(seed)

    @property
    def finished(self) -> bool:
        """Whether every sample of the trial has been recorded."""
        return self.k >= self.n_ticks

    @property
    def progress(self) -> float:
        """Fraction of the trial recorded, in [0, 1]."""
        return min(1.0, self.k / self.n_ticks)

    def update_person(self, x: float, rtt_ms: float | None) -> None:
        """Store the person's latest position (units) and the browser's last round trip (ms)."""
        self.person_x = x
        self.last_heard = time.monotonic()
        if rtt_ms is not None and self.k > 0:
            self.round_trips.add(rtt_ms)

    def tick(self, lateness: float = 0.0) -> None:
        """Record sample k and advance the avatar to t_{k+1}.

        Parameters
        ----------
        lateness
            How late (s) the server called this tick compared with its schedule.
        """
        t = self.k * self.period
        x = self.person_x
        self.recorder.append(t, x, self.avatar_x)
        self._times.append(t)
        self._person.append(x)
        self._lateness.append(lateness)
        if self.avatar is not None and self.avatar_x is not None:
            self._avatar.append(self.avatar_x)
            previous = x if self._previous_person_x is None else self._previous_person_x
            self.avatar_x, _ = self.avatar.step(x, (x - previous) / self.period)
        self._previous_person_x = x
        self.k += 1

    def finish(self, complete: bool, reason: str) -> dict[str, Any]:
        """Close the files, compute the metrics and write the final sidecar.

        Parameters
        ----------
        complete
            Whether the trial ran its full duration.
        reason
            Why it ended (``"completed"``, ``"connection closed"``...).

        Returns
        -------
        dict
            The sidecar's contents, including ``metrics``.
        """
        times = np.asarray(self._times)
        avatar = np.asarray(self._avatar) if self.avatar is not None else None
        lateness = np.asarray(self._lateness) * 1000.0
        extra = {
            "started_utc": self.started_utc,
            "ended_utc": datetime.now(UTC).isoformat(),
            "end_reason": reason,
            "round_trip_ms": self.round_trips.summary(),
            "tick_lateness_ms": {
                "mean": float(lateness.mean()) if lateness.size else None,
                "max": float(lateness.max()) if lateness.size else None,
            },
            "rejected_messages": self.rejected_messages,
        }
        try:
            extra["metrics"] = compute_trial_metrics(times, np.asarray(self._person), avatar)
        except Exception as error:  # the recording is kept whatever the analysis does
            logger.exception("metrics of %s failed", self.recorder.person_path)
            extra["metrics"] = {"error": f"{type(error).__name__}: {error}"}
        return self.recorder.finish(complete, extra)
