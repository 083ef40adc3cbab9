"""Pilots of a study: virtual participants play a protocol through the real lab server.

`run_pilot` starts ``mirror-avatar lab --protocol FILE`` in a process of its own on loopback
and, for each participant in turn, does what the researcher and the people would: creates the
participant's run through the researcher's API, joins every person's slot with a `StandIn` -
a virtual participant's page over a WebSocket -, starts the run and waits for its end. The
server records everything as it does for people, so the folders are those of a real study.

A stand-in's page does what a browser's does (`StandIn.animate`, on animation frames 60 times a
second of its own clock, `_animate`): each ``frame`` the server sends holds its own position and
its visible partners' (delayed, hidden, held to a due time or predicted as the condition's
partner view says, by the server: `mirror_avatar.lab.running.partner_frames`); the page draws
the newest due on each animation frame and reports what it drew
(`mirror_avatar.lab.running.stand_in_page.PageDisplay`; a hidden partner is not drawn). The
stand-in is any player SPEC (`mirror_avatar.specs.load_player`) in the role its page is told,
stepped once per control period of the page's clock from the trial's ``go``: the partners drawn
at that moment are its observation, and the positions it reaches are sent as the pointer's, each
with the page time it was reached at (`mirror_avatar.lab.running.stand_in_page.pointer_batches`).
Questions are answered by an `AnswerRule` per question. Its page keeps its clock against the
server's as a browser's does (`_exchange_clocks`), so its round trips and offset are recorded in
each trial's sidecar, its draws are placed on the server's clock (each trial's
``trial-NN_view.csv``) and it is screened at entry as a person is.

The stand-ins are checked as a protocol's avatars are (`check_stand_ins`: each built and dry-run
in every role its person plays, by `mirror_avatar.lab.design.avatars.load_avatar`) before the
server starts, so that a spec naming a device, a FIFO, a huge file or a diverging partner is
refused in one line naming the stand-in, and nothing is started or written.

Under declared networks (`mirror_avatar.lab.running.pilot_network`: one for every person, or
one per person) the stand-ins' pages reach the server through emulated internets, as
participants at home would; the researcher's API does not. Their truth logs are in the output
folder.

Participants' runs are played in turn, or several at once (``at_once``) against the one
server, as a lab runs several sessions: each participant's stand-ins, seeds and answers are
the same however many play beside them, so only the timing (the machine's load, the network's
draws) differs.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Awaitable, Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit, urlunsplit

import httpx
import numpy as np
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.interruptions import run_interruptible
from mirror_avatar.common.seeds import spawn_seeds
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.files.importing import excerpt
from mirror_avatar.lab.design.avatars import load_avatar
from mirror_avatar.lab.design.plan import MAX_SPEC_CHARS, SessionPlan
from mirror_avatar.lab.design.protocol import Protocol, load_protocol
from mirror_avatar.lab.running.pilot_network import emulated_internets
from mirror_avatar.lab.running.screening import ENTRY_EXCHANGES
from mirror_avatar.lab.running.stand_in_answers import AnswerRule, check_rules, right_guesses
from mirror_avatar.lab.running.stand_in_page import PageDisplay, next_frame_ms, pointer_batches
from mirror_avatar.players.base import Observation, Player
from mirror_avatar.remote.network import Network

PLAYER_ROLES = {"solo": "leader"}
"""The role preset a stand-in plays for a page's role where they differ (alone: it leads)."""

START_TIMEOUT = 120.0
"""Seconds the lab server may take to start (it imports and compiles its kernels)."""

SLACK = 60.0
"""Seconds a participant's run may take beyond its planned time before the pilot gives up."""


