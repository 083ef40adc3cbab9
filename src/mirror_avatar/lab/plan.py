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
(``kind: "avatar"``; ``spec`` any player spec, `mirror_avatar.specs.load_player`). The graph is
also who sees whom on the participants' pages.
"""

from __future__ import annotations

import math
import secrets
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from mirror_avatar.errors import InputError
from mirror_avatar.graphs import TOPOLOGIES, Graph, check_graph, complete_graph, make_graph
from mirror_avatar.realtime.clock import MAX_LATENESS
from mirror_avatar.realtime.messages import PARTICIPANT_PATTERN
from mirror_avatar.user_files import is_int

CONDITIONS = ("solo", "leader_follower", "joint", "group")
"""Kinds of lab session."""

DEVICES = ("pointer", "lsl")
"""A person's input devices: their page's pointer (mouse, touch, keyboard) or an LSL stream."""

MAX_PLAYERS = 16
"""Most players in one session."""

DURATION_RANGE = (1.0, 600.0)
"""Shortest and longest trial (s)."""

MAX_TRIALS = 100
"""Most trials in one session."""

MAX_PAUSE = 600.0
"""Longest pause between trials (s)."""

LATENESS_RANGE = (0.03, 10.0)
"""Smallest and largest bound on a tick's lateness a plan may set (s)."""

MAX_SPEC_CHARS = 1024
"""Longest avatar spec or LSL stream name (characters)."""


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
    """

    label: str
    kind: str
    spec: str | None = None
    device: str | None = None
    lsl: LslDevice | None = None


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
    InputError
        ``plan: <field>: problem`` for the first problem found.
    """
    if not isinstance(data, dict):
        raise _error("the plan must be a JSON object")
    condition = data.get("condition")
    if condition not in CONDITIONS:
        raise _error(f"condition must be one of {', '.join(CONDITIONS)}")
    players = data.get("players")
    if not isinstance(players, list) or not 1 <= len(players) <= MAX_PLAYERS:
        raise _error(f"players must be a list of 1 to {MAX_PLAYERS} slots")
    slots = tuple(_parse_slot(item, k) for k, item in enumerate(players))
    _check_labels(slots)
    n = len(slots)
    leaders = _parse_leaders(data.get("leaders", []), n)
    _check_condition(condition, slots, leaders)
    plan = SessionPlan(
        condition=condition,
        slots=slots,
        graph=_parse_graph(data.get("graph", "complete"), condition, n),
        leaders=leaders,
        duration=_number(data, "duration", 60.0, DURATION_RANGE),
        trials=int(_number(data, "trials", 1, (1, MAX_TRIALS), integer=True)),
        pause=_number(data, "pause", 5.0, (0.0, MAX_PAUSE)),
        show_metrics=_flag(data, "show_metrics", True),
        on_drop=_choice(data, "on_drop", ("continue", "stop")),
        max_lateness=_number(data, "max_lateness", MAX_LATENESS, LATENESS_RANGE),
        seed=int(_number(data, "seed", secrets.randbits(63), (0, 2**63 - 1), integer=True)),
    )
    return plan


def _error(problem: str) -> InputError:
    return InputError("plan", problem)


def _parse_slot(item: object, k: int) -> Slot:
    if not isinstance(item, dict):
        raise _error(f"players[{k}] must be an object")
    label = item.get("label")
    if not isinstance(label, str) or not PARTICIPANT_PATTERN.fullmatch(label):
        raise _error(
            f"players[{k}].label must be 1-32 letters, digits, '_' or '-', starting with a "
            "letter or digit"
        )
    kind = item.get("kind")
    if kind == "avatar":
        spec = item.get("spec")
        if not isinstance(spec, str) or not 0 < len(spec) <= MAX_SPEC_CHARS:
            raise _error(f"players[{k}].spec must name the avatar (a player spec)")
        return Slot(label, "avatar", spec=spec)
    if kind != "human":
        raise _error(f"players[{k}].kind must be 'human' or 'avatar'")
    device = item.get("device", "pointer")
    if device not in DEVICES:
        raise _error(f"players[{k}].device must be one of {', '.join(DEVICES)}")
    lsl = _parse_lsl(item.get("lsl"), k) if device == "lsl" else None
    return Slot(label, "human", device=device, lsl=lsl)


