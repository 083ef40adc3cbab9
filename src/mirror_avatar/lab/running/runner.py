"""A lab session on the server: its participants' connections, its trials, one clock for all.

A `LabSession` runs the trials of its schedule (`mirror_avatar.lab.running.schedule.Schedule`: one
`mirror_avatar.lab.design.plan.SessionPlan`, or a participant's run of a study protocol) one after
another (countdown, trial, end screen, what follows the trial, pause) when the researcher
starts it; the schedule says which plan plays each trial, who plays it, what the pages see and
what each trial's record holds. Its clock ticks every
control period T on absolute deadlines: each tick advances the `mirror_avatar.lab.running.trial.
LabTrial` (`mirror_avatar.realtime.clock.run_on_clock`) from the positions last received, then
sends every connected participant a frame with the players it sees. Frames go through each
connection's `mirror_avatar.realtime.outbox.Outbox`, which keeps only the newest undelivered
frame (a superseded frame is counted as dropped), so a slow page never delays the clock or the
others. A trial that cannot keep its clock is ended, saying why (`mirror_avatar.realtime.clock.
ClockLimits`: the plan's ``max_lateness``).

A participant whose connection closes mid-trial, or whose input stops delivering (a frozen page,
a vanished LSL stream: `mirror_avatar.realtime.inputs`), is marked in the trial's sidecar and
the console's events at once; the trial goes on with their position held, unless the plan says
``on_drop: "stop"``; the researcher may stop it from the console either way. Opening the link
again rejoins. A trial whose recording cannot be written (a full disk, a file-size limit) ends
as ``"disk full: cannot write FILE (...)"`` (`mirror_avatar.realtime.trial.write_failure`): the
samples written stay, the pages get their end message, and the next trial opens new files.
A trial whose avatar diverges ends at that sample, the player and the sample its end reason in
the console's events and the trial's sidecar (`mirror_avatar.realtime.trial.ClockedTrial`).
An avatar that runs in the browser is sent to its person's page before the trial's clock starts,
and its states are taken from that page (`mirror_avatar.lab.running.page_avatar`).
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import logging
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Protocol

from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.plan import SessionPlan
from mirror_avatar.lab.running.page_avatar import READY_TIMEOUT, PageStep
from mirror_avatar.lab.running.participant import COLOURS, Participant
from mirror_avatar.lab.running.schedule import Schedule
from mirror_avatar.lab.running.trial import LabTrial, build_avatars
from mirror_avatar.metrics.registry import END_SCREEN, GROUP_PLAYER, is_headline
from mirror_avatar.players.base import Player, PlayerDiverged
from mirror_avatar.realtime.clock import MAX_STEP, ClockLimits, run_on_clock
from mirror_avatar.realtime.inputs import BrowserInput, InputSource
from mirror_avatar.realtime.outbox import Outbox
from mirror_avatar.realtime.trial import DISK_FULL, Array, Clock

logger = logging.getLogger(__name__)

STATES = ("waiting", "countdown", "running", "pause", "finished", "aborted")
"""A session's states: waiting for the researcher's start, counting down, a trial running,
pausing between trials, all trials done, aborted."""

ENDED = ("finished", "aborted")
"""States in which the session's links have expired."""


class Outlet(Protocol):
    """Where a session publishes each sample's positions (an LSL outlet)."""

    def push_positions(self, positions: Array, timestamp: float) -> None:
        """Publish the players' positions (units) taken at ``timestamp`` (s, the clock's)."""
        ...

    def mark(self, event: str, timestamp: float | None = None) -> None:
        """Publish an event that happened at ``timestamp`` (s, the clock's; None: now)."""
        ...

    def close(self) -> None:
        """Stop publishing."""
        ...


CLOSE_ENDED = 4001
"""WebSocket close code telling a page its session has ended (its link has expired)."""


