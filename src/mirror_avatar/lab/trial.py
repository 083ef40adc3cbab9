"""One lab trial: every player on the server's clock, every sample on disk as it is taken.

A `LabTrial` is a session of the engine's step loop (`mirror_avatar.engine.loop.Engine`) whose
people are `mirror_avatar.lab.inputs.HumanPlayer` s reading their devices and whose avatars are
the engine's own players, advanced by their ``step`` exactly as in simulations. The server calls
`LabTrial.tick` once per control period T; sample k is the time ``k * T`` of the engine's clock.

Files, in the session's folder, flushed line by line (METHODS section 9):

- ``trial-NN_session.csv`` + ``.json``: the N-player session (`mirror_avatar.session`), read by
  ``mirror-avatar evaluate``; the sidecar's ``metadata["lab"]`` names the session, the trial,
  the condition and every slot, and ``dropped`` / ``held`` are updated as they happen;
- ``trial-NN_inputs.csv``: per sample, the clock time at which it was taken (``clock_s``: the
  LSL clock when pylsl is installed, so the samples line up with EEG recorded through LSL;
  otherwise the monotonic clock) and, per person, the sequence number of the device sample
  used, its age (ms) and whether it was held (no new sample since the previous tick: the last
  position is kept, never extrapolated).

Whatever happens - a participant drops, the server is killed - the lines written stay
readable; the sidecar says ``"complete": false`` until the trial ends well.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable, Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar import __version__
from mirror_avatar.engine.loop import Engine, Sink, count_samples
from mirror_avatar.lab.inputs import HumanPlayer, InputSource
from mirror_avatar.lab.plan import SessionPlan
from mirror_avatar.live.session import RecordedTrial
from mirror_avatar.metrics import compute_phase, session_metrics
from mirror_avatar.metrics.group import compute_cluster_phase
from mirror_avatar.players.base import Observation, Player
from mirror_avatar.seeds import spawn_seeds
from mirror_avatar.session import SessionWriter
from mirror_avatar.specs import load_player
from mirror_avatar.trials import MIN_SAMPLES

logger = logging.getLogger(__name__)

Array = NDArray[np.float64]
Clock = Callable[[], float]
"""A clock (s) stamping each sample, as recorded in ``clock_s``."""


def trial_stem(directory: Path, n: int) -> Path:
    """Path of trial n's files without their suffixes: ``directory/trial-NN``."""
    return directory / f"trial-{n:02d}"


def build_avatars(plan: SessionPlan) -> dict[int, Player]:
    """Load every avatar of the plan in its role and step it once (compiling off the clock).

    Raises
    ------
    InputError
        An avatar spec that names no player or a role its model cannot play.
    """
    avatars: dict[int, Player] = {}
    for k, slot in enumerate(plan.slots):
        if slot.kind == "avatar" and slot.spec is not None:
            avatars[k] = load_player(slot.spec, plan.roles[k])
            avatars[k].reset(seed=0)
            avatars[k].step(Observation.of_partner(0, 0.0, 0.0, 0.0))
    return avatars


class InputLog:
    """Engine sink writing ``trial-NN_inputs.csv``: the clock and each person's device sample.

    Parameters
    ----------
    path
        The file; it must not exist yet.
    people
        The people (player index, player), in player order.
    clock
        Stamps each sample (s).
    publish
        Receives each sample's positions (N,) and its clock time (the LSL outlet), or None.

    Attributes
    ----------
    first_stamp, last_stamp
        Clock times of the first and the latest sample written (NaN before any).
    """

    def __init__(
        self,
        path: Path,
        people: list[tuple[int, HumanPlayer]],
        clock: Clock,
        publish: Callable[[Array, float], None] | None = None,
    ) -> None:
        self.people = people
        self.clock = clock
        self.publish = publish
        self.first_stamp = self.last_stamp = math.nan
        self._file: IO[str] = path.open("x", encoding="utf-8", newline="\n")
        columns = ["time", "clock_s"]
        for _, player in people:
            columns += [f"seq_{player.label}", f"age_ms_{player.label}", f"held_{player.label}"]
        self._file.write(",".join(columns) + "\n")
        self._file.flush()

    def __call__(self, row: Array) -> None:
        """Write the sample's time, clock time and inputs; publish its positions."""
        stamp = self.clock()
        if math.isnan(self.first_stamp):
            self.first_stamp = stamp
        self.last_stamp = stamp
        fields = [repr(float(row[0])), repr(stamp)]
        for _, player in self.people:
            tick = player.last_input
            age = "" if math.isnan(tick.age) else f"{tick.age * 1000.0:.3f}"
            fields += [str(tick.seq), age, str(int(tick.held))]
        self._file.write(",".join(fields) + "\n")
        self._file.flush()
        if self.publish is not None:
            self.publish(row[1::4], stamp)

    def close(self) -> None:
        """Close the file."""
        self._file.close()


