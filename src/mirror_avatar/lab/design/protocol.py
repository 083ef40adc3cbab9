"""A study protocol: blocks of conditions, who plays in each, the questions, the order.

A protocol is a TOML file (`load_protocol`; the format is in the lab guide,
docs/lab.md#study-protocols). It has blocks, each a list of conditions; a condition is one game
(``solo``, ``leader_follower``, ``joint``, ``group``) with its players, graph, leaders, trials,
duration and pause, which becomes a `mirror_avatar.lab.design.plan.SessionPlan` once its players
are decided (`Condition.plan`). A player is a person (by label), an avatar (by player spec) or a
``person-or-avatar``: the partner's slot is filled by the person or by the avatar, balanced across
participants and across the positions of the order (`mirror_avatar.lab.design.order.meets_person`),
so that neither the participant nor the page knows which (the files record it). Questions are
declared once and asked after each trial of a condition (``after_trial``) or after a block
(``after_block``). The order of blocks and of each block's conditions is fixed, random or
counterbalanced across participants (`mirror_avatar.lab.design.order`). An ``[analysis]``
table declares the hypothesis `study report` tests first (`Analysis`).

Every mistake is refused with one line naming the file, the key path (such as
``blocks[1].conditions[0].players``), the problem and how to fix it; every avatar is built and
dry-run in each condition's role when the protocol is read, and a run planned too long for a
participant, or a condition whose end screens show a trial's metrics (off unless asked: they may
tell the partner's kind), is read with a warning (`mirror_avatar.lab.design.protocol_checks`,
`Protocol.warnings`).
"""

from __future__ import annotations

import math
import secrets
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from mirror_avatar.files.user_files import is_int, parse_toml, read_text
from mirror_avatar.lab.design.checker import Checker
from mirror_avatar.lab.design.online import Online, parse_online
from mirror_avatar.lab.design.order import (
    block_order,
    condition_order,
    first_meets_person,
    meets_person,
)
from mirror_avatar.lab.design.partner_view import PartnerView, parse_partner_view
from mirror_avatar.lab.design.perturbation import Perturbation, parse_perturbations
from mirror_avatar.lab.design.plan import (
    MAX_SPEC_CHARS,
    PlanError,
    SessionPlan,
    parse_plan,
)
from mirror_avatar.lab.design.protocol_checks import (
    AvatarCheck,
    long_run,
    metrics_shown,
    page_knows,
)
from mirror_avatar.lab.design.protocol_keys import (
    ANALYSIS,
    ANALYSIS_SETTINGS,
    BLIND_METRICS,
    BLOCK,
    BLOCK_SETTINGS,
    CONDITION,
    CONDITION_SETTINGS,
    CONDITION_TRIAL_SETTINGS,
    MAX_BLOCKS,
    MAX_CONDITIONS,
    MAX_OCCLUSION_END,
    MAX_OPTIONS,
    MAX_PRIMARY,
    MAX_QUESTIONS,
    PLAYER,
    PLAYER_SETTINGS,
    QUESTION,
    QUESTION_SETTINGS,
    STUDY_SETTINGS,
    keys_of,
)
from mirror_avatar.metrics.registry import TABLE_COLUMNS

MAX_PROTOCOL_BYTES = 256 * 1024
"""Largest protocol file read (bytes)."""


@dataclass(frozen=True)
class Question:
    """A question asked on the participants' pages.

    Attributes
    ----------
    id
        Its name (the column of the answers).
    text
        What the page asks.
    kind
        One of `mirror_avatar.lab.design.protocol_keys.QUESTION_KINDS`.
    options
        A choice's options.
    points
        A Likert scale's number of points (answers 1..points).
    anchors
        The labels of a Likert scale's two ends.
    max_chars
        Longest free-text answer (characters).
    """

    id: str
    text: str
    kind: str
    options: tuple[str, ...] = ()
    points: int = 0
    anchors: tuple[str, str] = ("", "")
    max_chars: int = 0

    def problem(self, value: object) -> str | None:
        """Return why ``value`` cannot answer the question, or None when it can.

        A choice's answer is one of its options, a Likert answer an integer 1..points, a text
        answer at most ``max_chars`` characters.
        """
        if self.kind == "choice" and value not in self.options:
            return f"{self.id}: choose one of the options"
        if self.kind == "likert" and not (is_int(value) and 1 <= value <= self.points):
            return f"{self.id}: choose a point from 1 to {self.points}"
        if self.kind == "text" and not (isinstance(value, str) and len(value) <= self.max_chars):
            return f"{self.id}: write at most {self.max_chars} characters"
        return None

    def to_json(self) -> dict[str, object]:
        """Return the question as a page shows it."""
        return {
            "id": self.id,
            "text": self.text,
            "kind": self.kind,
            "options": list(self.options),
            "points": self.points,
            "anchors": list(self.anchors),
            "max_chars": self.max_chars,
        }


