"""One live trial: the person and the avatar on the engine's clock, every sample recorded to disk.

A `LiveTrial` is the one-participant case of the real-time core's clocked trial
(`mirror_avatar.realtime.trial.ClockedTrial`), driven by the server: `update_person` stores the
pointer's latest position whenever the browser sends one, and the clock
(`mirror_avatar.realtime.clock.run_on_clock`) ticks it once per control period T (0.03 s). The
person is player 0, a `mirror_avatar.realtime.inputs.HumanPlayer` whose sample k is the latest
position received when tick k runs (velocity ``(x_k - x_{k-1}) / T``), and the avatar, if any,
is player 1, advanced by its own ``step`` exactly as in simulations. The time axis is therefore
the engine's clock, uniform at 1/T Hz; when each sample was really taken, and how late its tick
was, is recorded beside it.

Recording, as each sample is taken (flushed): ``<stem>_session.csv``, the session in the
toolkit's session format (`mirror_avatar.sessions.writer.SessionWriter`, read back by
`mirror_avatar.sessions.loading.load_session`, so ``mirror-avatar evaluate`` works on it) with its
sidecar ``<stem>_session.json`` (participant, mode, avatar spec, seed, timestamps, completeness,
round trips, lateness and, at the end, the metrics), ``<stem>_inputs.csv`` (each sample's true time,
lateness and input, `mirror_avatar.realtime.trial.TickLog`) and ``<stem>.csv``, the person's trial
alone
(``time,position``, the trial exchange format: solo trials feed ``mirror-avatar generator fit``
directly). The sidecar
says ``"complete": false`` until the trial ends well, so a crash, a dropped connection or a closed
tab leaves readable files that say they are incomplete.
"""

from __future__ import annotations

import logging
import math
import secrets
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar import __version__
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.files.atomic import LineFile
from mirror_avatar.files.trials import MIN_SAMPLES
from mirror_avatar.live.messages import StartRequest
from mirror_avatar.metrics import compute_relative_phase, session_metrics
from mirror_avatar.players.base import Observation, Player
from mirror_avatar.realtime.inputs import BrowserInput, HumanPlayer
from mirror_avatar.realtime.latency import RoundTrips
from mirror_avatar.realtime.trial import ClockedTrial
from mirror_avatar.sessions.graphs import complete_graph
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.signature import DEFAULT_BINS, compute_ims

logger = logging.getLogger(__name__)

AvatarFactory = Callable[[str], Player]
"""Builds the avatar for a trial from its mode."""

AVATAR_ROLES = {"avatar_leads": "leader", "avatar_follows": "follower", "joint": "joint"}
"""The avatar's role in each avatar mode (``solo`` has no avatar)."""

PERSON_ROLES = {"solo": "solo", "avatar_leads": "follower", "avatar_follows": "leader"}
"""The person's role in each mode (``joint`` otherwise)."""

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
        ``factory(mode) -> Player``: the leader virtual trainer for ``avatar_leads``, the
        follower for ``avatar_follows`` and the joint-improvisation one for ``joint``.
    """
    from mirror_avatar.specs import load_player

    def factory(mode: str) -> Player:
        return load_player(spec, AVATAR_ROLES[mode])

    return factory


class PersonTrialWriter:
    """Append the person's samples (``time,position``) to a CSV trial file, each line flushed.

    Used as an engine sink: it reads the time and player 0's position of each row.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self._file = LineFile(path, "time,position")

    def __call__(self, row: NDArray[np.float64]) -> None:
        """Write the sample's time and the person's position."""
        self._file.write(f"{float(row[0])!r},{float(row[1])!r}")

    def close(self) -> None:
        """Close the file."""
        self._file.close()