class LabTrial(RecordedTrial):
    """Trial n of a lab session in progress: its engine, its files and its people's state.

    Parameters
    ----------
    plan
        The session's plan.
    n
        The trial's number (1-based).
    directory
        The session's folder.
    inputs
        Each person's input device, by player index.
    avatars
        Each avatar, by player index (`build_avatars`).
    clock
        Stamps each sample (s).
    lab
        What the sidecar's ``metadata["lab"]`` records besides the trial and the slots
        (session id, condition...).
    publish
        Receives each sample's positions and clock time (the LSL outlet), or None.
    """

    def __init__(
        self,
        plan: SessionPlan,
        n: int,
        directory: Path,
        inputs: Mapping[int, InputSource],
        avatars: Mapping[int, Player],
        clock: Clock,
        lab: dict[str, Any],
        publish: Callable[[Array, float], None] | None = None,
    ) -> None:
        self.plan = plan
        self.n = n
        self.roles = plan.roles
        self.labels = tuple(slot.label for slot in plan.slots)
        players: list[Player] = []
        for k, slot in enumerate(plan.slots):
            if slot.kind == "human":
                players.append(HumanPlayer(inputs[k], slot.label))
            else:
                players.append(avatars[k])
        self.players = players
        self.people = [(k, p) for k, p in enumerate(players) if isinstance(p, HumanPlayer)]
        self.period = players[0].period
        self.n_ticks = count_samples(plan.duration, self.period)
        self.seed = int(spawn_seeds(plan.seed, n)[n - 1])
        self.dropped: dict[str, int] = {}
        stem = trial_stem(directory, n)
        self.session_path = stem.with_name(stem.name + "_session.csv")
        self.inputs_path = stem.with_name(stem.name + "_inputs.csv")
        self.writer = SessionWriter(
            self.session_path,
            self.labels,
            self.roles,
            plan.graph,
            self.period,
            self._metadata(lab, clock),
        )
        self.input_log = InputLog(self.inputs_path, self.people, clock, publish)
        self._taken = np.full(len(players), np.nan)
        sinks: list[Sink] = [self.writer.append, self.input_log, self._remember]
        self.engine = Engine(players, plan.graph, self.roles, self.labels, sinks)
        self.engine.reset(self.seed, self.n_ticks)
        self.writer.annotate(
            {"player_seeds": self.engine.player_seeds, "players": [p.describe() for p in players]}
        )
        self._lock = threading.Lock()
        self._closed = False

    def _metadata(self, lab: dict[str, Any], clock: Clock) -> dict[str, Any]:
        slots = [
            {
                "label": slot.label,
                "kind": slot.kind,
                "role": role,
                "spec": slot.spec,
                "device": slot.device,
            }
            for slot, role in zip(self.plan.slots, self.roles, strict=True)
        ]
        return {
            "lab": lab | {"trial": self.n, "slots": slots},
            "seed": self.seed,
            "duration_requested_s": self.plan.duration,
            "period_s": self.period,
            "time_axis": "engine clock: sample k at k * period_s",
            "clock": getattr(clock, "__qualname__", str(clock)),
            "created_utc": datetime.now(UTC).isoformat(),
            "software": f"mirror-avatar {__version__}",
            "dropped": {},
            "held": {},
            "files": {"session": self.session_path.name, "inputs": self.inputs_path.name},
        }

    def _remember(self, row: Array) -> None:
        self._taken = row[1::4].copy()

    def positions(self) -> list[float]:
        """Return every player's position (units) at the last sample taken (NaN before)."""
        return self._taken.tolist()

    def held(self) -> dict[str, int]:
        """Ticks at which each person's position was held (no new sample), by label."""
        return {player.label: player.held for _, player in self.people}

    def tick(self) -> None:
        """Take sample k and advance the avatars to t_{k+1} (the last sample: take it only).

        Safe from a worker thread: a tick and `finish` never overlap; after `finish` it does
        nothing.
        """
        with self._lock:
            if self._closed or self.finished:
                return
            if self.k < self.n_ticks - 1:
                self.engine.step()
            else:
                self.engine.finish()

    def mark_dropped(self, label: str) -> None:
        """Record that ``label``'s connection dropped at the current sample (sidecar, now)."""
        with self._lock:
            if self._closed:
                return
            self.dropped.setdefault(label, self.k)
            self.writer.annotate({"dropped": dict(self.dropped), "held": self.held()})

    def recent(self, seconds: float = 10.0) -> dict[str, Any]:
        """Return the last ``seconds`` of positions, and the group synchronisation over them.

        Returns
        -------
        dict
            ``times`` (s), ``positions`` (one list per player, units) and ``group_sync``:
            the mean of ρ_g(t) over the window (METHODS section 8) for three or more players
            who all moved, else None.
        """
        with self._lock:
            session = self.engine.session()
        window = max(2, int(round(seconds / self.period)))
        x = session.positions[:, -window:]
        return {
            "times": session.times[-window:].tolist(),
            "positions": x.tolist(),
            "group_sync": _group_sync(x) if len(self.players) >= 3 else None,
        }

    def finish(self, complete: bool, reason: str) -> dict[str, Any]:
        """Close the files, compute the metrics and write the final sidecar.

        Returns
        -------
        dict
            The sidecar's metadata with ``n_samples`` and ``metrics``
            (`mirror_avatar.metrics.session_metrics`; ``{"error": ...}`` if they fail, the
            recording is kept).
        """
        with self._lock:
            self._closed = True
        self.input_log.close()
        extra: dict[str, Any] = {
            "ended_utc": datetime.now(UTC).isoformat(),
            "end_reason": reason,
            "dropped": dict(self.dropped),
            "held": self.held(),
        }
        try:
            session = self.engine.session()
            extra["metrics"] = session_metrics(session) if session.n_samples >= MIN_SAMPLES else {}
        except Exception as error:  # the recording is kept whatever the analysis does
            logger.exception("metrics of %s failed", self.session_path)
            extra["metrics"] = {"error": f"{type(error).__name__}: {error}"}
        sidecar = self.writer.close(complete, extra)
        return sidecar["metadata"] | {"n_samples": sidecar["n_samples"]}


def _group_sync(x: Array) -> float | None:
    if x.shape[1] < MIN_SAMPLES or not all(np.ptp(row) > 0 for row in x):
        return None
    cluster = compute_cluster_phase(np.array([compute_phase(row) for row in x]))
    return float(cluster.group.mean())