@dataclass
class StandIn:
    """A virtual participant's page: a player SPEC stepping on the partners the page draws.

    Parameters
    ----------
    label
        The person's label in the protocol (its slot).
    spec
        The player SPEC standing in for the person.
    seed
        The stand-in's seed: trial n's player is reset with the n-th seed spawned from it, its
        random answers drawn from it.
    answers
        The rule for each question id; `AnswerRule()` (random) for the others.
    right
        The right person-or-computer guess about the person's partners in each trial
        (`mirror_avatar.lab.running.stand_in_answers.right_guesses`), for a ``detect`` rule.
    """

    label: str
    spec: str
    seed: int
    answers: Mapping[str, AnswerRule] = field(default_factory=dict)
    right: Mapping[int, str | None] = field(default_factory=dict)
    role: str = "waiting"
    player: Player | None = None
    display: PageDisplay = field(default_factory=PageDisplay)
    _players: dict[str, Player] = field(default_factory=dict)
    _seen: dict[int, float] = field(default_factory=dict)
    _x: float = 0.0
    _steps: int = 0
    _next_step_ms: float | None = None
    _sent: int = 0
    _rng: np.random.Generator = field(init=False)

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(spawn_seeds(self.seed, 1)[0])

    def welcome(self, message: Mapping[str, Any]) -> None:
        """Take the page's slot and role (sent on joining and as each condition begins)."""
        self.role = str(message["role"])
        if self.role == "waiting":
            self.player = None
            return
        role = PLAYER_ROLES.get(self.role, self.role)
        if role not in self._players:
            self._players[role] = _warmed(load_avatar(self.spec, role))
        self.player = self._players[role]

    def countdown(self) -> None:
        """Start the next trial's drawing afresh, as a page does at its countdown."""
        self.display.clear()

    def start(self, trial: int, t_ms: float) -> None:
        """Reset the player for trial ``trial`` at page time ``t_ms`` (ms), if the stand-in plays.

        Its steps are then due every control period after ``t_ms``, on the page's clock.
        """
        if self.player is None:
            return
        self._seen.clear()
        self._x, _ = self.player.reset(seed=int(spawn_seeds(self.seed, trial)[trial - 1]))
        self._steps = 0
        self._next_step_ms = t_ms + CONTROL_PERIOD * 1000.0

    def stop(self) -> None:
        """Stop stepping at a trial's end (the point stays where it is)."""
        self._next_step_ms = None

    def animate(self, t_ms: float) -> list[str]:
        """Do a page's animation frame at page time ``t_ms`` (ms); return the messages to send.

        The display draws the frames due; the player takes each step due by ``t_ms`` on the
        partners drawn now; the positions reached are sent as the pointer's, read at their
        steps' times (the position now when none was, as a page sends its pointer's when it
        did not move), and the frames drawn are reported.
        """
        self.display.draw(t_ms)
        if self.player is None:
            return self.display.reports()
        read = []
        while self._next_step_ms is not None and self._next_step_ms <= t_ms:
            self._x = self._step()
            read.append((self._next_step_ms, self._x))
            self._next_step_ms += CONTROL_PERIOD * 1000.0
        batches = pointer_batches(read or [(t_ms, self._x)], t_ms, self._sent)
        self._sent += len(batches)
        return [*map(json.dumps, batches), *self.display.reports()]

    def _step(self) -> float:
        """Step the player on the partners drawn now; return its position (units)."""
        assert self.player is not None
        partners = dict(self.display.partners)
        positions = np.array(list(partners.values()), dtype=float)
        previous = np.array([self._seen.get(j, x) for j, x in partners.items()], dtype=float)
        velocities = (positions - previous) / CONTROL_PERIOD
        self._seen = partners
        self._steps += 1
        observation = Observation(self._steps - 1, positions, velocities, previous)
        return float(self.player.step(observation)[0])

    def reply(self, message: Mapping[str, Any]) -> list[str]:
        """Return the answer messages to a ``questions`` message."""
        return [
            json.dumps(
                {
                    "type": "answer",
                    "trial": message["trial"],
                    "question": question["id"],
                    "value": self.answers.get(question["id"], AnswerRule()).answer(
                        question, self._rng, self.right.get(int(message["trial"]))
                    ),
                }
            )
            for question in message["questions"]
        ]


def _warmed(player: Player) -> Player:
    """Step ``player`` once off the clock, so that its kernels are compiled before a trial."""
    player.reset(seed=0)
    player.step(Observation.of_partner(0, 0.0, 0.0, 0.0))
    return player


async def play_page(url: str, stand_in: StandIn) -> str:
    """Join by the WebSocket ``url`` as ``stand_in`` and play until the session ends.

    Returns
    -------
    str
        The session's last state (``finished`` or ``aborted``), or ``closed``.

    Raises
    ------
    InputError
        The stand-in was screened out (its page sent ``refused``).
    """
    async with connect(url, proxy=None, open_timeout=30, max_queue=None) as ws:
        await ws.send(json.dumps({"type": "window", "width": WINDOW_PX[0], "height": WINDOW_PX[1]}))
        clock = asyncio.create_task(_exchange_clocks(ws))
        animation = asyncio.create_task(_animate(ws, stand_in))
        try:
            async for text in ws:
                message = json.loads(text)
                kind = message["type"]
                if kind == "welcome":
                    await asyncio.to_thread(stand_in.welcome, message)
                if kind == "refused":
                    raise InputError(
                        f"--stand-in {stand_in.label}",
                        f"screened out by the protocol's [online] screening: {message['message']} "
                        "(pilot under a --network within it, or loosen the screening)",
                    )
                for reply in _answer(stand_in, message):
                    await ws.send(reply)
                if kind == "state" and message["state"] in ("finished", "aborted"):
                    return str(message["state"])
        except ConnectionClosed:
            pass
        finally:
            for task in (clock, animation):
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await task
    return "closed"


