"""A lab session's plan: the condition, who plays (people and avatars), who sees whom, the trials.

The researcher's console sends a plan as JSON (`parse_plan`); the server keeps it, with the
seed it drew, in the session's ``plan.json``. Conditions (METHODS section 9):

- ``solo``: every person plays alone (no coupling; people only).
- ``leader_follower``: two players; the one in ``leaders`` leads, the other follows.
- ``joint``: two players improvising together.
- ``group``: N >= 2 players on a graph (a topology name or an adjacency matrix); players in
  ``leaders`` take the group-leader role.

A slot is a person (``kind: "human"``; ``device: "pointer"`` - mouse, touch or keyboard on the
participant's page - or ``"lsl"``, an LSL stream with its channel and unit mapping) or an avatar
(``kind: "avatar"``; ``spec`` any player spec, `mirror_avatar.specs.load_player`; ``runs``
``"server"``, the default, or ``"browser"``: stepped in the page of the dyad's one person, `RUNS`).
The graph is also who sees whom on the participants' pages.
"""

from __future__ import annotations

import secrets
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from mirror_avatar.common.constraints import ConstraintError, Flag, Interval, Options, Setting
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.user_files import is_int
from mirror_avatar.realtime.clock import MAX_LATENESS
from mirror_avatar.realtime.messages import PARTICIPANT_PATTERN
from mirror_avatar.sessions.graphs import TOPOLOGIES, Graph, check_graph, complete_graph, make_graph

CONDITIONS = ("solo", "leader_follower", "joint", "group")
"""Kinds of lab session."""

RUNS = ("server", "browser")
"""Where an avatar's player runs: stepped by the server's clock, or in its person's page
(`mirror_avatar.lab.running.page_avatar`; the kinds `mirror_avatar.browser.BROWSER_KINDS`)."""

DEVICES = ("pointer", "lsl")
"""A person's input devices: their page's pointer (mouse, touch, keyboard) or an LSL stream."""

MAX_PLAYERS = 16
"""Most players in one session."""

SEED_LIMIT = 2**63 - 1
"""Largest seed."""

MAX_SPEC_CHARS = 1024
"""Longest avatar spec or LSL stream name (characters)."""

TRIAL_SETTINGS = (
    Setting("trials", "trials of the condition", Interval(int, 1, 100), 1),
    Setting("duration", "length of each trial", Interval(float, 1.0, 600.0, unit="s"), 60.0),
    Setting("pause", "between a trial's end and the next countdown",
            Interval(float, 0.0, 600.0, unit="s"), 5.0),
    Setting("show_metrics", "the end screen shows the trial's metrics", Flag(), True),
    Setting("on_drop", "a trial whose person's connection drops: goes on (their position "
            "held) or stops", Options(("continue", "stop")), "continue"),
)  # fmt: skip
"""The plan's keys of its trials, declared once: a protocol's conditions take them as they are."""

SESSION_SETTINGS = (
    Setting("max_lateness", "how late a tick may come before the trial ends as unable to keep "
            "its clock", Interval(float, 0.03, 10.0, unit="s"), MAX_LATENESS),
    Setting("seed", "the session's seed; each trial's is spawned from it",
            Interval(int, 0, SEED_LIMIT), None),
)  # fmt: skip
"""The plan's other scalar keys (a seed left out is drawn)."""


class PlanError(InputError):
    """A plan refused: ``key`` is the plan's key at fault, ``what`` the problem, ``fix`` the fix.

    The message is ``plan: KEY: what (fix)``; callers (a protocol's checks) read the key and
    the problem from the attributes, never from the message.
    """

    def __init__(self, key: str, what: str, fix: str) -> None:
        self.key, self.what, self.fix = key, what, fix
        super().__init__("plan", f"{key}: {what} ({fix})")


