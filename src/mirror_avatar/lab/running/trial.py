"""One lab trial: every player on the session's clock, every sample on disk as it is taken.

A `LabTrial` is the real-time core's clocked trial (`mirror_avatar.realtime.trial.ClockedTrial`)
with a lab session's players: its people are `mirror_avatar.realtime.inputs.HumanPlayer` s
reading their devices and its avatars the engine's own players, advanced by their ``step``
exactly as in simulations. The session's clock (`mirror_avatar.realtime.clock.run_on_clock`)
ticks it once per control period T; sample k is the time ``k * T`` of the engine's clock.

Files, in the session's folder, flushed line by line (METHODS section 9):

- ``trial-NN_session.csv`` + ``.json``: the N-player session (`mirror_avatar.sessions.session`),
  read by ``mirror-avatar evaluate``; the sidecar's ``metadata["lab"]`` names the session, the
  trial, the condition and every slot (with an LSL device: its source id, host and counts of invalid
  and clipped samples; with an avatar: where it ran, ``runs``), and ``dropped`` / ``held`` /
  ``lost`` are updated as they happen, and ``missing`` counts the samples of an avatar run in
  its person's page at which the page had reported no newer tick
  (`mirror_avatar.lab.running.page_avatar`);
- ``trial-NN_page.csv``, with an avatar run in its person's page: every tick the page reported
  (`mirror_avatar.lab.running.page_avatar.PageAvatar.write_steps`), written when the trial ends;
- ``trial-NN_pointer.csv`` (`PointerLog`, when a person plays with a page's pointer): every
  pointer sample a page sent, with its time on the page's clock and on the server's (METHODS
  section 18), written at the tick that first could use it;
- ``trial-NN_view.csv`` (`mirror_avatar.lab.running.views.ViewLog`): every partner position a
  page drew, with the time of its sample and of the draw on the server's clock (METHODS
  section 19), written at the tick after the page reported it;
- ``trial-NN_inputs.csv`` (`mirror_avatar.realtime.trial.TickLog`): per sample, the clock time at
  which it was taken (``clock_s``: the LSL clock when pylsl is installed, so the samples line up
  with EEG recorded through LSL; otherwise the monotonic clock), how late its tick was, and per
  person the sequence number of the device sample used, its age (ms), whether it was held (no
  new sample since the previous tick: the last position is kept, never extrapolated) and whether
  the input was live.

When a trial ends, its sidecar records each page's clock and rates (``pages``: `page_record`;
``view``: its partners' draws, `mirror_avatar.lab.running.views.ViewLog.summary`) and the
session's metrics (``metrics``) and the field's
measures (``measures``), as ``evaluate`` and ``study table`` compute them
(`mirror_avatar.metrics.measuring.measure_trial`: the first second left out,
`mirror_avatar.metrics.measuring.TRIAL_SURROGATES` circular-shift surrogates seeded by the
trial's seed), computed in the worker thread that finishes the trial.

Whatever happens - a participant drops, the disk fills, the server is killed, an avatar
diverges (the trial ends at that sample, its sidecar's ``diverged`` saying which player and
when) - the lines written stay readable; the sidecar says ``"complete": false`` until the trial
ends well.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from mirror_avatar import __version__
from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import spawn_seeds
from mirror_avatar.engine.loop import count_samples, row_positions, spawn_session_seeds
from mirror_avatar.files.atomic import LineFile
from mirror_avatar.files.trial_record import PerturbationRecord, SlotRecord, trial_record
from mirror_avatar.files.trials import MIN_SAMPLES
from mirror_avatar.lab.design.avatars import load_avatar, successor_players
from mirror_avatar.lab.design.perturbation import Perturbation
from mirror_avatar.lab.design.plan import SessionPlan
from mirror_avatar.lab.files import trial_file, trial_stem
from mirror_avatar.lab.running.page_avatar import PageAvatar
from mirror_avatar.lab.running.views import ViewLog
from mirror_avatar.metrics import compute_phase
from mirror_avatar.metrics.group import compute_cluster_phase
from mirror_avatar.metrics.measuring import measure_trial
from mirror_avatar.players.base import Player
from mirror_avatar.realtime.clock import time_players
from mirror_avatar.realtime.inputs import BrowserInput, HumanPlayer, InputSource, PointerSample
from mirror_avatar.realtime.trial import Array, Clock, ClockedTrial
from mirror_avatar.sessions.session import Session

logger = logging.getLogger(__name__)


def build_avatars(plan: SessionPlan) -> dict[int, Player]:
    """Load every avatar of the plan in its role and time the server's avatars' step here.

    Each avatar is loaded (`mirror_avatar.lab.design.avatars.load_avatar`); one that runs in
    the browser becomes a `mirror_avatar.lab.running.page_avatar.PageAvatar`. The others are
    stepped once untimed (compiling them off the clock) and then timed
    (`mirror_avatar.realtime.clock.time_players`); a plan whose avatars together need more than
    the control period per step cannot keep real time and is refused.

    Raises
    ------
    InputError
        An avatar spec that names no player or a role its model cannot play, an avatar the page
        cannot step set to run there, or avatars too slow for the control period on this machine.
    """
    built: dict[int, Player] = {}
    for k, slot in enumerate(plan.slots):
        if slot.kind == "avatar" and slot.spec is not None:
            built[k] = load_avatar(slot.spec, plan.roles[k])
            if slot.runs == "browser":
                n_steps = count_samples(plan.duration, built[k].period)
                built[k] = PageAvatar(built[k], slot.label, n_steps)
    avatars = {k: p for k, p in built.items() if not isinstance(p, PageAvatar)}
    if avatars:
        medians = time_players(list(avatars.values()))
        period = next(iter(avatars.values())).period
        if sum(medians) > period:
            slowest = max(range(len(medians)), key=medians.__getitem__)
            k = list(avatars)[slowest]
            raise InputError(
                f"players[{k}].spec",
                f"the avatars need {sum(medians) * 1000:.1f} ms per step on this machine "
                f"({plan.slots[k].label}: {medians[slowest] * 1000:.1f} ms), over the control "
                f"period of {period * 1000:.0f} ms: choose a smaller model",
            )
    return built


POINTER_COLUMNS = ("label", "seq", "page_ms", "server_s", "received_s", "x")
"""Columns of a trial's pointer file (`PointerLog`)."""


