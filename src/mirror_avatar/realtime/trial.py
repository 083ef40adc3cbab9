"""A clocked trial: players on the engine's step loop, every sample on disk with its true time.

A `ClockedTrial` is one session of the engine's step loop (`mirror_avatar.engine.loop.Engine`)
driven by a real-time clock (`mirror_avatar.realtime.clock.run_on_clock`): its people are
`mirror_avatar.realtime.inputs.HumanPlayer` s reading their input devices, its avatars the
engine's own players, advanced by their ``step`` exactly as in simulations. Sample k belongs to
the time ``k * T`` of the engine's clock; when it was really taken is recorded beside it.

Files, flushed line by line as each sample is taken:

- ``<stem>_session.csv`` + ``.json``: the session (`mirror_avatar.sessions.writer.SessionWriter`),
  read by ``mirror-avatar evaluate``; the sidecar says ``"complete": false`` until the trial ends
  well, and at the end holds the lateness and liveness summaries (`ClockedTrial.finish`);
- ``<stem>_inputs.csv`` (`TickLog`): per sample, the clock time at which it was really taken
  (``clock_s``), how late its tick was against the schedule (``late_ms``), how long the players'
  step took (``step_ms``, the file writes excluded) and, per person, the sequence number of the
  device sample used, its age (ms), whether it was held and whether the input was live; a
  player with columns of its own (`LoggedPlayer`: an avatar stepped in a page) adds them.

A tick that cannot write (a full disk, a file-size limit) raises `OSError` naming the file
(`write_failure` makes it the trial's end reason); the lines written stay readable and `finish`
still returns the trial's summary and rewrites the sidecar if it can. A tick whose player diverges
(its position or velocity no longer finite) raises `mirror_avatar.players.base.PlayerDiverged`
after recording it in the sidecar (``"diverged"``: sample, player, label, message): the samples
before it stay, all finite, and the clock ends the trial with the message as its reason.
"""

from __future__ import annotations

import errno
import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.engine.loop import Engine, Sink
from mirror_avatar.files.atomic import LineFile
from mirror_avatar.files.trial_record import InputEventRecord
from mirror_avatar.players.base import Player, PlayerDiverged
from mirror_avatar.realtime.inputs import HumanPlayer
from mirror_avatar.realtime.latency import summarise
from mirror_avatar.sessions.graphs import Graph
from mirror_avatar.sessions.session import Session
from mirror_avatar.sessions.writer import SessionWriter

logger = logging.getLogger(__name__)

Array = NDArray[np.float64]
Clock = Callable[[], float]
"""A clock (s) stamping each sample, as recorded in ``clock_s``."""

DISK_FULL = "disk full"
"""How the end reason of a trial whose recording ran out of room (a full disk, a quota, a
file-size limit) begins."""


def write_failure(error: OSError) -> str:
    """Say why a recording could not be written, naming the file, in the system's words.

    Out of room (a full disk, a quota, a file-size limit) it begins with `DISK_FULL`:
    ``disk full: cannot write FILE (File too large)``.
    """
    what = "the recording" if error.filename is None else str(error.filename)
    words = error.strerror or str(error)
    if error.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
        return f"{DISK_FULL}: cannot write {what} ({words})"
    return f"cannot write {what}: {words}"


@runtime_checkable
class LoggedPlayer(Protocol):
    """A player that writes columns of its own to ``<stem>_inputs.csv`` (an avatar in a page)."""

    def tick_columns(self) -> list[str]:
        """Return the names of its columns."""
        ...

    def tick_fields(self) -> list[str]:
        """Return its fields of the sample just taken."""
        ...


class TickLog:
    """Engine sink writing ``<stem>_inputs.csv``: each sample's true time, lateness and inputs.

    Parameters
    ----------
    path
        The file; it must not exist yet.
    people
        The people, in player order.
    clock
        Stamps each sample (s).
    logged
        The other players with columns of their own (`LoggedPlayer`), after the people's.

    Attributes
    ----------
    first_stamp, last_stamp
        Clock times of the first and the latest sample written (NaN before any).
    first_utc
        When the first sample was written (UTC, ISO 8601; None before any).
    lateness, step_time
        How late the tick being taken is (s) and how long its step took (s): set by the trial
        before the row is written.
    """

    def __init__(
        self,
        path: Path,
        people: Sequence[HumanPlayer],
        clock: Clock,
        logged: Sequence[LoggedPlayer] = (),
    ) -> None:
        self.people = list(people)
        self.logged = list(logged)
        self.clock = clock
        self.first_stamp = self.last_stamp = math.nan
        self.first_utc: str | None = None
        self.lateness = self.step_time = 0.0
        columns = ["time", "clock_s", "late_ms", "step_ms"]
        for person in self.people:
            label = person.label
            columns += [f"seq_{label}", f"age_ms_{label}", f"held_{label}", f"alive_{label}"]
        for player in self.logged:
            columns += player.tick_columns()
        self._file = LineFile(path, ",".join(columns))

    def __call__(self, row: Array) -> None:
        """Write the sample's time, clock time, lateness, step time and inputs."""
        stamp = self.clock()
        if math.isnan(self.first_stamp):
            self.first_stamp = stamp
            self.first_utc = datetime.now(UTC).isoformat()
        self.last_stamp = stamp
        fields = [repr(float(row[0])), repr(stamp)]
        fields += [f"{self.lateness * 1000.0:.3f}", f"{self.step_time * 1000.0:.3f}"]
        for person in self.people:
            tick = person.last_input
            age = "" if math.isnan(tick.age) else f"{tick.age * 1000.0:.3f}"
            fields += [str(tick.seq), age, str(int(tick.held)), str(int(tick.alive))]
        for player in self.logged:
            fields += player.tick_fields()
        self._file.write(",".join(fields))

    def close(self) -> None:
        """Close the file (what could not be flushed on a full disk is lost, the rest stays)."""
        self._file.close()