WINDOW_PX = (1280, 720)
"""The window (CSS pixels) a stand-in's page says it has as it connects: a laptop's browser."""

CLOCK_BURST_S = 0.02
"""Seconds between a page's first `ENTRY_EXCHANGES` clock exchanges (``BURST_MS`` in
``clock.js``)."""

CLOCK_EVERY_S = 0.1
"""Seconds between a page's clock exchanges after them (``REQUEST_MS`` in ``clock.js``)."""


def page_ms() -> float:
    """Return a stand-in page's clock (ms): the wall clock, as a browser's page time is."""
    return time.time() * 1000.0


async def _exchange_clocks(ws: Any) -> None:
    """Ask the server's time as a participant's page does (``clock.js``), until the socket closes.

    The first `ENTRY_EXCHANGES` are `CLOCK_BURST_S` apart (the protocol's screening judges the
    stand-in on them, as a person), then one every `CLOCK_EVERY_S`; the server's answers are
    reported by `_answer`, and the round trips and offset go into each trial's sidecar.
    """
    with contextlib.suppress(ConnectionClosed):
        for n in itertools.count(1):
            await ws.send(json.dumps({"type": "clock", "id": n, "t0": page_ms()}))
            await asyncio.sleep(CLOCK_BURST_S if n < ENTRY_EXCHANGES else CLOCK_EVERY_S)


async def _animate(ws: Any, stand_in: StandIn) -> None:
    """Run the page's animation frames until the socket closes.

    Each animation frame (`mirror_avatar.lab.running.stand_in_page.next_frame_ms`, on the
    page's clock from the moment it connected) runs `StandIn.animate` at the page time it
    actually runs at, and sends its messages.
    """
    start = page_ms()
    with contextlib.suppress(ConnectionClosed):
        while True:
            now = page_ms()
            await asyncio.sleep((next_frame_ms(start, now) - now) / 1000.0)
            for message in stand_in.animate(page_ms()):
                await ws.send(message)


def _answer(stand_in: StandIn, message: Mapping[str, Any]) -> list[str]:
    """Return what a page sends back to one server message."""
    kind = message["type"]
    if kind == "ping":
        return [json.dumps({"type": "pong", "id": message["id"], "late_frames": 0})]
    if kind == "clock":
        return [json.dumps({"type": "clocked", "id": message["id"], "t3": page_ms()})]
    if kind == "countdown":
        stand_in.countdown()
    if kind == "go":
        stand_in.start(int(message["trial"]), page_ms())
    if kind == "end":
        stand_in.stop()
    if kind == "frame":
        stand_in.display.receive(message)
    if kind == "questions":
        return stand_in.reply(message)
    return []


SERVER_ENTRY = (
    "import logging, signal; signal.signal(signal.SIGTERM, signal.SIG_IGN); "
    "logging.basicConfig(format='%(asctime)s %(levelname)s %(name)s: %(message)s'); "
    "logging.getLogger('mirror_avatar.lab').setLevel(logging.INFO); "
    "from mirror_avatar.console import run; run()"
)
"""How the pilot starts its lab server: the console script with SIGTERM ignored, which is the
pilot's normal stop (uvicorn shuts down on it and then leaves the ignored signal be, so the
server finishes with exit code 0); SIGINT is its stop when the pilot is interrupted or fails (the
server's log then ends ``aborted (SIGINT)``). The sessions' events (a page joined, a trial
started or ended, all trials played: `mirror_avatar.lab.running.runner.LabSession.log`) go to
its log, each with its time, beside uvicorn's lines, so that the log says when each
participant's run played."""

STOP_TIMEOUT = 30.0
"""Seconds the lab server may take to shut down before it is killed."""