@dataclass(frozen=True)
class Player:
    """A player slot of a condition: its label, kind, avatar spec, device and where it runs.

    ``kind`` is one of `mirror_avatar.lab.design.protocol_keys.PLAYER_KINDS`; ``spec`` and
    ``runs`` (`mirror_avatar.lab.design.plan.RUNS`) are for avatars.
    """

    label: str
    kind: str
    spec: str | None = None
    device: str = "pointer"
    runs: str = "server"


@dataclass(frozen=True)
class Condition:
    """One condition of a block: its game and players, and what `parse_plan` reads.

    Attributes
    ----------
    name
        Its name (unique in the protocol).
    game
        One of `mirror_avatar.lab.design.plan.CONDITIONS`.
    players
        Its player slots, in order.
    leaders
        Labels of the leading players.
    settings
        The plan's other keys (graph, trials, duration, pause, show_metrics, on_drop).
    after_trial
        Ids of the questions asked after each trial.
    delay
        How late the partners are drawn on the people's pages (s).
    occlude
        Intervals of each trial (s from its start) during which the partners are hidden.
    view
        How the people's pages draw the partners when their links differ
        (`mirror_avatar.lab.design.partner_view`).
    perturb
        Changes of its avatars at given times of each trial
        (`mirror_avatar.lab.design.perturbation`), in order of time.
    """

    name: str
    game: str
    players: tuple[Player, ...]
    leaders: tuple[str, ...]
    settings: dict[str, Any]
    after_trial: tuple[str, ...]
    delay: float = 0.0
    occlude: tuple[tuple[float, float], ...] = ()
    view: PartnerView = PartnerView()
    perturb: tuple[Perturbation, ...] = ()

    @property
    def trials(self) -> int:
        """Number of trials."""
        return int(self.settings.get("trials", 1))

    @property
    def choices(self) -> tuple[str, ...]:
        """Labels of its ``person-or-avatar`` slots."""
        return tuple(p.label for p in self.players if p.kind == "person-or-avatar")

    def with_avatars(self) -> SessionPlan:
        """Return its plan with every ``person-or-avatar`` slot filled by the avatar (seed 0)."""
        return self.plan(dict.fromkeys(self.choices, False), 0)

    def plan(self, persons: dict[str, bool], seed: int) -> SessionPlan:
        """Return the condition's plan, each ``person-or-avatar`` slot decided by ``persons``.

        Parameters
        ----------
        persons
            Per ``person-or-avatar`` label, True when a person fills it.
        seed
            The plan's seed.
        """
        slots: list[dict[str, str | None]] = []
        for player in self.players:
            human = player.kind == "person" or (
                player.kind == "person-or-avatar" and persons[player.label]
            )
            if human:
                slots.append({"label": player.label, "kind": "human", "device": player.device})
            else:
                slots.append(
                    {"label": player.label, "kind": "avatar", "spec": player.spec,
                     "runs": player.runs}
                )  # fmt: skip
        labels = [player.label for player in self.players]
        leaders = [labels.index(label) for label in self.leaders]
        data: dict[str, Any] = {"condition": self.game, "players": slots, "leaders": leaders}
        return parse_plan(data | self.settings | {"seed": seed})


@dataclass(frozen=True)
class Block:
    """A block: its conditions, their order, and the questions asked after it."""

    name: str
    order: str
    conditions: tuple[Condition, ...]
    after_block: tuple[str, ...]