class PointerLog:
    """Engine sink writing ``trial-NN_pointer.csv``: the pages' samples, at each tick.

    Each sample received since the previous tick, with its page time (ms), its server time and
    its batch's receipt (s, the server's clock) and its position (units).

    Parameters
    ----------
    path
        The file; it must not exist yet.
    pages
        Each pointer's label and input.

    Attributes
    ----------
    received
        The samples written at the latest tick, by label, oldest first.
    """

    def __init__(self, path: Path, pages: Mapping[str, BrowserInput]) -> None:
        self.pages = dict(pages)
        self.path = path
        self.received: dict[str, list[PointerSample]] = {}
        self._file = LineFile(path, ",".join(POINTER_COLUMNS))

    def __call__(self, row: Array) -> None:
        """Write the samples received since the previous tick."""
        self.received = {label: source.unread() for label, source in self.pages.items()}
        for label, samples in self.received.items():
            for s in samples:
                times = f"{s.page_ms:.3f},{s.server_s:.6f},{s.received_s:.6f}"
                self._file.write(f"{label},{s.seq},{times},{s.x!r}")

    def close(self) -> None:
        """Close the file."""
        self._file.close()


def page_record(source: BrowserInput, start_s: float, end_s: float) -> dict[str, Any]:
    """Return what the sidecar records of a page's clock and rates.

    Its clock (`mirror_avatar.realtime.page_clock.PageClock.summary`), rates
    (`mirror_avatar.realtime.inputs.BrowserInput.rates`) and interruptions (its tab hidden, its
    window out of focus: `mirror_avatar.realtime.interruptions.Interruptions.between`, the key
    absent when there were none) between server times ``start_s`` and ``end_s`` (s).
    """
    interruptions = source.interruptions.between(start_s, end_s)
    page = source.clock.summary(start_s, end_s) | source.rates(start_s, end_s)
    return page | ({"interruptions": interruptions} if interruptions else {})