class LabSession:
    """One lab session: its schedule, folder, participants, trials and clock.

    Parameters
    ----------
    session_id
        The session's name (its folder under the output folder).
    schedule
        What it plays (`mirror_avatar.lab.running.schedule.OnePlan`, or a participant's run of a
        protocol: `mirror_avatar.lab.running.study.ParticipantRun`).
    directory
        Its folder (created, or resumed when the schedule finds its earlier run there).
    clock
        Stamps each sample (the LSL clock when pylsl is installed).
    countdown
        Seconds of countdown before each trial.
    max_step
        Seconds one step of the avatars may take before the trial is ended.
    outlet
        The session's LSL outlet (`mirror_avatar.lab.running.lsl.SessionOutlet`), or None.
    open_device
        Opens an LSL input device from a slot (`mirror_avatar.lab.running.lsl.LslInput`).
    """

    def __init__(
        self,
        session_id: str,
        schedule: Schedule,
        directory: Path,
        clock: Clock,
        countdown: int = 3,
        max_step: float = MAX_STEP,
        outlet: Outlet | None = None,
        open_device: Callable[[Any], InputSource] | None = None,
    ) -> None:
        self.id = session_id
        self.schedule = schedule
        self.directory = directory
        self.clock = clock
        self.countdown = countdown
        self.limits = ClockLimits(max_step, schedule.plan.max_lateness)
        self.outlet = outlet
        self.open_device = open_device
        self.state = "waiting"
        self.trial: LabTrial | None = None
        self.results: list[dict[str, Any]] = []
        self.events: collections.deque[str] = collections.deque(maxlen=50)
        self.error: str | None = None
        self.avatars: dict[int, Player] | None = None
        self.runner: asyncio.Task[None] | None = None
        self._stop_reason: str | None = None
        self._events_seen = self._perturbations_seen = 0
        opening = schedule.open(session_id, directory, datetime.now(UTC).isoformat())
        self.created_utc, self.next_trial = opening.created_utc, opening.next_trial
        if opening.event is not None:
            self.log(opening.event)

    @property
    def plan(self) -> SessionPlan:
        """The plan of the current trial (the schedule's)."""
        return self.schedule.plan

    @property
    def participants(self) -> dict[int, Participant]:
        """The people playing the current plan, by player index (the schedule's)."""
        return self.schedule.playing

    @property
    def total_trials(self) -> int:
        """Number of trials the session plays."""
        return self.schedule.total_trials

    @property
    def ended(self) -> bool:
        """Whether the session is over (its links have expired)."""
        return self.state in ENDED

    def log(self, event: str) -> None:
        """Record an event for the console."""
        stamp = datetime.now(UTC).strftime("%H:%M:%S")
        self.events.append(f"{stamp} {event}")
        logger.info("session %s: %s", self.id, event)

    def attach(self, participant: Participant, outbox: Outbox, connection: object) -> None:
        """Register a participant's page (a previous page of the same slot was closed).

        The page is welcomed, then sent what it is owed (the questions still open to it).
        """
        participant.outbox = outbox
        participant.connection = connection
        participant.joined = True
        if isinstance(participant.source, BrowserInput):
            participant.source.reconnected()
        outbox.put(self.schedule.welcome(participant, self.state))
        self.log(f"{participant.label} joined")
        for message in self.schedule.owed(participant):
            outbox.put(message)

    def detach(self, participant: Participant, outbox: Outbox) -> None:
        """Forget a participant's page; a running trial marks them dropped."""
        if participant.outbox is not outbox:
            return
        participant.frames_dropped += outbox.superseded
        participant.outbox = None
        participant.connection = None
        outbox.close()
        trial = self.playing_in(participant)
        if trial is not None:
            trial.mark_dropped(participant.label)
            self.log(f"{participant.label} dropped at sample {trial.k} of trial {trial.n}")
            self._mark(f"{participant.label} dropped")
            if self.plan.on_drop == "stop":
                self._stop_reason = f"{participant.label} dropped"
        else:
            self.log(f"{participant.label} left")

    def playing_in(self, participant: Participant) -> LabTrial | None:
        """Return the trial running with ``participant`` in it, or None."""
        trial = self.trial
        playing = participant in self.participants.values()
        return trial if trial is not None and self.state == "running" and playing else None

    def missing(self) -> list[str]:
        """Labels of the people whose page has not joined (LSL devices are opened at start)."""
        return [
            p.label for p in self.participants.values() if p.device == "pointer" and not p.connected
        ]

    def start(self, force: bool = False) -> str | None:
        """Start (or resume) the trials; return why not, or None.

        Without ``force``, every person with a pointer must have joined.
        """
        if self.state != "waiting":
            return f"the session is {self.state}"
        if self.next_trial > self.total_trials:
            return "every trial has been played"
        missing = self.missing()
        if missing and not force:
            return f"not joined yet: {', '.join(missing)} (start anyway with force)"
        self.error = None
        self.state = "countdown"
        self.runner = asyncio.get_running_loop().create_task(self._run())
        return None

    async def stop(self, reason: str = "stopped by the researcher") -> None:
        """End the running trial (saved, incomplete) and wait for the researcher's start."""
        if self.runner is not None:
            self.runner.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self.runner
            self.runner = None
        if self.trial is not None:
            await self._end_trial(self.trial, False, reason)
            self.next_trial += 1
        if not self.ended:
            self.state = "waiting"
            self.broadcast({"type": "state", "state": "waiting", "message": "Please wait."})

    async def abort(self) -> None:
        """End the session: a running trial is saved (incomplete) and every link expires."""
        await self.stop("session aborted")
        self.state = "aborted"
        self.log("session aborted")
        self.close()

    def close(self) -> None:
        """Tell every page the session ended; close the input devices and the LSL outlet."""
        self.broadcast({"type": "state", "state": self.state, "message": "The session has ended."})
        for participant in self.everyone():
            if participant.outbox is not None:
                participant.outbox.end(CLOSE_ENDED, "the session has ended")
            closer = getattr(participant.source, "close", None)
            if participant.device == "lsl" and closer is not None:
                closer()
        if self.outlet is not None:
            self.outlet.close()

    def everyone(self) -> list[Participant]:
        """Every person's slot of the session (the schedule's people)."""
        return self.schedule.people

    def broadcast(self, message: dict[str, Any]) -> None:
        """Queue a control message to every connected page."""
        for participant in self.participants.values():
            if participant.outbox is not None:
                participant.outbox.put(message)

    async def _run(self) -> None:
        try:
            while self.next_trial <= self.total_trials:
                await self._prepare(self.next_trial)
                reason = await self._play(self.next_trial)
                self.next_trial += 1
                if reason.startswith(DISK_FULL):
                    self._wait(f"{reason}: make room, then start the next trial")
                    return
                self.state = "pause"
                await self.schedule.after_trial(self.next_trial - 1, self.log)
                if self.next_trial <= self.total_trials:
                    self.state = "pause"
                    await asyncio.sleep(self.plan.pause)
            self.state = "finished"
            self.log("all trials played")
            self.close()
        except (InputError, OSError) as error:
            self._wait(f"cannot run: {error}")

    async def _prepare(self, n: int) -> None:
        """Get trial n's players ready: its plan entered, the avatars built, the LSL devices open.

        A new plan is announced (console, LSL marker) and every connected page welcomed again.
        """
        entered = self.schedule.enter(n, again=self.avatars is None)
        if entered is not None:
            self.avatars = None
            for person in self.everyone():
                if person.outbox is not None:
                    person.outbox.put(self.schedule.welcome(person, self.state))
            self.log(entered.event)
            self._mark(entered.marker)
        if self.avatars is None:
            self.avatars = await asyncio.to_thread(build_avatars, self.plan)
        await asyncio.to_thread(self._open_devices)

    def answer(self, participant: Participant, answer: Any) -> str | None:
        """Take a participant's answer to a question; return why not, or None."""
        return self.schedule.answer(participant, answer)

    def _wait(self, problem: str) -> None:
        """Wait for the researcher, saying why."""
        self.error = problem
        self.state = "waiting"
        self.log(problem)
        self.broadcast({"type": "state", "state": "waiting", "message": "Please wait."})

    def _open_devices(self) -> None:
        for k, participant in self.participants.items():
            lsl = self.plan.slots[k].lsl
            if lsl is not None and participant.source is None:
                if self.open_device is None:
                    raise InputError(participant.label, "an LSL input needs the lab run with --lsl")
                participant.source = self.open_device(lsl)
                participant.joined = True
                self.log(f"{participant.label}: LSL stream {lsl.stream!r} open")

    async def _play(self, n: int) -> str:
        """Play trial n; return why it ended."""
        self.state = "countdown"
        for remaining in range(self.countdown, 0, -1):
            self.broadcast({"type": "countdown", "remaining": remaining, "trial": n})
            await asyncio.sleep(1.0)
        opening = asyncio.ensure_future(asyncio.to_thread(self._new_trial, n))
        try:
            trial = await asyncio.shield(opening)
        except asyncio.CancelledError:  # stopped while its files were opening: `stop` closes them
            self.trial = await opening
            raise
        except (OSError, PlayerDiverged):  # its number is taken by the files made: the next is new
            self.next_trial += 1
            raise
        self.trial, self.state, self._stop_reason = trial, "running", None
        self._events_seen = self._perturbations_seen = 0
        await self._hand_avatars(trial)
        self.log(f"trial {n} started")
        self.broadcast({"type": "go", "trial": n, "duration": self.plan.duration})
        complete, reason = await run_on_clock(
            trial, self.limits, lambda: self._stop_reason, lambda: self._after_tick(trial)
        )
        await self._end_trial(trial, complete, reason)
        return reason

    async def _hand_avatars(self, trial: LabTrial) -> None:
        """Send the page of the dyad's person the avatar it steps; wait until it has built it.

        A page that has not built it within `READY_TIMEOUT` (or is not connected) leaves the
        avatar at its start, each sample counted missing, until it reports a tick.
        """
        for k, avatar in trial.page_avatars.items():
            (owner,) = self.participants.values()
            if owner.outbox is not None:
                owner.outbox.put({"type": "avatar", "index": k, "player": avatar.message})
                if await asyncio.to_thread(avatar.ready.wait, READY_TIMEOUT):
                    continue
            self.log(f"{avatar.slot}: {owner.label}'s page has not built it: samples missing")

    def page_step(self, participant: Participant, step: PageStep) -> None:
        """Take the avatar's state at a tick from the page of the person who steps it."""
        trial = self.trial
        if trial is not None and participant in self.participants.values():
            for avatar in trial.page_avatars.values():
                avatar.put(step)

    def shown(self, participant: Participant, drawn: list[tuple[int, float, float]]) -> None:
        """Take the frames a person's page drew: (sample k, page ms, server s) each."""
        trial = self.trial
        if trial is not None and participant in self.participants.values():
            trial.views.shown(participant.label, drawn)

    def _new_trial(self, n: int) -> LabTrial:
        inputs = {k: p.source for k, p in self.participants.items() if p.source is not None}
        lab = self.schedule.record(self.id, n)
        assert self.avatars is not None
        return LabTrial(
            self.plan,
            n,
            self.directory,
            inputs,
            self.avatars,
            self.clock,
            lab,
            self.schedule.publisher(self.outlet),
            self.schedule.perturbations(),
        )

    def _after_tick(self, trial: LabTrial) -> None:
        if trial.k == 1:
            self._mark(f"trial {trial.n} start", trial.tick_log.first_stamp)
        for event in trial.events[self._events_seen :]:
            label, k = event["label"], event["sample"]
            lost = event["event"] == "lost"
            self.log(f"{label}: input {'lost' if lost else 'live again'} at sample {k}")
            self._mark(f"{label} input {event['event']}")
            if lost and event["seq"] is not None and self.plan.on_drop == "stop":
                self._stop_reason = f"{label}'s input was lost"
        self._events_seen = len(trial.events)
        for change in trial.perturbations[self._perturbations_seen :]:
            what = f"{change['player']} {change['change']}"
            self.log(f"{what} at sample {change['sample']} of trial {trial.n}")
            now = change["sample"] == trial.k - 1
            self._mark(f"perturbation {what}", trial.tick_log.last_stamp if now else None)
        self._perturbations_seen = len(trial.perturbations)
        self.schedule.send_frames(trial)

    def _mark(self, event: str, timestamp: float | None = None) -> None:
        if self.outlet is not None:
            self.outlet.mark(event, timestamp)

    async def _end_trial(self, trial: LabTrial, complete: bool, reason: str) -> None:
        """Finish the trial in a worker thread (its metrics) and tell the pages.

        A stop arriving meanwhile waits for the trial to be saved and listed.
        """
        self.trial = None
        finishing = asyncio.ensure_future(asyncio.to_thread(trial.finish, complete, reason))
        try:
            summary = await asyncio.shield(finishing)
        except asyncio.CancelledError:
            self.results.append(await finishing)
            raise
        self.results.append(summary)
        self.log(f"trial {trial.n} ended: {reason}")
        self._mark(f"trial {trial.n} end: {reason}", trial.tick_log.last_stamp)
        for k, participant in self.participants.items():
            if participant.outbox is None:
                continue
            message: dict[str, Any] = {"type": "end", "trial": trial.n, "reason": reason}
            if self.plan.show_metrics:
                message["metrics"] = participant_metrics(summary.get("metrics", {}), k)
                message["metrics"] |= participant_measures(summary.get("measures", {}), k)
            message["next_in"] = self.schedule.next_in(trial.n, complete)
            participant.outbox.put(message)

    def status(self) -> dict[str, Any]:
        """Return what the console shows: state, slots with their connection quality, trials.

        The schedule adds what it knows (a study: where the participant is in the protocol).
        """
        trial = self.trial
        slots = []
        held = {} if trial is None else trial.held()
        lost = {} if trial is None else trial.lost()
        alive = {} if trial is None else trial.alive()
        for k, slot in enumerate(self.plan.slots):
            row: dict[str, Any] = {
                "index": k,
                "label": slot.label,
                "kind": slot.kind,
                "role": self.plan.roles[k],
                "spec": slot.spec,
                "device": slot.device,
                "colour": COLOURS[k],
            }
            if self.avatars is not None and k in self.avatars:
                row["plays"] = self.avatars[k].label  # which policy or virtual trainer
            participant = self.participants.get(k)
            if participant is not None:
                row |= {"joined": participant.joined, "connected": participant.connected,
                        "entry_rtt_p95_ms": participant.entry_rtt_p95_ms}  # fmt: skip
                row |= participant.quality()
                if trial is not None:
                    row["held"] = held.get(slot.label, 0)
                    row["lost"] = lost.get(slot.label, 0)
                    row["input_live"] = alive.get(slot.label)
                    row["dropped_at"] = trial.dropped.get(slot.label)
            slots.append(row)
        status = {
            "id": self.id,
            "state": self.state,
            "error": self.error,
            "plan": self.plan.to_json(),
            "trial": None if trial is None else trial_clock(trial),
            "next_trial": self.next_trial,
            "slots": slots,
            "trials": [trial_row(summary) for summary in self.results],
            "events": list(self.events),
        }
        at = min(self.next_trial if trial is None else trial.n, self.total_trials)
        return self.schedule.status(status, at, self.ended)


