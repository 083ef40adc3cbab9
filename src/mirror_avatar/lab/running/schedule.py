"""What a lab session plays: its schedule, one plan or a participant's run of a protocol.

A `mirror_avatar.lab.running.runner.LabSession` runs the trials; its `Schedule` answers the
questions whose answers differ from one kind of session to the other: which plan plays trial n and
who plays it, what the pages are told and shown, what happens after a trial, and what the folder
and each trial's record hold. `OnePlan` plays one `mirror_avatar.lab.design.plan.SessionPlan`; a
participant's run of a study protocol is `mirror_avatar.lab.running.study.ParticipantRun`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple, Protocol

from mirror_avatar.files.atomic import write_atomic_json
from mirror_avatar.lab.design.perturbation import Perturbation
from mirror_avatar.lab.design.plan import SessionPlan
from mirror_avatar.lab.files import PLAN_FILE
from mirror_avatar.lab.running.participant import COLOURS, Participant
from mirror_avatar.lab.running.partner_frames import PartnerFrames
from mirror_avatar.lab.running.trial import LabTrial
from mirror_avatar.realtime.trial import Array


class Opening(NamedTuple):
    """A session's folder once made, or found holding the same schedule's earlier run.

    Attributes
    ----------
    created_utc
        When the session was first created (ISO 8601).
    next_trial
        The trial it plays next (1 unless resumed).
    event
        What the console's events say of it (a resumed run), or None.
    """

    created_utc: str
    next_trial: int
    event: str | None = None


class Entered(NamedTuple):
    """A new plan made current: what the console's events and the LSL markers say of it."""

    event: str
    marker: str


class Publisher(Protocol):
    """Where a schedule publishes each sample (an LSL outlet's ``push_positions``)."""

    def push_positions(self, positions: Array, timestamp: float) -> None:
        """Publish the players' positions (units) taken at ``timestamp`` (s, the clock's)."""
        ...


class Schedule(Protocol):
    """What a lab session plays, and what differs from one kind of session to another.

    ``plan`` and ``playing`` are the current plan and the people who play it, by player index;
    ``people`` every person with a join link.
    """

    @property
    def plan(self) -> SessionPlan:
        """The plan of the current trial."""
        ...

    @property
    def playing(self) -> dict[int, Participant]:
        """The people playing the current plan, by player index."""
        ...

    @property
    def people(self) -> list[Participant]:
        """Every person with a join link."""
        ...

    @property
    def total_trials(self) -> int:
        """Number of trials in all."""
        ...

    def open(self, session_id: str, directory: Path, created_utc: str) -> Opening:
        """Create the session's folder and its description, or resume the run found there."""
        ...

    def enter(self, n: int, again: bool) -> Entered | None:
        """Make trial n's plan current; say what changed, or None when the plan stays.

        ``again``: the session has no avatars for the current plan yet (its first trial, or
        their building failed): a schedule whose plan changes announces it again.
        """
        ...

    def welcome(self, participant: Participant, state: str) -> dict[str, Any]:
        """Return what a page is told on joining (and when the plan changes)."""
        ...

    def owed(self, participant: Participant) -> list[dict[str, Any]]:
        """Return what a page that (re)joins is owed besides its welcome (open questions)."""
        ...

    def send_frames(self, trial: LabTrial) -> None:
        """Send each connected page its frame of the sample just recorded."""
        ...

    def publisher(self, outlet: Publisher | None) -> Callable[[Array, float], None] | None:
        """Return what receives each sample's positions and clock time, or None."""
        ...

    def perturbations(self) -> list[tuple[int, Perturbation]]:
        """Return the changes of avatars in the next trial, with their player indices."""
        ...

    def record(self, session_id: str, n: int) -> dict[str, Any]:
        """Return what trial n's sidecar records of the session (``metadata["lab"]``)."""
        ...

    def next_in(self, n: int, complete: bool) -> float | None:
        """Return the pause (s) before the trial after trial n, or None if none follows soon."""
        ...

    async def after_trial(self, n: int, log: Callable[[str], None]) -> None:
        """Do what follows trial n before the pause (a study asks its questions; ends its run)."""
        ...

    def answer(self, participant: Participant, answer: Any) -> str | None:
        """Take a participant's answer to a question; return why not, or None."""
        ...

    def status(self, status: dict[str, Any], at: int, ended: bool) -> dict[str, Any]:
        """Return the session's status with what the schedule adds (``at``: its trial)."""
        ...