@contextlib.contextmanager
def lab_server(protocol_file: Path, out_dir: Path, log: Path) -> Iterator[tuple[str, str]]:
    """Run ``mirror-avatar lab --protocol`` on loopback; yield its base URL and token.

    Its output goes to ``log``. On leaving it is stopped: as finished (SIGTERM), or as aborted
    (SIGINT) when leaving by an exception (`SERVER_ENTRY`).
    """
    command = [
        sys.executable,
        "-c",
        SERVER_ENTRY,
        "lab",
        "--host",
        "127.0.0.1",
        "--port",
        "0",
        "--out",
        str(out_dir),
        "--no-lsl",
        "--protocol",
        str(protocol_file),
    ]
    with log.open("w") as sink:
        process = subprocess.Popen(
            command,
            stdout=subprocess.PIPE,
            stderr=sink,
            text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
    try:
        yield _console_link(process, log)
    except BaseException:
        _stop(process, signal.SIGINT)
        raise
    _stop(process, signal.SIGTERM)


def _stop(process: subprocess.Popen[str], signum: int) -> None:
    """Send ``signum`` to the lab server and wait for its end (killed after `STOP_TIMEOUT`)."""
    process.send_signal(signum)
    try:
        process.wait(STOP_TIMEOUT)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
    if process.stdout is not None:
        process.stdout.close()


def _console_link(process: subprocess.Popen[str], log: Path) -> tuple[str, str]:
    """Read the server's output until its console link; keep draining it afterwards."""
    lines: queue.Queue[str] = queue.Queue()

    def drain() -> None:
        assert process.stdout is not None
        for line in process.stdout:
            lines.put(line)
        lines.put("")

    threading.Thread(target=drain, daemon=True).start()
    deadline = time.monotonic() + START_TIMEOUT
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=1.0)
        except queue.Empty:
            continue
        if found := re.search(r"console: (http://[^/\s]+)/console\?token=(\S+)", line):
            return found.group(1), found.group(2)
        if not line:
            break
    last = log.read_text(errors="replace").strip().splitlines()[-1:] or ["no output"]
    raise InputError(str(log), f"the lab server did not start: {last[0]}")


async def pilot_participant(
    api: httpx.AsyncClient,
    number: int,
    stand_ins: Mapping[str, StandIn],
    planned_s: float,
    join_at: Mapping[str, str] | None = None,
    screened: bool = False,
) -> dict[str, Any]:
    """Play participant ``number``'s run with the stand-ins; return its final status.

    ``join_at`` is the base URL each person's stand-in page joins at (default: the server's
    own, as its join links give it; an emulated internet's to join through it). With
    ``screened`` (the protocol screens round trips at entry), the run starts once every
    stand-in is judged.

    Raises
    ------
    InputError
        When a person of the run has no stand-in, the run cannot start, or it does not end
        within its planned time and `SLACK`.
    """
    created = await api.post("/api/sessions", json={"participant": number})
    if not created.is_success:
        raise InputError(f"participant {number}", _refusal(created))
    status = created.json()
    missing = sorted(set(status["links"]) - set(stand_ins))
    if missing:
        raise InputError("--stand-in", f"no stand-in for {', '.join(missing)}: add LABEL=SPEC")
    for link in status["links"].values():
        await _agree(api, link)
    pages = [
        asyncio.create_task(
            play_page(_socket_url(link, (join_at or {}).get(label)), stand_ins[label])
        )
        for label, link in status["links"].items()
    ]
    try:
        await _wait_ready(api, status["id"], pages, screened)
        started = await api.post(f"/api/sessions/{status['id']}/start", json={})
        if not started.is_success:
            raise InputError(f"participant {number}", _refusal(started))
        ended, late = await asyncio.wait(
            pages, timeout=planned_s + SLACK, return_when=asyncio.FIRST_EXCEPTION
        )
        for page in ended:
            page.result()
        if late:
            raise InputError(
                f"participant {number}", f"the run did not end within {planned_s + SLACK:.0f} s"
            )
    finally:
        for page in pages:
            page.cancel()
        await asyncio.gather(*pages, return_exceptions=True)
    return dict((await api.get(f"/api/sessions/{status['id']}")).json())


async def _agree(api: httpx.AsyncClient, link: str) -> None:
    """Agree on the link's consent page, if the protocol has one, as its participant would.

    The stand-in's agreement is recorded as a person's is (`mirror_avatar.lab.running.consent`).
    """
    path = urlsplit(link).path
    intro = (await api.get(f"{path}/intro")).json()
    if intro.get("consent") is not None and not intro.get("consented"):
        answer = await api.post(f"{path}/consent", json={"agree": True})
        if not answer.is_success:
            raise InputError(link.split("/join/")[0], _refusal(answer))


