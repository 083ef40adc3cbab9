"""A participant's page on the lab server: its WebSocket, positions and pongs in, frames out.

A join link holds the secret key of one person's slot in one session; its page's WebSocket
(`join_socket`) replaces an earlier page of the same link, and is closed when the key is not
valid or its session has ended. Messages are those of `mirror_avatar.lab.running.messages`, rate
limited per connection (`mirror_avatar.realtime.inbox.Inbox`). The page's person is screened as
the protocol declares (`mirror_avatar.lab.running.screening`): on the round trips of their first
page's first clock exchanges, on its frame rate and window during play
(`mirror_avatar.lab.running.play_screening`), and on their tab hidden during a trial.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from dataclasses import asdict

from starlette.websockets import WebSocket, WebSocketDisconnect

from mirror_avatar.lab.running.consent import needs_consent
from mirror_avatar.lab.running.messages import (
    Answer,
    AvatarPosition,
    ClockReport,
    ClockRequest,
    FocusChange,
    ParticipantMessage,
    PointerBatch,
    Pong,
    Shown,
    WindowSize,
    parse_participant_message,
)
from mirror_avatar.lab.running.participant import Participant
from mirror_avatar.lab.running.play_screening import PlayScreen
from mirror_avatar.lab.running.runner import LabSession
from mirror_avatar.lab.running.screening import (
    BACK_NOTICE,
    ENTRY_EXCHANGES,
    HIDDEN_REFUSAL,
    Entry,
    entry_refusal,
    online_of,
    round_trip_p95,
)
from mirror_avatar.lab.running.sessions import CLOSE_REFUSED, Lab, refusal
from mirror_avatar.realtime.inbox import Inbox
from mirror_avatar.realtime.inputs import BrowserInput
from mirror_avatar.realtime.interruptions import KINDS
from mirror_avatar.realtime.latency import Pings
from mirror_avatar.realtime.outbox import Outbox, Peer, encode_message

CLOSE_POLICY, CLOSE_REPLACED, CLOSE_UNKNOWN, CLOSE_CONSENT = 1008, 4002, 4004, 4005
"""WebSocket close codes: too many bad messages, the link opened on another page, no such link,
no consent given yet (and `mirror_avatar.lab.running.sessions.CLOSE_REFUSED`: screened out)."""


async def join_socket(lab: Lab, websocket: WebSocket) -> None:
    """Serve a participant's page: its position in, the frames of the players it sees out."""
    found = lab.find(websocket.path_params["key"])
    if found is None:
        await websocket.close(CLOSE_UNKNOWN, "this link is not valid or its session has ended")
        return
    session, participant = found
    await websocket.accept()
    if participant.refused is not None:
        await websocket.send_text(encode_message(refusal(session, participant.refused)))
        await websocket.close(CLOSE_REFUSED, "screened out")
        return
    if needs_consent(session, participant):
        await websocket.close(CLOSE_CONSENT, "consent first")
        return
    previous = participant.connection
    if isinstance(previous, WebSocket):  # it may be gone already, or closing for another page
        with contextlib.suppress(RuntimeError, OSError, WebSocketDisconnect):
            await previous.close(CLOSE_REPLACED, "this link was opened on another page")
    page = ParticipantPage(lab, session, participant, websocket)
    await page.run()