@dataclass(frozen=True)
class LslDevice:
    """An LSL stream as a person's input device: position = ``offset + scale * value``.

    Attributes
    ----------
    stream
        The stream's name.
    channel
        The channel holding the position (0-based).
    scale, offset
        Unit mapping to the playing range: for a tracker in millimetres with 600 mm across the
        range, ``scale = 1/600``.
    source_id
        The stream's source id, to choose among streams of the same name (None: the name
        must be unique on the network).
    """

    stream: str
    channel: int = 0
    scale: float = 1.0
    offset: float = 0.0
    source_id: str | None = None


@dataclass(frozen=True)
class Slot:
    """One player of a lab session.

    Attributes
    ----------
    label
        The player's name (a participant id for people: letters, digits, ``_``, ``-``).
    kind
        ``"human"`` or ``"avatar"``.
    spec
        An avatar's player spec; None for people.
    device
        A person's device (`DEVICES`); None for avatars.
    lsl
        The LSL stream of a person whose device is ``"lsl"``.
    runs
        Where an avatar's player runs (`RUNS`); None for people.
    """

    label: str
    kind: str
    spec: str | None = None
    device: str | None = None
    lsl: LslDevice | None = None
    runs: str | None = None


@dataclass(frozen=True)
class SessionPlan:
    """What a lab session plays.

    Attributes
    ----------
    condition
        One of `CONDITIONS`.
    slots
        The players, in order (player k of every trial's session file).
    graph
        Who observes (and sees) whom, (N, N) of 0/1.
    leaders
        Indices of the leading players.
    duration
        Length of each trial (s).
    trials
        Number of trials.
    pause
        Seconds between the end of a trial and the next countdown.
    show_metrics
        Whether participants see the trial's metrics on their end screen.
    on_drop
        What a trial does when a person's connection drops: ``"continue"`` (their position is
        held, and the researcher may stop the trial) or ``"stop"``; an input that stops
        delivering (`mirror_avatar.realtime.inputs.LIVENESS_TIMEOUT`) counts as dropped.
    max_lateness
        Seconds a tick may come after its deadline before the trial is ended as unable to keep
        its clock (`mirror_avatar.realtime.clock.MAX_LATENESS` by default).
    seed
        The session's seed; trial n's seed is spawned from it.
    """

    condition: str
    slots: tuple[Slot, ...]
    graph: Graph
    leaders: tuple[int, ...] = ()
    duration: float = 60.0
    trials: int = 1
    pause: float = 5.0
    show_metrics: bool = True
    on_drop: str = "continue"
    max_lateness: float = MAX_LATENESS
    seed: int = field(default_factory=lambda: secrets.randbits(63))

    @property
    def n_players(self) -> int:
        """Number of players."""
        return len(self.slots)

    @property
    def roles(self) -> tuple[str, ...]:
        """Each player's role, from the condition and the leaders."""
        if self.condition == "solo":
            return ("solo",) * self.n_players
        if self.condition == "joint":
            return ("joint",) * self.n_players
        if self.condition == "leader_follower":
            return tuple("leader" if k in self.leaders else "follower" for k in range(2))
        return tuple(
            "group_leader" if k in self.leaders else "group" for k in range(self.n_players)
        )

    @property
    def humans(self) -> tuple[int, ...]:
        """Indices of the people."""
        return tuple(k for k, slot in enumerate(self.slots) if slot.kind == "human")

    def neighbours(self, k: int) -> list[int]:
        """Return the players player k observes (and sees on its page)."""
        return np.flatnonzero(self.graph[k]).tolist()

    def to_json(self) -> dict[str, Any]:
        """Return the plan as JSON (what `parse_plan` reads back)."""
        data = asdict(self)
        data["graph"] = self.graph.tolist()
        data["leaders"] = list(self.leaders)
        data["slots"] = [
            {key: value for key, value in asdict(slot).items() if value is not None}
            for slot in self.slots
        ]
        return data