def _refusal(response: httpx.Response) -> str:
    try:
        return str(response.json().get("error", response.text))
    except ValueError:
        return response.text.strip() or f"HTTP {response.status_code}"


def _socket_url(link: str, join_base: str | None = None) -> str:
    """Return a join link's WebSocket URL, at the base URL ``join_base`` when given."""
    parts = urlsplit(link if join_base is None else join_base + urlsplit(link).path)
    return urlunsplit(("ws", parts.netloc, parts.path.replace("/join/", "/ws/join/"), "", ""))


async def _wait_ready(
    api: httpx.AsyncClient,
    sid: str,
    pages: list[asyncio.Task[str]],
    screened: bool,
    timeout: float = 60.0,
) -> None:
    """Wait until every stand-in's page is connected and, when ``screened``, judged at entry.

    Raises
    ------
    InputError
        A stand-in was screened out (its page's refusal), or the pages were not ready within
        ``timeout`` (s).
    """
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for page in pages:
            if page.done():
                page.result()
        slots = (await api.get(f"/api/sessions/{sid}")).json()["slots"]
        if all(_ready(slot, screened) for slot in slots):
            return
        await asyncio.sleep(0.1)
    raise InputError(f"session {sid}", f"the stand-ins did not join within {timeout:.0f} s")


def _ready(slot: Mapping[str, Any], screened: bool) -> bool:
    """Whether a slot of a session's status is ready to start (an avatar's or a hidden one is)."""
    if "joined" not in slot:
        return True
    judged = not screened or slot["entry_rtt_p95_ms"] is not None
    return bool(slot["connected"]) and judged


COUNTDOWN_S = 3.0
"""Seconds of countdown before each trial (`mirror_avatar.lab.running.runner.LabSession`'s
default)."""


def planned_seconds(protocol: Protocol) -> float:
    """Return how long one participant's run is planned to take (s): trials, countdowns, pauses."""
    defaults = {f.name: f.default for f in fields(SessionPlan)}
    total = 0.0
    for block in protocol.blocks:
        for condition in block.conditions:
            duration = float(condition.settings.get("duration", defaults["duration"]))
            pause = float(condition.settings.get("pause", defaults["pause"]))
            total += condition.trials * (COUNTDOWN_S + duration + pause)
    return total


def person_roles(protocol: Protocol) -> dict[str, set[str]]:
    """Return the roles each person of a protocol plays, as their stand-in plays them."""
    roles: dict[str, set[str]] = {label: set() for label in protocol.people}
    for block in protocol.blocks:
        for condition in block.conditions:
            plan = condition.with_avatars()
            for player, role in zip(condition.players, plan.roles, strict=True):
                if player.kind != "avatar":
                    roles[player.label].add(PLAYER_ROLES.get(role, role))
    return roles


def check_stand_ins(protocol: Protocol, stand_ins: Mapping[str, str]) -> None:
    """Check that every stand-in names a person and plays each of their roles.

    Each spec is built and dry-run in every role its person plays (`person_roles`) as a
    protocol's avatars are (`mirror_avatar.lab.design.avatars.load_avatar`).

    Raises
    ------
    InputError
        ``--stand-in: LABEL=SPEC: problem (fix)`` for a label that is no person of the
        protocol, a spec longer than `MAX_SPEC_CHARS`, or one that cannot be read, built or
        dry-run (a device, a FIFO, a file too large, a parameter out of its range, ...).
    """
    unknown = sorted(set(stand_ins) - set(protocol.people))
    if unknown:
        raise InputError(
            "--stand-in",
            f"{', '.join(unknown)}: no such person in {Path(protocol.source).name} "
            f"(its people: {', '.join(protocol.people)})",
        )
    roles = person_roles(protocol)
    for label, spec in stand_ins.items():
        named = f"{label}={excerpt(spec, quote=False)}"
        if len(spec) > MAX_SPEC_CHARS:
            raise InputError(
                "--stand-in", f"{named}: over {MAX_SPEC_CHARS} characters (give a shorter SPEC)"
            )
        for role in sorted(roles[label]):
            try:
                load_avatar(spec, role)
            except InputError as error:
                raise InputError(
                    "--stand-in", f"{named}: {error} (give another SPEC for {label})"
                ) from None


