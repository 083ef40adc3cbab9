"""The lab server's settings and sessions: those open and the keys of their join links.

`Lab` creates a session of a plan (`mirror_avatar.lab.running.schedule.OnePlan`) or a participant's
run of the protocol loaded (`mirror_avatar.lab.running.study.ParticipantRun`), each with its LSL
outlet and clock when the server publishes LSL, and finds a session by the key of a join link while
the session lasts.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.lab.design.plan import LslDevice, SessionPlan
from mirror_avatar.lab.design.protocol import Protocol
from mirror_avatar.lab.running.participant import Participant
from mirror_avatar.lab.running.runner import LabSession, Outlet
from mirror_avatar.lab.running.schedule import OnePlan
from mirror_avatar.lab.running.screening import record_refusal
from mirror_avatar.lab.running.study import ParticipantRun, study_folder
from mirror_avatar.players.base import Player
from mirror_avatar.realtime.inputs import InputSource
from mirror_avatar.realtime.settings import PageSettings
from mirror_avatar.realtime.trial import Clock

logger = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class LabSettings(PageSettings):
    """How the lab server runs (and the `mirror_avatar.realtime.settings.PageSettings`).

    Parameters
    ----------
    out_dir
        Where sessions are recorded (one folder each).
    token
        The researcher's token.
    max_sessions
        Most sessions that have not ended at once.
    ping_interval
        Seconds between the round-trip pings sent to each page.
    requests_per_second
        API requests and WebSocket connections per second from one address (bursts of 4 s).
    lsl
        Whether sessions publish an LSL outlet and take LSL input devices (needs pylsl).
    protocol
        The study protocol whose participants' sessions the console creates
        (`mirror_avatar.lab.running.study.ParticipantRun`) until the console loads another, or None.
    public_url
        The address participants reach the server at, ``https://NAME[:PORT]`` behind a reverse
        proxy (`mirror_avatar.lab.running.public`): the join links are built on it; None: on the
        address the console reached the server by.
    """

    out_dir: Path
    token: str
    max_sessions: int = 16
    ping_interval: float = 0.5
    requests_per_second: float = 40.0
    lsl: bool = False
    protocol: Protocol | None = None
    public_url: str | None = None


KEEP_ENDED = 8
"""Ended sessions kept in memory for the console (the oldest beyond are forgotten; their
files stay)."""


@dataclass
class Lab:
    """The server's sessions and the keys of their join links.

    A session that ends loses its join keys at once (its links stop); of the ended sessions
    only the `KEEP_ENDED` most recent stay listed, so memory and the console's answers do not
    grow with the sessions a server has run. ``protocol`` is the protocol whose participants'
    runs are created: the settings' at first, then the last one loaded from the console.
    ``opening`` names the sessions whose folders are being made or read in a worker thread.
    """

    settings: LabSettings
    sessions: dict[str, LabSession] = field(default_factory=dict)
    keys: dict[str, tuple[LabSession, Participant]] = field(default_factory=dict)
    created: int = 0
    protocol: Protocol | None = field(init=False)
    opening: set[str] = field(default_factory=set)

    def __post_init__(self) -> None:
        self.protocol = self.settings.protocol

    async def create(self, plan: SessionPlan, avatars: dict[int, Player]) -> LabSession:
        """Create a session of ``plan`` with its avatars, built (`build_avatars`).

        Its folder and ``plan.json`` are written in a worker thread.
        """
        self.forget_ended()
        active = [s for s in self.sessions.values() if not s.ended]
        if len(active) + len(self.opening) >= self.settings.max_sessions:
            raise InputError("plan", f"{len(active)} sessions are open: end one first")
        self.created += 1
        stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%S")
        session_id = f"{stamp}-{self.created:03d}"
        outlet, open_device, clock = lsl_hooks(self.settings.lsl, session_id, plan)
        self.opening.add(session_id)
        try:
            session = await asyncio.to_thread(
                LabSession,
                session_id,
                OnePlan(plan),
                self.settings.out_dir / session_id,
                clock,
                self.settings.countdown,
                self.settings.max_tick,
                outlet,
                open_device,
            )
        finally:
            self.opening.discard(session_id)
        session.avatars = avatars
        self._add(session)
        return session

    async def create_study(self, participant: int) -> LabSession:
        """Create (or resume from its folder) participant ``participant``'s run of the protocol.

        The folder is made, or its ``study.json`` read and its trials listed, in a worker
        thread (`mirror_avatar.lab.running.study.read_schedule`: the checked reader), so that a bad
        folder delays no one's clock. With LSL, the session stamps its samples on the LSL
        clock and publishes one outlet for the participant's whole run (`study_outlet`).
        """
        protocol = self.protocol
        assert protocol is not None
        self.forget_ended()
        name = study_folder(protocol, participant)
        open_ = name in self.sessions and not self.sessions[name].ended
        if open_ or name in self.opening:
            raise InputError("participant", f"participant {participant}'s session is open")
        self.opening.add(name)
        try:
            session = await asyncio.to_thread(self._open_run, protocol, participant, name)
        finally:
            self.opening.discard(name)
        if self.settings.lsl:
            session.outlet = study_outlet(session)
        self.sessions.pop(name, None)
        self._add(session)
        return session

    def _open_run(self, protocol: Protocol, participant: int, name: str) -> LabSession:
        """Return the session of a participant's run, its folder made or resumed (blocking)."""
        return LabSession(
            name,
            ParticipantRun(protocol, participant),
            self.settings.out_dir / name,
            lsl_clock() if self.settings.lsl else time.monotonic,
            self.settings.countdown,
            self.settings.max_tick,
        )

    def open_study(self, participant: int) -> LabSession | None:
        """Return participant ``participant``'s run of the protocol while it is open, or None."""
        assert self.protocol is not None
        self.forget_ended()
        session = self.sessions.get(study_folder(self.protocol, participant))
        return None if session is None or session.ended else session

    def _add(self, session: LabSession) -> None:
        self.sessions[session.id] = session
        for participant in session.everyone():
            self.keys[participant.key] = (session, participant)

    def refuse(self, key: str, reason: str, measured: dict[str, Any] | None = None) -> bool:
        """End the visit of the person whose join key is ``key``: they are screened out.

        Their page is sent `refusal` (why, in one line, and the protocol's refusal code or link)
        and closed, now if it is connected, and each time their link is opened again. The
        refusal, with what was ``measured`` of the person (by name), is logged and written to
        ``refusal-<label>.json`` in the run's folder, in a worker thread
        (`mirror_avatar.lab.running.screening.record_refusal`). Returns whether the key names a
        person of an open session.
        """
        found = self.find(key)
        if found is None:
            return False
        session, participant = found
        participant.refused = reason
        if participant.outbox is not None:
            participant.outbox.put(refusal(session, reason))
            participant.outbox.end(CLOSE_REFUSED, "screened out")
        session.log(f"{participant.label} screened out: {reason}")
        writing = asyncio.get_running_loop().run_in_executor(
            None, record_refusal, session.directory, participant.label, reason, measured or {}
        )
        writing.add_done_callback(_report_unwritten)
        return True

    def find(self, key: str) -> tuple[LabSession, Participant] | None:
        """Return the session and slot of a join key, while the session lasts."""
        self.forget_ended()
        return self.keys.get(key)

    def forget_ended(self) -> None:
        """Drop the keys of ended sessions, and the ended sessions beyond `KEEP_ENDED`."""
        for key, (session, _) in list(self.keys.items()):
            if session.ended:
                del self.keys[key]
        ended = [sid for sid, session in self.sessions.items() if session.ended]
        for sid in ended[: max(0, len(ended) - KEEP_ENDED)]:
            del self.sessions[sid]