@dataclass(frozen=True)
class Analysis:
    """A protocol's hypothesis: the confirmatory test `study report` leads with.

    Attributes
    ----------
    primary
        The primary measures: study table columns (`mirror_avatar.metrics.registry.TABLE_COLUMNS`).
    direction
        One of `mirror_avatar.lab.design.protocol_keys.DIRECTIONS`: ``condition``'s mean
        ``"lower"`` or ``"higher"`` than ``reference``'s, or ``"two-sided"``.
    condition, reference
        The tested condition and the one it is compared with (also the reference of every
        exploratory comparison).
    smallest_effect
        The smallest difference of interest, in the primary measures' units.
    alpha
        The confirmatory test's significance level (family-wise over the primary measures).
    """

    primary: tuple[str, ...]
    direction: str
    condition: str
    reference: str
    smallest_effect: float
    alpha: float = 0.05


@dataclass(frozen=True)
class Protocol:
    """A study protocol (see the module docstring).

    Attributes
    ----------
    source
        The file it was read from.
    title
        Its title.
    seed
        The seed of every draw (order, partners); drawn and recorded when the file has none.
    block_order
        ``"fixed"`` or ``"random"``.
    questions
        Its questions, by id.
    blocks
        Its blocks, in the file's order.
    seed_drawn
        Whether the file has no seed and ``seed`` was drawn when it was read (a restart draws
        another, and the participants' runs then no longer resume).
    blind
        One of `mirror_avatar.lab.design.protocol_keys.BLINDS`: ``"single"``, the participants'
        pages never show a partner's kind; ``"double"``, the researcher's console neither, until
        export (`mirror_avatar.lab.running.blinding`).
    warnings
        What is odd but allowed, one line each
        (`mirror_avatar.lab.design.protocol_checks.long_run`).
    analysis
        Its hypothesis (``[analysis]``), None when it declares none.
    online
        Its panel identifiers and end codes (``[online]``,
        `mirror_avatar.lab.design.online`); empty when it declares none.
    """

    source: str
    title: str
    seed: int
    block_order: str
    questions: dict[str, Question]
    blocks: tuple[Block, ...]
    seed_drawn: bool = field(default=False, compare=False)
    blind: str = "single"
    warnings: tuple[str, ...] = field(default=(), compare=False)
    analysis: Analysis | None = None
    online: Online = Online()

    @property
    def conditions(self) -> tuple[str, ...]:
        """The conditions' names in the file's order."""
        return tuple(c.name for block in self.blocks for c in block.conditions)

    @property
    def people(self) -> tuple[str, ...]:
        """Labels of everyone who may play as a person, in order of first appearance."""
        labels: list[str] = []
        for block in self.blocks:
            for condition in block.conditions:
                for player in condition.players:
                    if player.kind != "avatar" and player.label not in labels:
                        labels.append(player.label)
        return tuple(labels)

    def schedule(self, participant: int) -> list[Step]:
        """Return what participant number ``participant`` (0-based) plays, in order."""
        steps = []
        blocks = block_order(self.block_order, len(self.blocks), participant, self.seed)
        for b in blocks:
            block = self.blocks[b]
            n = len(block.conditions)
            order = condition_order(block.order, n, participant, self.seed, b)
            for position, c in enumerate(order):
                condition = block.conditions[c]
                persons = {
                    player.label: meets_person(
                        block.order,
                        n,
                        participant,
                        position,
                        first_meets_person(self.seed, b, self.people.index(player.label)),
                    )
                    for player in condition.players
                    if player.kind == "person-or-avatar"
                }
                steps.append(Step(b, c, condition.name, persons))
        return steps


@dataclass(frozen=True)
class Step:
    """One condition in a participant's schedule.

    Block and condition indices, its name, and whether a person (True) or the avatar fills
    each ``person-or-avatar`` slot.
    """

    block: int
    condition: int
    name: str
    persons: dict[str, bool]


def load_protocol(path: Path) -> Protocol:
    """Read and validate a protocol file.

    Raises
    ------
    InputError
        ``FILE: KEY.PATH: problem (fix)`` for the first mistake found; a file that is not a
        regular UTF-8 text file of at most `MAX_PROTOCOL_BYTES` (`mirror_avatar.files.user_files`).
    """
    text = read_text(path, MAX_PROTOCOL_BYTES)
    return protocol_from_text(text, str(path))