def welcome(plan: SessionPlan, participant: Participant, state: str) -> dict[str, Any]:
    """Return what a participant's page is told on joining: its slot and the players it sees."""
    k = participant.index
    return {
        "type": "welcome",
        "label": participant.label,
        "index": k,
        "role": plan.roles[k],
        "condition": plan.condition,
        "device": participant.device,
        "visible": [
            {"index": j, "label": plan.slots[j].label, "colour": COLOURS[j]}
            for j in participant.visible
        ],
        "trials": plan.trials,
        "duration": plan.duration,
        "state": state,
    }


def next_in(plan: SessionPlan, n: int, total: int, complete: bool) -> float | None:
    """Return the plan's pause (s) after a complete trial n of ``total``, or None after the last."""
    return plan.pause if complete and n < total else None


class OnePlan:
    """The schedule of a session that plays one plan: its trials, its people, ``plan.json``.

    Parameters
    ----------
    plan
        What the session plays.
    """

    def __init__(self, plan: SessionPlan) -> None:
        self.plan = plan
        self.playing = {
            k: Participant(k, plan.slots[k].label, plan.slots[k].device or "pointer",
                           [k, *plan.neighbours(k)])
            for k in plan.humans
        }  # fmt: skip
        self.frames = PartnerFrames()

    @property
    def people(self) -> list[Participant]:
        """Every person of the plan."""
        return list(self.playing.values())

    @property
    def total_trials(self) -> int:
        """The plan's number of trials."""
        return self.plan.trials

    def open(self, session_id: str, directory: Path, created_utc: str) -> Opening:
        """Create the session's folder and its ``plan.json`` (id, creation time, plan)."""
        directory.mkdir(parents=True, exist_ok=False)
        described = {"id": session_id, "created_utc": created_utc, "plan": self.plan.to_json()}
        write_atomic_json(directory / PLAN_FILE, described)
        return Opening(created_utc, 1)

    def enter(self, n: int, again: bool) -> Entered | None:
        """Keep the one plan."""
        return None

    def welcome(self, participant: Participant, state: str) -> dict[str, Any]:
        """Return the page's welcome: its slot and the players it sees, labelled."""
        return welcome(self.plan, participant, state)

    def owed(self, participant: Participant) -> list[dict[str, Any]]:
        """Nothing besides the welcome."""
        return []

    def send_frames(self, trial: LabTrial) -> None:
        """Send each page the positions of the players it sees, as they arrive."""
        self.frames.send(trial, self.playing)

    def publisher(self, outlet: Publisher | None) -> Callable[[Array, float], None] | None:
        """Publish each sample's positions on the outlet as they are."""
        return None if outlet is None else outlet.push_positions

    def perturbations(self) -> list[tuple[int, Perturbation]]:
        """No avatar changes mid-trial."""
        return []

    def record(self, session_id: str, n: int) -> dict[str, Any]:
        """Return the session's id and the plan's condition."""
        return {"session_id": session_id, "condition": self.plan.condition}

    def next_in(self, n: int, complete: bool) -> float | None:
        """Return the plan's pause after a complete trial, None after the last."""
        return next_in(self.plan, n, self.total_trials, complete)

    async def after_trial(self, n: int, log: Callable[[str], None]) -> None:
        """Nothing follows a trial but the pause."""

    def answer(self, participant: Participant, answer: Any) -> str | None:
        """Refuse: no question is asked."""
        return "no question was asked"

    def status(self, status: dict[str, Any], at: int, ended: bool) -> dict[str, Any]:
        """Add nothing."""
        return status