def _parse_lsl(item: object, k: int) -> LslDevice:
    where = f"players[{k}].lsl"
    if not isinstance(item, dict):
        raise _error(f"{where} must give the stream: {{'stream': NAME, 'channel': 0, ...}}")
    stream = item.get("stream")
    if not isinstance(stream, str) or not 0 < len(stream) <= MAX_SPEC_CHARS:
        raise _error(f"{where}.stream must be the stream's name")
    channel = int(_number(item, "channel", 0, (0, 1023), integer=True, where=where))
    scale = _number(item, "scale", 1.0, (-1e6, 1e6), where=where)
    if scale == 0.0:
        raise _error(f"{where}.scale must not be 0")
    offset = _number(item, "offset", 0.0, (-1e6, 1e6), where=where)
    source_id = item.get("source_id")
    if source_id is not None and not (
        isinstance(source_id, str) and 0 < len(source_id) <= MAX_SPEC_CHARS
    ):
        raise _error(f"{where}.source_id must be the stream's source id")
    return LslDevice(stream, channel, scale, offset, source_id)


def _check_labels(slots: tuple[Slot, ...]) -> None:
    labels = [slot.label for slot in slots]
    for label in labels:
        if labels.count(label) > 1:
            raise _error(f"two players are labelled {label!r}")


def _parse_leaders(value: object, n: int) -> tuple[int, ...]:
    if not isinstance(value, list) or not all(is_int(k) and 0 <= k < n for k in value):
        raise _error(f"leaders must be a list of player indices 0..{n - 1}")
    return tuple(sorted(set(value)))


def _check_condition(condition: str, slots: tuple[Slot, ...], leaders: tuple[int, ...]) -> None:
    n = len(slots)
    if condition == "solo" and any(slot.kind == "avatar" for slot in slots):
        raise _error("a solo session has people only")
    if condition in ("leader_follower", "joint") and n != 2:
        raise _error(f"{condition} needs exactly two players")
    if condition == "leader_follower" and len(leaders) != 1:
        raise _error("leader_follower needs exactly one leader (leaders: [0] or [1])")
    if condition == "group" and n < 2:
        raise _error("a group needs at least two players")
    if not any(slot.kind == "human" for slot in slots):
        raise _error("a lab session needs at least one person")


def _parse_graph(value: object, condition: str, n: int) -> Graph:
    if condition == "solo":
        return np.zeros((n, n), dtype=np.int8)
    if condition != "group":
        return complete_graph(n)
    if isinstance(value, str):
        if value not in TOPOLOGIES or value == "random":
            shown = ", ".join(t for t in TOPOLOGIES if t != "random")
            raise _error(f"graph must be one of {shown} or an adjacency matrix")
        return make_graph(value, n)
    try:
        return check_graph(value, n)  # type: ignore[arg-type]
    except InputError as error:
        raise _error(f"graph: {error.problem}") from None


def _number(
    data: dict[str, Any],
    key: str,
    default: float,
    bounds: tuple[float, float],
    integer: bool = False,
    where: str = "",
) -> float:
    name = f"{where}.{key}" if where else key
    value = data.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise _error(f"{name} must be a number")
    if integer and not is_int(value):
        raise _error(f"{name} must be an integer")
    low, high = bounds
    if not (math.isfinite(value) and low <= value <= high):
        raise _error(f"{name} must lie between {low:g} and {high:g}")
    return value


def _flag(data: dict[str, Any], key: str, default: bool) -> bool:
    value = data.get(key, default)
    if not isinstance(value, bool):
        raise _error(f"{key} must be true or false")
    return value


def _choice(data: dict[str, Any], key: str, choices: tuple[str, ...]) -> str:
    value = data.get(key, choices[0])
    if value not in choices:
        raise _error(f"{key} must be one of {', '.join(choices)}")
    return str(value)