def trial_clock(trial: LabTrial) -> dict[str, Any]:
    """Return the running trial as the console shows it: number, progress, lateness.

    The lateness is the latest tick's and the largest so far (ms).
    """
    return {
        "n": trial.n,
        "progress": trial.progress,
        "late_ms": trial.tick_log.lateness * 1000.0,
        "max_late_ms": trial.max_lateness * 1000.0,
    }


def participant_metrics(metrics: dict[str, Any], k: int) -> dict[str, Any]:
    """Select the numbers participant k's end screen shows.

    CV and RMS for a dyad; for a group, the group synchronisation and the participant's own
    synchronisation, CV and RMS to its neighbours.
    """
    if "players" not in metrics:
        return {key: metrics[key] for key in END_SCREEN if key in metrics}
    own = metrics["players"][k]
    shown = {key: metrics.get(key) for key in END_SCREEN if key not in GROUP_PLAYER}
    return shown | {key: own[key] for key in END_SCREEN if key in own}


def participant_measures(measures: dict[str, Any], k: int) -> dict[str, Any]:
    """Select what participant k's end screen says of the measures of a dyad.

    ``co_confidence_rate`` (share of the trial spent moving together smoothly) and ``led_by``:
    ``"you"``, ``"partner"`` or ``"none"`` (neither led for most of the trial).
    """
    if "leader" not in measures:
        return {}
    leader = measures["leader"]
    led_by = "none" if leader == "none" else "you" if leader == k else "partner"
    return {"co_confidence_rate": measures.get("co_confidence_rate"), "led_by": led_by}