class LabTrial(ClockedTrial):
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
    perturbations
        Changes of avatars during the trial, each with the avatar's player index, in order
        of time (`mirror_avatar.lab.design.perturbation`).

    Attributes
    ----------
    perturbations
        The changes made so far, as the sidecar's ``"perturbations"`` lists them:
        ``{"sample", "time_s", "player", "change"}``.
    page_avatars
        The avatars stepped in their person's page, by player index.
    views
        What each page was sent of its partners and drew (`mirror_avatar.lab.running.views`).
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
        perturbations: Sequence[tuple[int, Perturbation]] = (),
    ) -> None:
        self.plan = plan
        self.n = n
        self.inputs = dict(inputs)
        players: list[Player] = []
        for k, slot in enumerate(plan.slots):
            if slot.kind == "human":
                players.append(HumanPlayer(inputs[k], slot.label))
            else:
                players.append(avatars[k])
        period = players[0].period
        self.page_avatars = {k: p for k, p in enumerate(players) if isinstance(p, PageAvatar)}
        self.page_path = trial_file(directory, n, "_page.csv")
        self.seed = int(spawn_seeds(plan.seed, n)[n - 1])
        self.dropped: dict[str, int] = {}
        self.publish = publish
        self.perturbations: list[dict[str, Any]] = []
        self._successors = self._build_successors(perturbations, len(players))
        self._taken = np.full(len(players), np.nan)
        self._sidecar_writes = ThreadPoolExecutor(max_workers=1, thread_name_prefix="sidecar")
        self.pages = {
            slot.label: source
            for k, slot in enumerate(plan.slots)
            if isinstance(source := self.inputs.get(k), BrowserInput)
        }
        self.pointer_log = PointerLog(trial_file(directory, n, "_pointer.csv"), self.pages)
        labels = [slot.label for slot in plan.slots]
        self.views = ViewLog(trial_file(directory, n, "_view.csv"), labels)
        self._stamps: list[float] = []
        for source in self.pages.values():
            source.unread()  # what came before the trial is not its
        super().__init__(
            players,
            [slot.label for slot in plan.slots],
            plan.roles,
            plan.graph,
            count_samples(plan.duration, period),
            self.seed,
            trial_stem(directory, n),
            self._metadata(lab, period),
            clock,
            [self._remember, self.pointer_log, self.views],
        )
        players_now = {
            "player_seeds": self.engine.player_seeds,
            "players": [p.describe() for p in players],
        }
        try:
            self.writer.annotate(players_now)
        except OSError:
            self.finish(False, "the trial's files could not be written")
            raise

    def _build_successors(
        self, perturbations: Sequence[tuple[int, Perturbation]], n_players: int
    ) -> list[tuple[int, Perturbation, Player]]:
        """Build and reset, off the clock, the player each perturbation hands the avatar over to.

        Each is `mirror_avatar.lab.design.avatars.successor_players`', reset with the seed the
        engine gives the avatar (`mirror_avatar.engine.loop.spawn_session_seeds`), so that it draws
        the avatar's own reference.
        """
        seeds, _ = spawn_session_seeds(self.seed, n_players)
        built = successor_players(self.plan, perturbations)
        for k, _, player in built:
            player.reset(seed=seeds[k])
        return built

    def before_step(self, k: int) -> None:
        """Hand each avatar perturbed at sample k over to its successor, and record it."""
        while self._successors and self._successors[0][1].sample <= k:
            i, perturbation, player = self._successors.pop(0)
            player.take_over(self.engine.players[i])
            self.engine.players[i] = self.players[i] = player
            change = PerturbationRecord(
                k, round(k * self.period, 9), perturbation.player, perturbation.change
            )
            self.perturbations.append(change.to_json())
            self.writer.annotate({"perturbations": list(self.perturbations)})

    def _metadata(self, lab: dict[str, Any], period: float) -> dict[str, Any]:
        """Return the sidecar's first metadata; its ``lab`` written by the trial's record."""
        slots = tuple(
            SlotRecord(slot.label, slot.kind, role, slot.spec, slot.device, self._device(k),
                       slot.runs)
            for k, (slot, role) in enumerate(zip(self.plan.slots, self.plan.roles, strict=True))
        )  # fmt: skip
        lab = lab | {"trial": self.n, "slots": [slot.to_json() for slot in slots]}
        files = {"page": self.page_path.name} if self.page_avatars else {}
        files["pointer"] = self.pointer_log.path.name
        files["view"] = self.views.path.name
        return {
            "lab": trial_record({"lab": lab}).lab_json(),
            "files": files,
            "seed": self.seed,
            "duration_requested_s": self.plan.duration,
            "period_s": period,
            "created_utc": datetime.now(UTC).isoformat(),
            "software": f"mirror-avatar {__version__}",
            "dropped": {},
            "held": {},
            "perturbations": [],
        }

    def _device(self, k: int) -> dict[str, Any] | None:
        """Return what an input device says of itself (an LSL stream: source id, host, counts)."""
        describe = getattr(self.inputs.get(k), "describe", None)
        return describe() if callable(describe) else None

    def _remember(self, row: Array) -> None:
        self._taken = row_positions(row).copy()
        self._stamps.append(self.tick_log.last_stamp)
        if self.publish is not None:
            self.publish(self._taken, self.tick_log.last_stamp)

    def positions(self) -> list[float]:
        """Return every player's position (units) at the last sample taken (NaN before)."""
        return self._taken.tolist()

    def mark_dropped(self, label: str) -> None:
        """Record that ``label``'s connection dropped at the current sample.

        Returns at once, whatever thread calls it (the event loop) and however slow the disk:
        the sidecar is rewritten in a thread of the trial's own, outside the trial's lock, so
        the clock ticks on meanwhile.
        """
        if self._closed:
            return
        self.dropped.setdefault(label, self.k)
        with contextlib.suppress(RuntimeError):  # finished meanwhile: its final sidecar has it
            self._sidecar_writes.submit(self._write_drops)

    def _write_drops(self) -> None:
        """Rewrite the sidecar with the drops: its text made under the lock, written outside."""
        with self._lock:
            if self._closed:
                return
            text = self.writer.sidecar_text({"dropped": dict(self.dropped), "held": self.held()})
        try:
            self.writer.write_sidecar(text)
        except OSError as error:
            logger.warning("the drops were not written to the sidecar: %s", error)

    def close_files(self) -> None:
        """Let the drops' sidecar writes end, close the files, write the page's avatar's steps."""
        self._sidecar_writes.shutdown(wait=True)
        self.pointer_log.close()
        self.views.close()
        super().close_files()
        for avatar in self.page_avatars.values():
            try:
                avatar.write_steps(self.page_path)
            except OSError as error:
                logger.warning("the page's avatar's steps were not written: %s", error)

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

    def analyse(self, session: Session) -> dict[str, Any]:
        """Return the drops, the input devices' final counts, the metrics and the measures.

        The metrics and measures are `mirror_avatar.metrics.measuring.measure_trial`'s, as
        ``evaluate`` and ``study table`` compute them; none when too few samples remain.
        """
        slots = self.writer.sidecar["metadata"]["lab"]["slots"]
        for k, slot in enumerate(slots):
            device = self._device(k)
            if device is not None:
                slot["input"] = device
        span = (self.tick_log.first_stamp, self.tick_log.last_stamp)
        pages = {label: page_record(source, *span) for label, source in self.pages.items()}
        stamps = np.asarray(self._stamps, dtype=np.float64)
        for label, page in pages.items():
            view = self.views.summary(label, stamps, session.positions)
            if view is not None:
                page["view"] = view
        counts: dict[str, Any] = {"dropped": dict(self.dropped), "pages": pages}
        if self.page_avatars:
            counts["missing"] = {p.slot: p.missing for p in self.page_avatars.values()}
        measured = measure_trial(session)
        if measured is None:
            return counts | {"metrics": {}, "measures": {}}
        measures = measured.measures.values if measured.metrics else {}
        return counts | {"metrics": measured.metrics, "measures": measures}


def _group_sync(x: Array) -> float | None:
    if x.shape[1] < MIN_SAMPLES or not all(np.ptp(row) > 0 for row in x):
        return None
    cluster = compute_cluster_phase(np.array([compute_phase(row) for row in x]))
    return float(cluster.group.mean())