def protocol_from_text(text: str, source: str) -> Protocol:
    """Read and validate a protocol's TOML text (``source`` names it in errors).

    Raises
    ------
    InputError
        ``SOURCE: not valid TOML: ...`` with where the syntax fails, TOML nested too deeply
        (`mirror_avatar.files.user_files.parse_toml`), or the first mistake in the protocol.
    """
    return parse_protocol(parse_toml(text, source), source)


def parse_protocol(data: dict[str, Any], source: str) -> Protocol:
    """Validate a protocol read from TOML (``source`` names it in errors)."""
    check = Checker(source)
    check.keys(data, "", keys_of(STUDY_SETTINGS))
    title = check.text(data.get("title", ""), "title", allow_empty=True)
    study = {setting.key: check.setting(data, "", setting) for setting in STUDY_SETTINGS}
    seed = secrets.randbits(63) if study["seed"] is None else study["seed"]
    order, blind = study["block_order"], study["blind"]
    questions = _questions(check, data.get("questions", {}))
    blocks = check.array(data.get("blocks"), "blocks", MAX_BLOCKS, "add [[blocks]] tables")
    parsed = tuple(
        _block(check, block, f"blocks[{b}]", questions) for b, block in enumerate(blocks)
    )
    names = [c.name for block in parsed for c in block.conditions]
    for b, block in enumerate(parsed):
        for c, condition in enumerate(block.conditions):
            if names.count(condition.name) > 1:
                where = f"blocks[{b}].conditions[{c}].name"
                raise check.error(where, f"{condition.name!r} names two conditions", "rename one")
    avatars, plans, warnings = AvatarCheck(check), [], list[str]()
    for b, block in enumerate(parsed):
        for c, condition in enumerate(block.conditions):
            where = f"blocks[{b}].conditions[{c}]"
            plans.append(condition.with_avatars())
            avatars.condition(where, condition.name, plans[-1], condition.perturb)
            warnings += metrics_shown(source, where, plans[-1])
            warnings += page_knows(source, where, plans[-1])
    return Protocol(
        source,
        title,
        int(seed),
        order,
        questions,
        parsed,
        seed_drawn="seed" not in data,
        blind=str(blind),
        warnings=(*warnings, *long_run(source, plans)),
        analysis=None if "analysis" not in data else _analysis(check, data["analysis"], names),
        online=Online()
        if "online" not in data
        else parse_online(check, data["online"], Path(source).parent),
    )


def _analysis(check: Checker, value: object, conditions: list[str]) -> Analysis:
    """Read ``[analysis]``: primary measures of the study table, conditions of the protocol."""
    data = check.table(value, "analysis")
    check.keys(data, "analysis", keys_of(ANALYSIS_SETTINGS))
    direction, smallest, alpha = (check.setting(data, "analysis", ANALYSIS[key])
                                  for key in ("direction", "smallest_effect", "alpha"))  # fmt: skip
    primary = data.get("primary")
    listed = primary if isinstance(primary, list) else [primary]
    if not 1 <= len(listed) <= MAX_PRIMARY:
        raise check.error("analysis.primary", f"must name 1 to {MAX_PRIMARY} measures",
                          'e.g. primary = "rmse"')  # fmt: skip
    measures = tuple(check.one_of(m, "analysis.primary", TABLE_COLUMNS, "measure") for m in listed)
    if "contrast" in data and "reference" in data:
        raise check.error("analysis.reference", "the contrast names the reference already",
                          "give contrast or reference, not both")  # fmt: skip
    condition, reference = _contrast(check, data, conditions)
    return Analysis(measures, str(direction), condition, reference, float(smallest),
                    float(alpha))  # fmt: skip