def headline_measures(measures: dict[str, Any]) -> dict[str, Any]:
    """Select the measures the console lists of a trial: headline ones, p-values, ``error``.

    The headline measures are `mirror_avatar.metrics.registry.is_headline`'s.
    The p-values come with their surrogates' description (``surrogates``: kind and count), so
    that the console writes a p-value at the floor of its surrogates as a bound.
    """
    return {
        key: value
        for key, value in measures.items()
        if is_headline(key) or key.endswith("_p_value") or key in ("surrogates", "error")
    }


def trial_row(summary: dict[str, Any]) -> dict[str, Any]:
    """Return a finished trial as the console lists it: outcome, metrics, measures, files.

    The measures are `headline_measures`'.
    """
    metrics = summary.get("metrics", {})
    return {
        "n": summary["lab"]["trial"],
        "complete": summary["complete"],
        "end_reason": summary.get("end_reason"),
        "n_samples": summary.get("n_samples"),
        "dropped": summary.get("dropped", {}),
        "held": summary.get("held", {}),
        "lost": summary.get("lost", {}),
        "late_ms": summary.get("tick_lateness_ms", {}),
        "metrics": {key: value for key, value in metrics.items() if is_headline(key)},
        "measures": headline_measures(summary.get("measures", {})),
        "files": [
            summary["files"]["session"],
            summary["files"]["session"].removesuffix(".csv") + ".json",
            summary["files"]["inputs"],
        ],
    }