class ParticipantPage:
    """One participant page's connection: receive positions and pongs, ping, send frames.

    ``entry_delays`` holds the round trips (ms) of the connection's clock exchanges until the
    person's entry is judged, ``entry_start_s`` when the first's request arrived (s, the
    server's clock) and ``window_px`` the page's window as it last said it; ``interrupted`` the
    kinds of interruption that began during a trial and have not ended.
    """

    def __init__(
        self, lab: Lab, session: LabSession, participant: Participant, websocket: WebSocket
    ) -> None:
        settings = lab.settings
        self.lab = lab
        self.settings = settings
        self.screening = online_of(session).screening
        self.entry_delays: list[float] = []
        self.entry_start_s = math.inf
        self.window_px: tuple[int, int] | None = None
        self.interrupted: set[str] = set()
        self.session = session
        self.participant = participant
        self.websocket = websocket
        self.pings = Pings()
        self.outbox = Outbox(Peer(websocket, settings.send_timeout, participant.label))
        self.play = PlayScreen(lab, session, participant, self.outbox)
        self.inbox = Inbox(
            websocket,
            parse_participant_message,
            settings.max_message_rate,
            settings.max_rejected,
            lambda problem: self.outbox.put({"type": "error", "message": problem}),
            lambda: self.outbox.end(CLOSE_POLICY, "too many bad messages"),
        )

    async def run(self) -> None:
        """Serve the page until it closes or the session ends."""
        self.participant.pings = self.pings
        self.session.attach(self.participant, self.outbox, self.websocket)
        pinger = asyncio.get_running_loop().create_task(self._ping())
        try:
            await self._receive()
        finally:
            pinger.cancel()
            if self.outbox.ending:
                await self.outbox.ended()
            self.session.detach(self.participant, self.outbox)
            self.outbox.close()  # also when a newer page of the slot replaced this one

    async def _ping(self) -> None:
        while True:
            self.outbox.put({"type": "ping", "id": self.pings.send()})
            await asyncio.sleep(self.settings.ping_interval)

    async def _receive(self) -> None:
        async for message in self.inbox.messages():
            self._handle(message)

    def _handle(self, message: ParticipantMessage) -> None:
        participant = self.participant
        participant.last_heard = time.monotonic()
        received_ms = self.session.clock() * 1000.0
        source = participant.source
        if isinstance(message, ClockRequest | ClockReport | PointerBatch):
            if isinstance(source, BrowserInput):
                self._clocked(source, message, received_ms)
        elif isinstance(message, FocusChange):
            if isinstance(source, BrowserInput):
                self._focus(source, message, received_ms)
        elif isinstance(message, WindowSize):
            self.window_px = (message.width, message.height)
        elif isinstance(message, Answer):
            problem = self.session.answer(participant, message)
            if problem is not None:
                self.outbox.put({"type": "error", "message": problem})
        elif isinstance(message, Shown):
            if isinstance(source, BrowserInput):
                pairs = zip(message.k, message.t_ms, strict=True)
                drawn = [(k, t, source.clock.to_server(t)) for k, t in pairs]
                self.session.shown(participant, drawn)
        elif isinstance(message, Pong):
            self.pings.answer(message.id)
            participant.late_frames = message.late_frames
        else:
            if isinstance(message, AvatarPosition):
                self.session.page_step(participant, message.step)
                message = message.position
            if isinstance(source, BrowserInput):
                source.put(message.x, message.seq)

    def _clocked(
        self,
        source: BrowserInput,
        message: ClockRequest | ClockReport | PointerBatch,
        received_ms: float,
    ) -> None:
        """Answer a clock request, complete an exchange or store a batch of timed samples."""
        if isinstance(message, ClockRequest):
            self.outbox.put_timed(lambda: self._clock_reply(source, message, received_ms))
        elif isinstance(message, ClockReport):
            exchange = source.clock.complete(message.id, message.t3)
            if exchange is not None:
                self._screen_entry(source, exchange.delay, exchange.t1 / 1000.0)
                self.play.exchange(exchange.delay)
        else:
            source.put_batch(message.seq, message.sent_ms, message.samples, received_ms / 1000.0)
            self.play.frame(source, message.sent_ms, received_ms / 1000.0, self.window_px)

    def _clock_reply(
        self, source: BrowserInput, request: ClockRequest, received_ms: float
    ) -> dict[str, object]:
        """Answer a clock request as the answer leaves: its receipt and send times (ms)."""
        sent_ms = self.session.clock() * 1000.0
        source.clock.answer(request.id, request.t0, received_ms, sent_ms)
        times = {"t0": request.t0, "t1": received_ms, "t2": sent_ms}
        return {"type": "clock", "id": request.id} | times

    def _screen_entry(self, source: BrowserInput, delay_ms: float, received_s: float) -> None:
        """Judge the person's entry on their page's first `ENTRY_EXCHANGES` clock exchanges.

        ``delay_ms`` is an exchange's round trip (ms), ``received_s`` when its request arrived
        (s, the server's clock): the frame rate is counted from the first's to the last's.
        Judged once a person: a page that reconnects is not judged again.
        """
        participant = self.participant
        if not self.screening.at_entry or participant.entry_rtt_p95_ms is not None:
            return
        self.entry_delays.append(delay_ms)
        self.entry_start_s = min(self.entry_start_s, received_s)
        if len(self.entry_delays) < ENTRY_EXCHANGES:
            return
        rate = source.rates(self.entry_start_s, received_s)["frame_rate_hz"]
        frames = float(rate) if isinstance(rate, int | float) else None
        entry = Entry(self.entry_delays, frames, self.window_px)
        p95 = participant.entry_rtt_p95_ms = round_trip_p95(entry.delays_ms)
        reason = entry_refusal(entry, self.screening)
        if reason is None:
            said = f"round trip p95 {p95:.0f} ms, {entry.frame_rate_hz or 0:.0f} frames/s"
            window = "" if entry.window_px is None else ", window {}x{} px".format(*entry.window_px)
            self.session.log(f"{participant.label} admitted: {said}{window}")
            return
        rules = ("hidden_tab", "during_play")
        bounds = {k: v for k, v in asdict(self.screening).items() if k not in rules}
        self.lab.refuse(participant.key, reason, entry.measured() | {"bounds": bounds})

    def _focus(self, source: BrowserInput, change: FocusChange, received_ms: float) -> None:
        """Record the page's tab hidden or shown, its window blurred or focused.

        Its time is the page's, mapped onto the server's clock (the receipt's before the first
        clock exchange). An interruption that begins during a trial is logged, and refuses the
        person when it is a hidden tab and the protocol says so; when it ends, the person is
        told `BACK_NOTICE`.
        """
        at_s = source.clock.to_server(change.t_ms)
        at_s = received_ms / 1000.0 if math.isnan(at_s) else at_s
        ended = source.interruptions.event(change.event, at_s)
        if change.event == "hidden":
            self.play.hidden(source, at_s)
        participant, trial = self.participant, self.session.playing_in(self.participant)
        if change.event in KINDS and trial is not None and change.event not in self.interrupted:
            self.interrupted.add(change.event)
            self.session.log(f"{participant.label}: {change.event} during trial {trial.n}")
            if change.event == "hidden" and self.screening.hidden_tab == "refuse":
                measured = {"trial": trial.n, "hidden_at_s": at_s}
                self.lab.refuse(participant.key, HIDDEN_REFUSAL, measured)
        elif ended is not None and ended[0] in self.interrupted:
            self.interrupted.discard(ended[0])
            kind, start_s, end_s = ended
            self.session.log(f"{participant.label}: back after {end_s - start_s:.1f} s ({kind})")
            self.outbox.put({"type": "notice", "message": BACK_NOTICE})