def parse_plan(data: object) -> SessionPlan:
    """Validate a plan sent as JSON and return it.

    Parameters
    ----------
    data
        ``{"condition", "players": [slot...], "graph", "leaders", "duration", "trials",
        "pause", "show_metrics", "on_drop", "max_lateness", "seed"}``; all but ``condition`` and
        ``players`` are optional (graph: complete; one 60 s trial; 5 s pauses; metrics shown; a
        drop continues; `MAX_LATENESS`; a drawn seed).

    Raises
    ------
    PlanError
        ``plan: KEY: problem (fix)`` for the first problem found, with the key, problem and fix
        as attributes.
    """
    if not isinstance(data, dict):
        raise PlanError("plan", "must be a JSON object", 'send {"condition": ..., ...}')
    condition = data.get("condition")
    if condition not in CONDITIONS:
        raise PlanError(
            "condition", f"{condition!r} is not a condition", f"one of {', '.join(CONDITIONS)}"
        )
    players = data.get("players")
    if not isinstance(players, list) or not 1 <= len(players) <= MAX_PLAYERS:
        raise PlanError(
            "players", f"must be a list of 1 to {MAX_PLAYERS} slots", "list the players"
        )
    slots = tuple(_parse_slot(item, k) for k, item in enumerate(players))
    _check_labels(slots)
    n = len(slots)
    leaders = _parse_leaders(data.get("leaders", []), n)
    _check_condition(condition, slots, leaders)
    values = {setting.key: _read(setting, data) for setting in TRIAL_SETTINGS + SESSION_SETTINGS}
    seed = secrets.randbits(63) if values["seed"] is None else values["seed"]
    return SessionPlan(
        condition=condition,
        slots=slots,
        graph=_parse_graph(data.get("graph", "complete"), condition, n),
        leaders=leaders,
        duration=float(values["duration"]),
        trials=int(values["trials"]),
        pause=float(values["pause"]),
        show_metrics=bool(values["show_metrics"]),
        on_drop=str(values["on_drop"]),
        max_lateness=float(values["max_lateness"]),
        seed=int(seed),
    )


def _read(setting: Setting, data: dict[str, Any], where: str = "") -> Any:
    """Read a declared setting of the plan, refusing a value outside it as a `PlanError`."""
    try:
        return setting.read(data, where)
    except ConstraintError as error:
        raise PlanError(
            error.key, f"{error.value!r} is not allowed", f"give {error.constraint}"
        ) from None


LSL_SETTINGS = (
    Setting("channel", "the stream's channel read", Interval(int, 0, 1023), 0),
    Setting("scale", "position = offset + scale * value", Interval(float, -1e6, 1e6), 1.0),
    Setting("offset", "position = offset + scale * value", Interval(float, -1e6, 1e6), 0.0),
)  # fmt: skip
"""A person's LSL stream's scalar keys."""

LABEL_FIX = "1-32 letters, digits, '_' or '-', starting with a letter or digit"
"""How to write a player's label."""


def _parse_slot(item: object, k: int) -> Slot:
    where = f"players[{k}]"
    if not isinstance(item, dict):
        raise PlanError(where, "must be an object", '{"label": "P1", "kind": "human"}')
    label = item.get("label")
    if not isinstance(label, str) or not PARTICIPANT_PATTERN.fullmatch(label):
        raise PlanError(f"{where}.label", f"{label!r} is not a label", LABEL_FIX)
    kind = item.get("kind")
    if kind == "avatar":
        spec = item.get("spec")
        if not isinstance(spec, str) or not 0 < len(spec) <= MAX_SPEC_CHARS:
            raise PlanError(f"{where}.spec", "must name the avatar", "give a player spec")
        runs = item.get("runs", "server")
        if runs not in RUNS:
            raise PlanError(
                f"{where}.runs", f"{runs!r} is not where an avatar runs", "'server' or 'browser'"
            )
        return Slot(label, "avatar", spec=spec, runs=runs)
    if kind != "human":
        raise PlanError(f"{where}.kind", f"{kind!r} is not a kind of player", "'human' or 'avatar'")
    device = item.get("device", "pointer")
    if device not in DEVICES:
        raise PlanError(
            f"{where}.device", f"{device!r} is not a device", f"one of {', '.join(DEVICES)}"
        )
    lsl = _parse_lsl(item.get("lsl"), f"{where}.lsl") if device == "lsl" else None
    return Slot(label, "human", device=device, lsl=lsl)