def _contrast(check: Checker, data: dict[str, Any], conditions: list[str]) -> tuple[str, str]:
    """Return the tested condition and its reference, each a condition of the protocol."""
    contrast = data.get("contrast")
    if contrast is not None:
        if not isinstance(contrast, list) or len(contrast) != 2 or contrast[0] == contrast[1]:
            raise check.error("analysis.contrast", "must name two different conditions",
                              f'e.g. ["{conditions[-1]}", "{conditions[0]}"]')  # fmt: skip
        return (check.one_of(contrast[0], "analysis.contrast[0]", tuple(conditions), "condition"),
                check.one_of(contrast[1], "analysis.contrast[1]", tuple(conditions),
                             "condition"))  # fmt: skip
    reference = check.one_of(data.get("reference", conditions[0]), "analysis.reference",
                             tuple(conditions), "condition")  # fmt: skip
    others = [c for c in conditions if c != reference]
    if len(others) != 1:
        which = f"{len(conditions)} conditions: which one is tested is not clear"
        raise check.error("analysis.contrast", which,
                          f'give contrast = ["{others[0]}", "{reference}"]')  # fmt: skip
    return others[0], reference


def _questions(check: Checker, value: object) -> dict[str, Question]:
    table = check.table(value, "questions")
    if len(table) > MAX_QUESTIONS:
        raise check.error("questions", f"more than {MAX_QUESTIONS} questions", "ask fewer")
    return {
        check.label(qid, f"questions.{qid}"): _question(check, qid, q) for qid, q in table.items()
    }


def _question(check: Checker, qid: str, value: object) -> Question:
    where = f"questions.{qid}"
    data = check.table(value, where)
    check.keys(data, where, keys_of(QUESTION_SETTINGS))
    text = check.text(data.get("text"), f"{where}.text")
    kind, points, most = (check.setting(data, where, QUESTION[key])
                          for key in ("kind", "points", "max_chars"))  # fmt: skip
    if kind == "choice":
        options = check.array(
            data.get("options"),
            f"{where}.options",
            MAX_OPTIONS,
            'list at least two, e.g. ["a person", "a computer"]',
        )
        texts = tuple(check.text(o, f"{where}.options[{i}]") for i, o in enumerate(options))
        if len(texts) < 2 or len(set(texts)) != len(texts):
            raise check.error(
                f"{where}.options", "needs two or more different options", "add or rename"
            )
        return Question(qid, text, kind, options=texts)
    if kind == "likert":
        anchors = data.get("anchors", ["", ""])
        if not isinstance(anchors, list) or len(anchors) != 2:
            raise check.error(
                f"{where}.anchors", "must name the two ends", 'e.g. ["not at all", "very"]'
            )
        ends = tuple(check.text(a, f"{where}.anchors[{i}]", True) for i, a in enumerate(anchors))
        return Question(qid, text, kind, points=points, anchors=(ends[0], ends[1]))
    return Question(qid, text, kind, max_chars=most)


def _block(check: Checker, value: object, where: str, questions: dict[str, Question]) -> Block:
    data = check.table(value, where)
    check.keys(data, where, keys_of(BLOCK_SETTINGS))
    name = check.text(data.get("name", where), f"{where}.name")
    order = check.setting(data, where, BLOCK["order"])
    after = check.refs(data.get("after_block", []), f"{where}.after_block", questions)
    items = check.array(
        data.get("conditions"),
        f"{where}.conditions",
        MAX_CONDITIONS,
        f"add [[{where.split('[')[0]}.conditions]] tables",
    )
    conditions = tuple(
        _condition(check, item, f"{where}.conditions[{c}]", questions)
        for c, item in enumerate(items)
    )
    return Block(name, str(order), conditions, after)