def lateness_summary(lateness_s: Sequence[float], period: float) -> dict[str, Any]:
    """Summarise the ticks' lateness: count, mean, median, p95, max (ms), ticks over a period."""
    values = np.asarray(lateness_s, dtype=np.float64)
    over = int(np.count_nonzero(values > period))
    return summarise((values * 1000.0).tolist()) | {"over_period": over}


class ClockedTrial:
    """Players on the engine's clock, recorded sample by sample (see the module docstring).

    Parameters
    ----------
    players
        The engine's players, in order; the people among them are `HumanPlayer` s.
    labels, roles, graph
        As in `mirror_avatar.sessions.session.Session`.
    n_ticks
        Samples the whole trial takes.
    seed
        Seed of the engine's session.
    stem
        Path of the trial's files without suffix.
    metadata
        What the sidecar records from the start.
    clock
        Stamps each sample (s).
    sinks
        Further engine sinks (a person's own trial file, an LSL outlet...), after the files.

    Attributes
    ----------
    step_time
        How long the latest tick's players took to step (s, in the ticking thread, the file
        writes excluded): the players' own speed, whatever the event loop was doing.
    events
        What happened to the inputs, in order: ``{"sample", "label", "event", "seq"}`` with
        event ``"lost"`` or ``"live"`` (see `mirror_avatar.realtime.inputs`) and the sequence
        number of the input's newest sample then (-1: it had delivered none).
    """

    def __init__(
        self,
        players: Sequence[Player],
        labels: Sequence[str],
        roles: Sequence[str],
        graph: Graph,
        n_ticks: int,
        seed: int,
        stem: Path,
        metadata: dict[str, Any],
        clock: Clock,
        sinks: Sequence[Sink] = (),
    ) -> None:
        self.players = list(players)
        self.people = [p for p in self.players if isinstance(p, HumanPlayer)]
        self.period = self.players[0].period
        self.n_ticks = n_ticks
        self.session_path = stem.with_name(stem.name + "_session.csv")
        self.inputs_path = stem.with_name(stem.name + "_inputs.csv")
        files = dict(metadata.get("files", {})) | {
            "session": self.session_path.name,
            "inputs": self.inputs_path.name,
        }
        metadata = metadata | {
            "time_axis": "engine clock: sample k at k * period_s; when each was taken: inputs",
            "clock": getattr(clock, "__qualname__", str(clock)),
            "files": files,
        }
        self.writer = SessionWriter(self.session_path, labels, roles, graph, self.period, metadata)
        try:
            logged = [p for p in self.players if isinstance(p, LoggedPlayer)]
            self.tick_log = TickLog(self.inputs_path, self.people, clock, logged)
        except OSError:
            self.writer.close(False, {"end_reason": "the trial's files could not be opened"})
            raise
        self.step_time = 0.0
        self.events: list[dict[str, Any]] = []
        self._tick_began = self._sink_time = 0.0
        self._lateness: list[float] = []
        self._alive = {person.label: True for person in self.people}
        own: list[Sink] = [self.writer.append, self.tick_log]
        timed = [self._timed(sink) for sink in (*own, *sinks)]
        self.diverged: dict[str, Any] | None = None
        self.engine = Engine(self.players, graph, roles, labels, timed)
        self._lock = threading.Lock()
        self._closed = False
        try:
            self.engine.reset(seed, n_ticks)
        except PlayerDiverged as error:
            self.diverged = error.describe()
            self.finish(False, str(error))
            raise

    def _timed(self, sink: Sink) -> Sink:
        def timed(row: Array) -> None:
            began = time.perf_counter()
            if sink is self.tick_log:
                self.tick_log.step_time = self.step_time_so_far(began)
            sink(row)
            self._sink_time += time.perf_counter() - began

        return timed

    def step_time_so_far(self, now: float) -> float:
        """Return the tick's stepping time until ``now`` (s, `time.perf_counter`), sinks out."""
        return max(0.0, now - self._tick_began - self._sink_time)

    @property
    def k(self) -> int:
        """Samples recorded so far."""
        return self.writer.n_samples

    @property
    def finished(self) -> bool:
        """Whether every sample of the trial has been recorded."""
        return self.k >= self.n_ticks

    @property
    def progress(self) -> float:
        """Fraction of the trial recorded, in [0, 1]."""
        return min(1.0, self.k / self.n_ticks)

    def held(self) -> dict[str, int]:
        """Ticks at which each person's position was held (no new sample), by label."""
        return {person.label: person.held for person in self.people}

    def lost(self) -> dict[str, int]:
        """Ticks at which each person's input was lost, by label."""
        return {person.label: person.lost for person in self.people}

    def alive(self) -> dict[str, bool]:
        """Whether each person's input was live at the latest tick, by label."""
        return dict(self._alive)

    def tick(self, lateness: float = 0.0) -> None:
        """Take sample k and advance the players to t_{k+1} (the last sample: take it only).

        Safe from a worker thread: a tick and `finish` never overlap; after `finish` it does
        nothing.

        Parameters
        ----------
        lateness
            How late (s) the clock called this tick compared with its schedule.

        Raises
        ------
        OSError
            When a sample cannot be written (`write_failure` says why).
        PlayerDiverged
            When a player's state at k + 1 is not finite (recorded as ``diverged``).
        """
        with self._lock:
            if self._closed or self.finished:
                return
            self._lateness.append(lateness)
            self.tick_log.lateness = lateness
            self._tick_began, self._sink_time = time.perf_counter(), 0.0
            k = self.k
            if k < self.n_ticks - 1:
                self.before_step(k)
                try:
                    self.engine.step()
                except PlayerDiverged as error:
                    self.diverged = error.describe()
                    self.writer.annotate({"diverged": self.diverged})
                    raise
            else:
                self.engine.finish()
            self.step_time = self.step_time_so_far(time.perf_counter())
            self._note_liveness(k)

    def before_step(self, k: int) -> None:
        """Do what must happen at sample k before the players step to k + 1 (subclasses).

        Called in the ticking thread, within the tick.
        """

    @property
    def max_lateness(self) -> float:
        """The largest lateness of the trial's ticks so far (s)."""
        return max(self._lateness, default=0.0)

    def _note_liveness(self, k: int) -> None:
        """Record each input that was lost or came back at sample k (events, sidecar now)."""
        changed = False
        for person in self.people:
            tick = person.last_input
            if tick.alive != self._alive[person.label]:
                self._alive[person.label] = tick.alive
                event = "live" if tick.alive else "lost"
                seq = tick.seq if tick.seq >= 0 else None  # a page that has sent nothing
                self.events.append(InputEventRecord(k, person.label, event, seq).to_json())
                changed = True
        if changed:
            self.writer.annotate({"input_events": list(self.events), "lost": self.lost()})

    def close_files(self) -> None:
        """Close the files other than the session's (subclasses add theirs)."""
        self.tick_log.close()

    def analyse(self, session: Session) -> dict[str, Any]:
        """Return what the sidecar records at the end besides timing (subclasses: metrics)."""
        return {}

    def finish(self, complete: bool, reason: str) -> dict[str, Any]:
        """Close the files, summarise the clock and the inputs, analyse and write the sidecar.

        Returns
        -------
        dict
            The sidecar's metadata with ``n_samples``, ``started_utc`` (when the first sample
            was taken; None if none was), ``ended_utc`` and ``end_reason``; ``tick_lateness_ms``
            (`lateness_summary`), ``held``, ``lost`` and ``input_events``; ``diverged`` when a
            player diverged (`tick`); and what `analyse`
            adds (``{"error": ...}`` as ``metrics`` if it fails: the recording is kept). On a
            full disk the sidecar keeps what it said before (``"complete": false``).
        """
        with self._lock:
            self._closed = True
        self.close_files()
        extra: dict[str, Any] = {
            "started_utc": self.tick_log.first_utc,
            "ended_utc": datetime.now(UTC).isoformat(),
            "end_reason": reason,
            "tick_lateness_ms": lateness_summary(self._lateness, self.period),
            "held": self.held(),
            "lost": self.lost(),
            "input_events": list(self.events),
        }
        if self.diverged is not None:
            extra["diverged"] = self.diverged
        try:
            extra |= self.analyse(self.engine.session())
        except Exception as error:  # the recording is kept whatever the analysis does
            logger.exception("analysis of %s failed", self.session_path)
            extra["metrics"] = {"error": f"{type(error).__name__}: {error}"}
        try:
            sidecar = self.writer.close(complete, extra)
        except OSError as error:
            logger.warning("the sidecar of %s was not rewritten: %s", self.session_path, error)
            sidecar = self.writer.sidecar
            sidecar["metadata"] |= extra | {"complete": complete}
            sidecar["n_samples"] = self.writer.n_samples
        return sidecar["metadata"] | {"n_samples": sidecar["n_samples"]}