def start_trial(
    out_dir: Path,
    request: StartRequest,
    avatar_factory: AvatarFactory | None,
    avatar_spec: str | None,
    period: float = CONTROL_PERIOD,
) -> LiveTrial:
    """Build the avatar, open the trial's files and return the trial, ready to tick.

    Files go to ``out_dir/<participant>/<participant>_<mode>_<UTC timestamp>*``.

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
    avatar = avatar_factory(request.mode) if with_avatar and avatar_factory else None
    if avatar is not None and not math.isclose(avatar.period, period):
        raise ValueError(f"the avatar steps every {avatar.period} s, the server every {period} s")
    if with_avatar and avatar_factory:
        _warm_up(avatar_factory(request.mode))
    now = datetime.now(UTC)
    stem = f"{request.participant}_{request.mode}_{now.strftime('%Y%m%dT%H%M%S%fZ')}"
    directory = out_dir / request.participant
    directory.mkdir(parents=True, exist_ok=True)
    metadata = {
        "participant": request.participant,
        "mode": request.mode,
        "avatar": avatar_spec if with_avatar else None,
        "avatar_role": AVATAR_ROLES.get(request.mode),
        "avatar_player": None if avatar is None else type(avatar).__name__,
        "avatar_plays": None if avatar is None else avatar.label,
        "seed": seed,
        "duration_requested_s": request.duration,
        "period_s": period,
        "sampling_rate_hz": 1.0 / period,
        "created_utc": now.isoformat(),
        "software": f"mirror-avatar {__version__}",
        "files": {"person": f"{stem}.csv", "session": f"{stem}_session.csv"},
    }
    return LiveTrial(request, directory / stem, metadata, avatar, seed, period)


def _warm_up(avatar: Player) -> None:
    """Step a spare avatar once, so compiling its step happens here, not on the live clock."""
    avatar.reset(seed=0)
    avatar.step(Observation.of_partner(0, 0.0, 0.0, 0.0))


PLOT_POINTS = 600
"""Most samples per series the results screen draws (longer trials are decimated)."""


def compute_trial_traces(session: Session, max_points: int = PLOT_POINTS) -> dict[str, Any]:
    """Decimated series for the results screen's figures (not stored: the session file is).

    Returns
    -------
    dict
        ``times`` (s) and ``positions`` (one list per player, units), every ``step``-th
        sample so that at most ``max_points`` remain, and with an avatar ``relative_phase``
        (person minus avatar, rad) when both moved; empty when the trial is too short.
    """
    if session.n_samples < MIN_SAMPLES:
        return {}
    step = max(1, math.ceil(session.n_samples / max_points))
    traces: dict[str, Any] = {
        "times": session.times[::step].tolist(),
        "positions": [x[::step].tolist() for x in session.positions],
    }
    x = session.positions
    if session.n_players == 2 and np.ptp(x[0]) > 0 and np.ptp(x[1]) > 0:
        traces["relative_phase"] = compute_relative_phase(x[0], x[1])[::step].tolist()
    return traces


def compute_trial_metrics(session: Session) -> dict[str, Any]:
    """Compute the end-of-trial numbers shown to the participant and stored in the sidecar.

    Parameters
    ----------
    session
        The trial's session: player 0 the person, player 1 the avatar (if any).

    Returns
    -------
    dict
        `mirror_avatar.metrics.session_metrics` of the session (with an avatar: ``rmse``,
        ``phase_locking`` (the paper's CV), ``mean_relative_phase`` person minus avatar, positive
        = person ahead, ``emd_players``...), plus for the plot ``velocity_bins`` (bin centres,
        units/s), ``person_ims`` / ``avatar_ims`` (velocity PDFs) and ``person_speed`` /
        ``avatar_speed`` (mean |velocity|, units/s). Empty when the trial is too short.
    """
    if session.n_samples < MIN_SAMPLES:
        return {}
    metrics = session_metrics(session)
    metrics["velocity_bins"] = DEFAULT_BINS.centres.tolist()
    for name, velocity in zip(("person", "avatar"), session.velocities, strict=False):
        metrics[f"{name}_ims"] = compute_ims(velocity).tolist()
        metrics[f"{name}_speed"] = float(np.mean(np.abs(velocity)))
    return metrics


class LiveTrial(ClockedTrial):
    """A trial in progress: the person at the browser and the avatar, on the real-time core.

    Parameters
    ----------
    request
        The browser's start request (mode, participant, duration).
    stem
        Path of the trial's files without suffix.
    metadata
        What the sidecar records from the start.
    avatar
        The engine player, already built; None in solo mode.
    seed
        Seed of the session (the avatar's seed is spawned from it).
    period
        Control period T (s).
    """

    def __init__(
        self,
        request: StartRequest,
        stem: Path,
        metadata: dict[str, Any],
        avatar: Player | None,
        seed: int,
        period: float = CONTROL_PERIOD,
    ) -> None:
        self.mode = request.mode
        self.duration = request.duration
        self.avatar = avatar
        self.round_trips = RoundTrips()
        self.rejected_messages = 0
        self.started_utc = datetime.now(UTC).isoformat()
        self.source = BrowserInput()
        self.person = HumanPlayer(self.source, f"person {request.participant}", period)
        players = [self.person] if avatar is None else [self.person, avatar]
        roles = [PERSON_ROLES.get(self.mode, "joint")]
        roles += [] if avatar is None else [AVATAR_ROLES[self.mode]]
        labels = [self.person.label] + ([] if avatar is None else ["avatar"])
        self.person_path = stem.with_name(stem.name + ".csv")
        self.person_writer = PersonTrialWriter(self.person_path)
        self.last_heard = time.monotonic()
        self._seq = 0
        super().__init__(
            players,
            labels,
            roles,
            complete_graph(len(players)),
            int(round(request.duration / period)) + 1,
            seed,
            stem,
            metadata,
            time.monotonic,
            [self.person_writer],
        )

    @property
    def avatar_x(self) -> float | None:
        """The avatar's position (units) at the engine's current sample; None in solo mode."""
        if self.avatar is None:
            return None
        return self.engine.state(1)[0]

    def update_person(self, x: float, rtt_ms: float | None, seq: int | None = None) -> None:
        """Store the person's latest position (units) and the browser's last round trip (ms).

        ``seq`` numbers the page's positions; without it they are numbered in arrival order.
        """
        self._seq = self._seq + 1 if seq is None else seq
        self.source.put(x, self._seq)
        self.last_heard = time.monotonic()
        if rtt_ms is not None and self.k > 0:
            self.round_trips.add(rtt_ms)

    def close_files(self) -> None:
        """Close the person's trial file and the tick log."""
        super().close_files()
        self.person_writer.close()

    def analyse(self, session: Session) -> dict[str, Any]:
        """Return the live trial's end numbers: round trips, rejected messages and metrics."""
        return {
            "started_utc": self.started_utc,
            "round_trip_ms": self.round_trips.summary(),
            "rejected_messages": self.rejected_messages,
            "metrics": compute_trial_metrics(session),
        }

    def finish(self, complete: bool, reason: str) -> dict[str, Any]:
        """Close the files, compute the metrics and write the final sidecar.

        Returns
        -------
        dict
            `ClockedTrial.finish`'s summary; the figures' ``traces`` (`compute_trial_traces`)
            are returned, not stored in the sidecar.
        """
        summary = super().finish(complete, reason)
        try:
            traces = compute_trial_traces(self.engine.session())
        except Exception:  # the recording is kept whatever the analysis does
            logger.exception("traces of %s failed", self.session_path)
            traces = {}
        return summary | {"traces": traces}