def _parse_lsl(item: object, where: str) -> LslDevice:
    if not isinstance(item, dict):
        raise PlanError(where, "must give the stream", "{'stream': NAME, 'channel': 0, ...}")
    stream = item.get("stream")
    if not isinstance(stream, str) or not 0 < len(stream) <= MAX_SPEC_CHARS:
        raise PlanError(f"{where}.stream", "must be the stream's name", "name the LSL stream")
    channel, scale, offset = (_read(setting, item, where) for setting in LSL_SETTINGS)
    if scale == 0.0:
        raise PlanError(f"{where}.scale", "must not be 0", "give the units per stream value")
    source_id = item.get("source_id")
    if source_id is not None and not (
        isinstance(source_id, str) and 0 < len(source_id) <= MAX_SPEC_CHARS
    ):
        raise PlanError(f"{where}.source_id", "must be the stream's source id", "or leave it out")
    return LslDevice(stream, int(channel), float(scale), float(offset), source_id)


def _check_labels(slots: tuple[Slot, ...]) -> None:
    labels = [slot.label for slot in slots]
    for label in labels:
        if labels.count(label) > 1:
            raise PlanError("players", f"two players are labelled {label!r}", "relabel one")


def _parse_leaders(value: object, n: int) -> tuple[int, ...]:
    if not isinstance(value, list) or not all(is_int(k) and 0 <= k < n for k in value):
        raise PlanError("leaders", f"must be a list of player indices 0..{n - 1}", "e.g. [0]")
    return tuple(sorted(set(value)))


PLAYERS_FIX = "change the players to suit the game"
"""How to fix players that do not suit their condition."""


def _check_condition(condition: str, slots: tuple[Slot, ...], leaders: tuple[int, ...]) -> None:
    n = len(slots)
    if condition == "solo" and any(slot.kind == "avatar" for slot in slots):
        raise PlanError("players", "a solo session has people only", PLAYERS_FIX)
    if condition in ("leader_follower", "joint") and n != 2:
        raise PlanError("players", f"{condition} needs exactly two players", PLAYERS_FIX)
    if condition == "leader_follower" and len(leaders) != 1:
        raise PlanError(
            "leaders", "leader_follower needs exactly one leader", "name one leader by its player"
        )
    if condition == "group" and n < 2:
        raise PlanError("players", "a group needs at least two players", PLAYERS_FIX)
    if not any(slot.kind == "human" for slot in slots):
        raise PlanError("players", "a lab session needs at least one person", PLAYERS_FIX)
    in_page = [slot.label for slot in slots if slot.runs == "browser"]
    if in_page and (n != 2 or len(in_page) != 1):
        raise PlanError(
            "players",
            f"{in_page[0]} runs in the browser, which needs a dyad of one person and that avatar "
            "(the person's page steps it)",
            "set runs = 'server', or make the game a person and this avatar",
        )


def _parse_graph(value: object, condition: str, n: int) -> Graph:
    if condition == "solo":
        return np.zeros((n, n), dtype=np.int8)
    if condition != "group":
        return complete_graph(n)
    fix = "a topology name or an adjacency matrix"
    if isinstance(value, str):
        if value not in TOPOLOGIES or value == "random":
            shown = ", ".join(t for t in TOPOLOGIES if t != "random")
            raise PlanError("graph", f"{value!r} is not one of {shown}", fix)
        return make_graph(value, n)
    try:
        return check_graph(value, n)  # type: ignore[arg-type]
    except InputError as error:
        raise PlanError("graph", error.problem, fix) from None