def _condition(
    check: Checker, value: object, where: str, questions: dict[str, Question]
) -> Condition:
    data = check.table(value, where)
    check.keys(data, where, keys_of(CONDITION_SETTINGS))
    name = check.text(data.get("name"), f"{where}.name")
    game, delay = (check.setting(data, where, CONDITION[key]) for key in ("game", "delay"))
    items = check.array(
        data.get("players"), f"{where}.players", 16, 'e.g. [{ label = "P1", kind = "person" }]'
    )
    players = tuple(_player(check, item, f"{where}.players[{k}]") for k, item in enumerate(items))
    labels = [player.label for player in players]
    leaders = data.get("leaders", [])
    if not isinstance(leaders, list) or not all(label in labels for label in leaders):
        raise check.error(
            f"{where}.leaders",
            "must list labels of this condition's players",
            f"choose among {', '.join(labels)}",
        )
    settings = {
        setting.key: check.setting(data, where, setting)
        for setting in CONDITION_TRIAL_SETTINGS
        if setting.key in data or setting is BLIND_METRICS  # the plan's default is on
    }
    if "graph" in data:
        settings["graph"] = data["graph"]
    after = check.refs(data.get("after_trial", []), f"{where}.after_trial", questions)
    occlude = _intervals(check, data.get("occlude", []), f"{where}.occlude")
    in_page = [player.label for player in players if player.runs == "browser"]
    view = parse_partner_view(check, data, where, in_page[0] if in_page else None)
    condition = Condition(
        name, str(game), players, tuple(leaders), settings, after, float(delay), occlude, view
    )
    _check_plan(check, condition, where)
    for key in ("delay", "occlude"):
        if in_page and key in data:
            raise check.error(
                f"{where}.{key}",
                f"{in_page[0]} runs in the browser, whose page draws it as it steps it",
                f'leave out {key}, or set runs = "server" on {in_page[0]}',
            )
    if "perturb" not in data:
        return condition
    plan = condition.plan({p.label: False for p in players if p.kind == "person-or-avatar"}, 0)
    specs = {p.label: None if p.kind == "person" else p.spec for p in players}
    roles = dict(zip(labels, plan.roles, strict=True))
    perturb = parse_perturbations(
        check, data["perturb"], f"{where}.perturb", specs, roles, plan.duration
    )
    return replace(condition, perturb=perturb)


def _intervals(check: Checker, value: object, where: str) -> tuple[tuple[float, float], ...]:
    """Read occlusion intervals: ``"whole"`` (the whole trial) or ``[[start, end], ...]`` (s)."""
    if value == "whole":
        return ((0.0, math.inf),)
    fix = 'e.g. [[5, 12]] (seconds from the trial\'s start) or "whole"'
    if not isinstance(value, list) or len(value) > MAX_CONDITIONS:
        raise check.error(where, "must be a list of [start, end] intervals", fix)
    intervals = []
    for i, item in enumerate(value):
        ok = isinstance(item, list) and len(item) == 2
        ok = ok and all(isinstance(t, int | float) and not isinstance(t, bool) for t in item)
        if not ok or not 0 <= item[0] < item[1] <= MAX_OCCLUSION_END:
            raise check.error(f"{where}[{i}]", "must be [start, end] with 0 <= start < end", fix)
        intervals.append((float(item[0]), float(item[1])))
    return tuple(intervals)


def _player(check: Checker, value: object, where: str) -> Player:
    data = check.table(value, where)
    check.keys(data, where, keys_of(PLAYER_SETTINGS))
    label = check.label(data.get("label"), f"{where}.label")
    kind = check.setting(data, where, PLAYER["kind"])
    spec = data.get("spec")
    if kind == "person" and spec is not None:
        raise check.error(
            f"{where}.spec", "a person has no spec", "remove it, or make the kind avatar"
        )
    if kind != "person" and not (isinstance(spec, str) and 0 < len(spec) <= MAX_SPEC_CHARS):
        raise check.error(
            f"{where}.spec",
            f"{'an' if kind == 'avatar' else 'a'} {kind} needs the avatar's player spec",
            'e.g. spec = "bundled:slow"',
        )
    runs = check.setting(data, where, PLAYER["runs"])
    if kind == "person" and "runs" in data:
        raise check.error(f"{where}.runs", "a person's page is where a person plays", "remove it")
    device = data.get("device", "pointer")
    if device != "pointer":
        raise check.error(
            f"{where}.device",
            f"{device!r} is not available in a protocol",
            "use 'pointer': LSL devices are set in single plans",
        )
    return Player(label, str(kind), spec, device, str(runs))


def _check_plan(check: Checker, condition: Condition, where: str) -> None:
    """Refuse a condition whose plan would be refused, with either filling of its partners.

    The plan's error names its key (`mirror_avatar.lab.design.plan.PlanError`): the condition's key
    of that name is at fault.
    """
    choices = [player.label for player in condition.players if player.kind == "person-or-avatar"]
    for person in (True, False):
        try:
            condition.plan(dict.fromkeys(choices, person), 0)
        except PlanError as error:
            either = " when its person-or-avatar is an avatar" if choices and not person else ""
            key = error.key.split("[")[0].split(".")[0]
            raise check.error(f"{where}.{key}", f"{error.what}{either}", error.fix) from None