def run_pilot(
    protocol_file: Path,
    out_dir: Path,
    participants: range,
    stand_ins: Mapping[str, str],
    seed: int,
    answers: Mapping[str, AnswerRule] | None = None,
    on_done: Callable[[int, dict[str, Any]], None] | None = None,
    networks: Mapping[str, Network] | None = None,
    at_once: int = 1,
) -> list[dict[str, Any]]:
    """Play ``participants``' runs of a protocol with virtual participants.

    Parameters
    ----------
    protocol_file
        The study protocol (TOML), served as ``mirror-avatar lab --protocol`` serves it.
    out_dir
        Where the server records (``OUT/<protocol>-pNNN/`` per participant); the server's log
        is ``OUT/pilot-server.log``.
    participants
        The participants' numbers.
    stand_ins
        The player SPEC standing in for each person's label of the protocol.
    seed
        The pilot's seed: the stand-in for person ``j`` of participant ``p`` is seeded with
        ``spawn_seeds([seed, p], len(people))[j]``.
    answers
        The rule for each question id (default: random answers).
    on_done
        Called with each participant's number and final status as their run ends.
    networks
        The emulated internets between the stand-ins' pages and the server, by person
        (`mirror_avatar.lab.running.pilot_network.parse_networks`: seeded from ``seed``, their
        truth in ``OUT/``), or None for none.
    at_once
        How many participants' runs play at the same time, each starting as one ends, in the
        order of their numbers (1: in turn).

    Returns
    -------
    list of dict
        Each participant's final status (as ``GET /api/sessions/ID`` answers), in the order of
        ``participants``.

    Raises
    ------
    InputError
        A stand-in refused (`check_stand_ins`), before the server starts; a run that cannot
        start or end (`pilot_participant`), which ends the runs playing beside it.
    """
    protocol = load_protocol(protocol_file)
    check_stand_ins(protocol, stand_ins)
    check_rules(protocol, answers or {})
    out_dir.mkdir(parents=True, exist_ok=True)
    planned = planned_seconds(protocol)
    with (
        lab_server(protocol_file, out_dir, out_dir / "pilot-server.log") as (base, token),
        emulated_internets(networks or {}, base, out_dir, seed, protocol.people) as join_at,
    ):
        pilot = Pilot(protocol, stand_ins, seed, answers or {}, planned, join_at)
        return run_interruptible(pilot.play_all(base, token, participants, at_once, on_done))


@dataclass(frozen=True)
class Pilot:
    """What every participant's run of a pilot shares (`run_pilot` says what each is)."""

    protocol: Protocol
    stand_ins: Mapping[str, str]
    seed: int
    answers: Mapping[str, AnswerRule]
    planned: float
    join_at: Mapping[str, str]

    def people(self, number: int) -> dict[str, StandIn]:
        """Return participant ``number``'s stand-ins by label, seeded as `run_pilot` says."""
        seeds = spawn_seeds([self.seed, number], len(self.protocol.people))
        return {
            label: StandIn(
                label,
                self.stand_ins[label],
                int(seeds[j]),
                self.answers,
                right_guesses(self.protocol, number, label),
            )
            for j, label in enumerate(self.protocol.people)
            if label in self.stand_ins
        }

    async def play_all(
        self,
        base: str,
        token: str,
        participants: Iterable[int],
        at_once: int,
        on_done: Callable[[int, dict[str, Any]], None] | None,
    ) -> list[dict[str, Any]]:
        """Play the participants' runs through the server at ``base``, ``at_once`` at a time."""
        headers = {"Authorization": f"Bearer {token}"}
        screened = self.protocol.online.screening.at_entry
        turns = asyncio.Semaphore(at_once)

        async def play(api: httpx.AsyncClient, number: int) -> dict[str, Any]:
            async with turns:
                status = await pilot_participant(
                    api, number, self.people(number), self.planned, self.join_at, screened
                )
            if on_done is not None:
                on_done(number, status)
            return status

        async with httpx.AsyncClient(base_url=base, headers=headers, timeout=30.0) as api:
            return await all_or_none([play(api, number) for number in participants])


async def all_or_none(runs: Iterable[Awaitable[dict[str, Any]]]) -> list[dict[str, Any]]:
    """Await ``runs`` together; return their results in order.

    The first to fail cancels the others, and its exception is raised once they have ended.
    """
    tasks = [asyncio.ensure_future(run) for run in runs]
    try:
        return list(await asyncio.gather(*tasks))
    finally:
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