def _report_unwritten(writing: asyncio.Future[None]) -> None:
    """Log a refusal's file that could not be written (the refusal itself stands)."""
    error = writing.exception()
    if error is not None:
        logger.warning("a refusal was not written to its file: %s", error)


CLOSE_REFUSED = 4003
"""WebSocket close code of a page whose person was screened out (`Lab.refuse`)."""


def refusal(session: LabSession, reason: str) -> dict[str, Any]:
    """Return the message telling a screened-out person why, with the refusal code or link.

    The code and link are the protocol's (``[online]``: `mirror_avatar.lab.design.online`);
    a session of a plan has neither.
    """
    schedule = session.schedule
    ending = schedule.protocol.online.refusal if isinstance(schedule, ParticipantRun) else None
    return {"type": "refused", "message": reason} | (
        {"code": None, "url": None} if ending is None else ending.to_json()
    )


def lsl_hooks(
    enabled: bool, session_id: str, plan: SessionPlan
) -> tuple[Outlet | None, Callable[[LslDevice], InputSource] | None, Clock]:
    """Return a session's LSL outlet, LSL device opener and clock (without LSL: monotonic)."""
    if not enabled:
        return None, None, time.monotonic
    from mirror_avatar.lab.running.lsl import LslInput, SessionOutlet

    outlet = SessionOutlet(
        f"mirror-avatar {session_id}",
        f"mirror-avatar-{session_id}",
        [slot.label for slot in plan.slots],
        list(plan.roles),
        [slot.kind for slot in plan.slots],
        CONTROL_PERIOD,
    )

    def open_device(device: LslDevice) -> InputSource:
        return LslInput(
            device.stream, device.channel, device.scale, device.offset,
            source_id=device.source_id,
        )  # fmt: skip

    return outlet, open_device, lsl_clock()


def lsl_clock() -> Clock:
    """Return the LSL clock (`pylsl.local_clock`, s)."""
    import pylsl

    return pylsl.local_clock


def study_outlet(session: LabSession) -> Outlet:
    """Return the LSL outlet of a participant's run of a protocol.

    **Choice**: one outlet for the whole run (a recorder resolves it once), with a channel per
    player label of the run (`mirror_avatar.lab.running.study.ParticipantRun.channels`; NaN while
    that player is not in the condition), named and identified by the run's folder
    (``mirror-avatar <protocol>-p003``, so a resumed run publishes under the same source id),
    and markers naming each condition and its line-up as it begins, each trial's start and
    end and each perturbation.
    """
    from mirror_avatar.lab.running.lsl import SessionOutlet

    assert isinstance(session.schedule, ParticipantRun)
    labels, roles, kinds = session.schedule.channels()
    return SessionOutlet(
        f"mirror-avatar {session.id}",
        f"mirror-avatar-{session.id}",
        labels,
        roles,
        kinds,
        CONTROL_PERIOD,
    )
