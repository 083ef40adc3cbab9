"""The declared record of one lab trial: what its sidecar says of the session, study and game.

A lab trial's sidecar (``trial-NN_session.json``, `mirror_avatar.sessions.writer.SessionWriter`)
holds,
in its ``metadata``, the ``lab`` object that names the session, the trial, the game's condition
and every slot, and in a study session the participant's run: protocol, participant number,
block, the protocol's condition, the trial's number in it, the partners' delay, the occlusions
and every player's true kind. Beside it are the trial's seed, the clock's start, whether it
completed, the drops, held samples and perturbations. `TrialRecord` declares that content once:
`trial_record` is its one reader (version 1 of the format: the files the lab writes, and has
written, with one-line errors naming the file and the key; `read_trial_record` reads a
sidecar's), `TrialRecord.metadata_json` its one writer (the ``lab`` object through `lab_json`,
key for key and in the order the lab has always written it, so files stay byte-identical). A
BIDS export carries the record whole in each ``_motion.json``'s ``MirrorGame`` key
(`mirror_avatar.lab.export.bids`) and its readers read it back with `trial_record`, so a
trial's record is equal from its run folder and from its export (but for the folders of a file
a slot's spec names: a dataset to be shared names it by its base name). `AnswersRecord` does
the same for the answers given after a trial (``trial-NN_answers.json``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.trial_io import read_sidecar_text
from mirror_avatar.files.user_files import parse_json

RECORD_VERSION = 1
"""Version of the trial record's format; version 1 is every file the lab has written so far."""

KINDS = ("human", "avatar")
"""A slot's kind as the record spells it (the protocol's ``person`` is a ``human`` slot)."""

KIND_NAMES = {"human": "person", "avatar": "avatar"}
"""A slot's kind as a study's tables name it."""


def partner_kind(kinds: Iterable[str]) -> str:
    """Name the true kind of a player's partners from their kinds as a table names them.

    The partners' kind (``person`` or ``avatar``, `KIND_NAMES`) when every partner is of one,
    ``mixed`` when of several, ``none`` for no partner (a solo trial).
    """
    named = set(kinds)
    if len(named) == 1:
        return named.pop()
    return "mixed" if named else "none"


@dataclass(frozen=True)
class SlotRecord:
    """One player's slot: label, true kind, role, avatar spec, input device and its report.

    ``input`` is what an input device says of itself (an LSL stream's source id, host and
    counts), None for the pointer of a page. ``runs`` is where an avatar ran: ``"server"`` or
    ``"browser"`` (its person's page); None for a person, and for an avatar of a trial recorded
    before avatars ran anywhere but the server.
    """

    label: str
    kind: str
    role: str
    spec: str | None = None
    device: str | None = None
    input: dict[str, Any] | None = None
    runs: str | None = None

    def to_json(self) -> dict[str, Any]:
        """Return the slot as the sidecar writes it."""
        slot = {"label": self.label, "kind": self.kind, "role": self.role,
                "spec": self.spec, "device": self.device}  # fmt: skip
        slot |= {} if self.runs is None else {"runs": self.runs}
        return slot if self.input is None else slot | {"input": self.input}


@dataclass(frozen=True)
class StudyRecord:
    """Where a trial stands in a participant's run of a study protocol.

    ``delay_s`` is the partners' visual delay on the pages (s), ``occluded_s`` the
    ``[start, end]`` intervals (s) during which they were hidden, ``partners`` each player's
    label and true kind (`KINDS`), ``panel`` each person's identifiers on their recruitment
    panel by label (as their join link gave them), ``consented`` when each person agreed on the
    consent page (UTC, ISO 8601) by label; those two are written only when there are any.
    ``partner_view`` is how the pages drew the partners, as the condition declared it
    (``handling``, ``lag_s``, ``horizon_s``, ``jitter_s``, ``jitter_distribution``:
    `mirror_avatar.lab.design.partner_view`), None in the records written before it.
    """

    protocol: str
    participant: int
    block: str
    condition: str
    condition_trial: int
    delay_s: float
    occluded_s: tuple[tuple[float, float], ...]
    partners: dict[str, str]
    panel: dict[str, dict[str, str]] = field(default_factory=dict)
    consented: dict[str, str] = field(default_factory=dict)
    partner_view: dict[str, Any] | None = None

    def to_json(self) -> dict[str, Any]:
        """Return the study's keys of the ``lab`` object, in the order the lab writes them."""
        panel = {"panel": {label: dict(ids) for label, ids in self.panel.items()}}
        consented = {"consented": dict(self.consented)}
        return (
            {
                "partner_delay_s": self.delay_s,
                "occluded_s": [list(pair) for pair in self.occluded_s],
                "protocol": self.protocol,
                "participant": self.participant,
                "block": self.block,
                "protocol_condition": self.condition,
                "condition_trial": self.condition_trial,
                "partners": dict(self.partners),
            }
            | (panel if self.panel else {})
            | (consented if self.consented else {})
            | ({} if self.partner_view is None else {"partner_view": dict(self.partner_view)})
        )


@dataclass(frozen=True)
class PerturbationRecord:
    """A change of an avatar during the trial: at ``sample`` (``time_s``, s), of ``player``."""

    sample: int
    time_s: float
    player: str
    change: str

    def to_json(self) -> dict[str, Any]:
        """Return the change as the sidecar's ``perturbations`` lists it."""
        return {"sample": self.sample, "time_s": self.time_s, "player": self.player,
                "change": self.change}  # fmt: skip


@dataclass(frozen=True)
class InputEventRecord:
    """A person's input lost or live again: at ``sample``, of ``label``, at message ``seq``.

    ``event`` is ``lost`` or ``live``; ``seq`` is the page's last message number (None when
    the input has none).
    """

    sample: int
    label: str
    event: str
    seq: int | None = None

    def to_json(self) -> dict[str, Any]:
        """Return the event as the sidecar's ``input_events`` lists it."""
        return {"sample": self.sample, "label": self.label, "event": self.event, "seq": self.seq}


PAGE_INTERRUPTIONS = ("hidden", "blur")
"""The interruptions a page reports: its tab hidden, its window out of focus."""

BELOW_BOUNDS = "below_bounds"
"""The interruption of a page whose frame rate or window is below the protocol's bounds during
play (`mirror_avatar.lab.running.play_screening`)."""

INTERRUPTION_KINDS = (*PAGE_INTERRUPTIONS, BELOW_BOUNDS)
"""A page's interruptions: those it reports (`PAGE_INTERRUPTIONS`) and its frame rate or window
below the protocol's bounds during play."""


@dataclass(frozen=True)
class PageRecord:
    """A participant page's clock and rates over the trial (the sidecar's ``pages``).

    As `mirror_avatar.lab.running.trial.page_record` writes them (METHODS section 18):
    ``exchanges`` (NTP-style exchanges during the trial), ``rtt_ms`` (their round trips: n,
    mean, median, p95, max; ms), ``offset_ms`` and ``uncertainty_ms`` (the page clock's
    estimates, server minus page: first, median, min, max; ms; None without an exchange),
    ``sample_rate_hz`` and ``frame_rate_hz`` (pointer samples and animation frames received per
    second), ``stalls`` (each gap in the page's samples: ``start_s`` on the server's clock and
    ``length_s``) and ``interruptions`` (each time the page's tab was hidden, its window out
    of focus or its frame rate or window below the protocol's bounds: ``kind``, one of
    `INTERRUPTION_KINDS`, ``start_s`` and ``end_s`` on the server's clock, cut to the trial;
    ``reason`` when the server gave one; ``open`` when it had not ended by the trial's end; the
    key absent when there were none, as in the records written before it) and ``view`` (its
    partners' draws: ``frames``, ``delay_ms`` from each sample's time to its draw's, n, mean,
    median, p95, max, and ``error_rms``, the drawn positions' RMS error against the recording,
    units; `mirror_avatar.lab.running.views.ViewLog.summary`; absent when it drew none, as in
    the records written before it).
    """

    exchanges: int
    rtt_ms: dict[str, float | int | None]
    offset_ms: dict[str, float] | None
    uncertainty_ms: dict[str, float] | None
    sample_rate_hz: float | None
    frame_rate_hz: float | None
    stalls: tuple[dict[str, float], ...] = ()
    interruptions: tuple[dict[str, Any], ...] = ()
    view: dict[str, Any] | None = None

    def to_json(self) -> dict[str, Any]:
        """Return the page as the sidecar's ``pages`` holds it."""
        return {
            "exchanges": self.exchanges,
            "rtt_ms": dict(self.rtt_ms),
            "offset_ms": None if self.offset_ms is None else dict(self.offset_ms),
            "uncertainty_ms": None if self.uncertainty_ms is None else dict(self.uncertainty_ms),
            "sample_rate_hz": self.sample_rate_hz,
            "frame_rate_hz": self.frame_rate_hz,
            "stalls": [dict(stall) for stall in self.stalls],
        } | (
            ({"interruptions": [dict(s) for s in self.interruptions]} if self.interruptions else {})
            | ({"view": self.view} if self.view is not None else {})
        )

    def cells(self) -> dict[str, float | int | None]:
        """Return its cells in the study table (`mirror_avatar.analysis.dictionary`)."""
        return (
            {
                "page_rtt_median_ms": self.rtt_ms.get("median"),
                "page_rtt_p95_ms": self.rtt_ms.get("p95"),
                "page_rtt_max_ms": self.rtt_ms.get("max"),
                "page_offset_ms": None if self.offset_ms is None else self.offset_ms["median"],
                "page_uncertainty_ms": None
                if self.uncertainty_ms is None
                else self.uncertainty_ms["median"],
                "page_sample_rate_hz": self.sample_rate_hz,
                "page_frame_rate_hz": self.frame_rate_hz,
                "page_stalls": len(self.stalls),
                "page_stalled_s": sum(stall["length_s"] for stall in self.stalls),
            }
            | self._interruption_cells()
            | self._view_cells()
        )

    def _view_cells(self) -> dict[str, float | None]:
        """Return the partners' drawn delay (mean, p95; ms) and RMS error (units), or Nones."""
        view = self.view or {"delay_ms": {}}
        return {
            "page_view_delay_ms": view["delay_ms"].get("mean"),
            "page_view_delay_p95_ms": view["delay_ms"].get("p95"),
            "page_view_error_rms": view.get("error_rms"),
        }

    def _interruption_cells(self) -> dict[str, float | int]:
        """Count each kind of interruption and sum its length (s)."""
        cells: dict[str, float | int] = {}
        for kind in INTERRUPTION_KINDS:
            spans = [span for span in self.interruptions if span["kind"] == kind]
            cells[f"page_{kind}"] = len(spans)
            cells[f"page_{kind}_s"] = sum(span["end_s"] - span["start_s"] for span in spans)
        return cells


@dataclass(frozen=True)
class TrialRecord:
    """One lab trial as its sidecar declares it (see the module docstring).

    ``condition`` is the game (``solo``, ``leader_follower``, ``joint``, ``group``); ``study``
    is None outside a study; ``seed`` and ``started_utc`` are None when unknown; ``dropped``
    gives the sample at which each dropped participant's connection dropped, ``held`` each
    person's samples held because nothing new arrived, ``missing`` each avatar run in a page's
    samples at which the page had reported no newer tick, ``input_events`` when inputs were lost
    or came back, ``clock`` the clock that stamped the samples, ``files`` the trial's
    companion files by role (``inputs``, ...), as names beside the sidecar, and ``pages`` each
    participant page's clock and rates (`PageRecord`), by label.
    """

    session_id: str
    trial: int
    condition: str
    slots: tuple[SlotRecord, ...]
    study: StudyRecord | None = None
    seed: int | None = None
    created_utc: str | None = None
    started_utc: str | None = None
    complete: bool = False
    dropped: dict[str, int] = field(default_factory=dict)
    perturbations: tuple[PerturbationRecord, ...] = ()
    held: dict[str, int] = field(default_factory=dict)
    missing: dict[str, int] = field(default_factory=dict)
    input_events: tuple[InputEventRecord, ...] = ()
    clock: str | None = None
    files: dict[str, str] = field(default_factory=dict)
    pages: dict[str, PageRecord] = field(default_factory=dict)
    version: int = RECORD_VERSION

    def lab_json(self) -> dict[str, Any]:
        """Return the sidecar's ``lab`` object: the one writer of its keys and their order."""
        study = {} if self.study is None else self.study.to_json()
        return (
            {"session_id": self.session_id, "condition": self.condition}
            | study
            | {
                "trial": self.trial,
                "slots": [slot.to_json() for slot in self.slots],
            }
        )

    def metadata_json(self) -> dict[str, Any]:
        """Return the sidecar metadata's recorded keys (``lab``, ``seed``, ``perturbations``...)."""
        metadata: dict[str, Any] = {"lab": self.lab_json()}
        stamps = {"created_utc": self.created_utc, "started_utc": self.started_utc}
        metadata |= {key: value for key, value in stamps.items() if value is not None}
        if self.seed is not None:
            metadata["seed"] = self.seed
        metadata |= {
            "complete": self.complete,
            "dropped": dict(self.dropped),
            "perturbations": [change.to_json() for change in self.perturbations],
            "held": dict(self.held),
        }
        if self.missing:
            metadata["missing"] = dict(self.missing)
        if self.input_events:
            metadata["input_events"] = [event.to_json() for event in self.input_events]
        if self.clock is not None:
            metadata["clock"] = self.clock
        if self.files:
            metadata["files"] = dict(self.files)
        if self.pages:
            metadata["pages"] = {label: page.to_json() for label, page in self.pages.items()}
        return metadata

    @property
    def block(self) -> str | None:
        """The study block the trial belongs to, None outside a study."""
        return None if self.study is None else self.study.block

    @property
    def named_condition(self) -> str:
        """The condition as the researcher named it: the protocol's, else the game's."""
        return self.condition if self.study is None else self.study.condition

    def partners_of(self, label: str) -> tuple[SlotRecord, ...]:
        """Return the slots of every player but ``label``, in player order."""
        return tuple(slot for slot in self.slots if slot.label != label)


def read_trial_record(path: str | Path) -> TrialRecord:
    """Read a lab trial's record from its sidecar (``trial-NN_session.json``).

    Raises
    ------
    InputError
        A sidecar that cannot be read, or whose metadata lacks a key of the record or holds
        one of the wrong type (the error names the file and the key).
    """
    path = Path(path)
    sidecar = parse_json(read_sidecar_text(path), path)
    metadata = sidecar.get("metadata") if isinstance(sidecar, dict) else None
    return trial_record(_Keys(path, "metadata").object(metadata), path)


def lab_trial_record(
    metadata: dict[str, Any], source: str | Path = "the trial's metadata"
) -> TrialRecord | None:
    """Return the record of a lab trial's ``metadata``, or None when it is not a lab trial's.

    A session from another source (a simulation, a live trial, another tool's recording)
    has no ``lab`` object and no record.

    Raises
    ------
    InputError
        A ``lab`` object that is not a trial's record (as `trial_record`).
    """
    return trial_record(metadata, source) if "lab" in metadata else None


def trial_record(
    metadata: dict[str, Any], source: str | Path = "the trial's metadata", key: str = "metadata"
) -> TrialRecord:
    """Make the record of a trial from its sidecar's ``metadata`` (version 1).

    ``key`` names the object that holds the record in ``source`` (a BIDS export's
    ``MirrorGame``), for the errors.

    Raises
    ------
    InputError
        As `read_trial_record`, naming ``source`` and the key in ``key``.
    """
    keys = _Keys(Path(source), key)
    lab = keys.within("lab").object(metadata.get("lab"))
    at = keys.within("lab")
    slots = lab.get("slots")
    if not isinstance(slots, list) or not slots:
        raise at.error("slots", "is not a non-empty list")
    study = _study(at, lab) if "protocol" in lab else None
    dropped = keys.object(metadata.get("dropped", {}), "dropped")
    changes = _list(keys, metadata, "perturbations")
    events = _list(keys, metadata, "input_events")
    held = keys.object(metadata.get("held", {}), "held")
    missing = keys.object(metadata.get("missing", {}), "missing")
    files = keys.object(metadata.get("files", {}), "files")
    pages = keys.object(metadata.get("pages", {}), "pages")
    return TrialRecord(
        session_id=at.text(lab, "session_id"),
        trial=at.count(lab, "trial"),
        condition=at.text(lab, "condition", empty=True),
        slots=tuple(_slot(at.within(f"slots[{k}]"), s) for k, s in enumerate(slots)),
        study=study,
        seed=_seed(keys, metadata, at, lab),
        created_utc=keys.optional_text(metadata, "created_utc")
        or at.optional_text(lab, "created_utc"),
        started_utc=keys.optional_text(metadata, "started_utc"),
        complete=metadata.get("complete") is True,
        dropped={str(who): keys.within("dropped").count(dropped, who) for who in dropped},
        perturbations=tuple(
            _perturbation(keys.within(f"perturbations[{k}]"), c) for k, c in enumerate(changes)
        ),
        held={str(who): keys.within("held").count(held, who) for who in held},
        missing={str(who): keys.within("missing").count(missing, who) for who in missing},
        input_events=tuple(
            _input_event(keys.within(f"input_events[{k}]"), e) for k, e in enumerate(events)
        ),
        clock=keys.optional_text(metadata, "clock"),
        files={str(role): keys.within("files").text(files, role) for role in files},
        pages={str(who): _page(keys.within(f"pages.{who}"), page) for who, page in pages.items()},
    )


def _seed(keys: _Keys, metadata: dict[str, Any], at: _Keys, lab: dict[str, Any]) -> int | None:
    """Return the trial's seed: the metadata's, else (early recordings) the ``lab`` object's."""
    if metadata.get("seed") is not None:
        return keys.count(metadata, "seed")
    return at.count(lab, "seed") if lab.get("seed") is not None else None


def _list(keys: _Keys, metadata: dict[str, Any], key: str) -> list[Any]:
    value = metadata.get(key, [])
    if not isinstance(value, list):
        raise keys.error(key, "is not a list")
    return value


def _input_event(keys: _Keys, value: object) -> InputEventRecord:
    event = keys.object(value)
    seq = event.get("seq")
    return InputEventRecord(
        sample=keys.count(event, "sample"),
        label=keys.text(event, "label"),
        event=keys.text(event, "event"),
        seq=None if seq is None else keys.count(event, "seq"),
    )


def _page(keys: _Keys, value: object) -> PageRecord:
    page = keys.object(value)
    offset, uncertainty = page.get("offset_ms"), page.get("uncertainty_ms")
    stalls, interruptions = page.get("stalls", []), page.get("interruptions", [])
    for name, listed in (("stalls", stalls), ("interruptions", interruptions)):
        if not isinstance(listed, list):
            raise keys.error(name, "is not a list")
    return PageRecord(
        exchanges=keys.count(page, "exchanges"),
        rtt_ms=keys.object(page.get("rtt_ms"), "rtt_ms"),
        offset_ms=None if offset is None else keys.object(offset, "offset_ms"),
        uncertainty_ms=None if uncertainty is None else keys.object(uncertainty, "uncertainty_ms"),
        sample_rate_hz=_optional_number(keys, page, "sample_rate_hz"),
        frame_rate_hz=_optional_number(keys, page, "frame_rate_hz"),
        stalls=tuple(_stall(keys.within(f"stalls[{k}]"), s) for k, s in enumerate(stalls)),
        interruptions=tuple(
            _interruption(keys.within(f"interruptions[{k}]"), span)
            for k, span in enumerate(interruptions)
        ),
        view=None if page.get("view") is None else _view(keys.within("view"), page["view"]),
    )


def _view(keys: _Keys, value: object) -> dict[str, Any]:
    view = keys.object(value)
    delay = keys.object(view.get("delay_ms"), "delay_ms")
    return {
        "frames": keys.count(view, "frames"),
        "delay_ms": delay
        | {key: _optional_number(keys.within("delay_ms"), delay, key) for key in ("mean", "p95")},
        "error_rms": _optional_number(keys, view, "error_rms"),
    }


def _interruption(keys: _Keys, value: object) -> dict[str, Any]:
    span = keys.object(value)
    kind = keys.text(span, "kind")
    if kind not in INTERRUPTION_KINDS:
        raise keys.error("kind", f"{kind!r} is not one of {', '.join(INTERRUPTION_KINDS)}")
    start, end = keys.number(span, "start_s"), keys.number(span, "end_s")
    if end < start:
        raise keys.error("end_s", "is before start_s")
    reason = span.get("reason")
    return (
        {"kind": kind, "start_s": start, "end_s": end}
        | ({"reason": keys.text(span, "reason")} if reason is not None else {})
        | ({"open": True} if span.get("open") is True else {})
    )


def _stall(keys: _Keys, value: object) -> dict[str, float]:
    stall = keys.object(value)
    return {key: keys.number(stall, key) for key in ("start_s", "length_s")}


def _optional_number(keys: _Keys, obj: dict[str, Any], key: str) -> float | None:
    return None if obj.get(key) is None else keys.number(obj, key)


def _slot(keys: _Keys, value: object) -> SlotRecord:
    slot = keys.object(value)
    kind = keys.text(slot, "kind")
    if kind not in KINDS:
        raise keys.error("kind", f"{kind!r} is not one of {', '.join(KINDS)}")
    device = slot.get("input")
    return SlotRecord(
        label=keys.text(slot, "label"),
        kind=kind,
        role=keys.text(slot, "role"),
        spec=keys.optional_text(slot, "spec"),
        device=keys.optional_text(slot, "device"),
        input=None if device is None else keys.object(device, "input"),
        runs=keys.optional_text(slot, "runs"),
    )


def _study(keys: _Keys, lab: dict[str, Any]) -> StudyRecord:
    occluded = lab.get("occluded_s", [])
    if not isinstance(occluded, list) or not all(
        isinstance(pair, list) and len(pair) == 2 and all(_is_number(v) for v in pair)
        for pair in occluded
    ):
        raise keys.error("occluded_s", "is not a list of [start, end] pairs of seconds")
    partners = keys.object(lab.get("partners", {}), "partners")
    if not all(kind in KINDS for kind in partners.values()):
        raise keys.error("partners", f"names a kind that is not one of {', '.join(KINDS)}")
    return StudyRecord(
        protocol=keys.text(lab, "protocol"),
        participant=keys.count(lab, "participant"),
        block=keys.text(lab, "block"),
        condition=keys.text(lab, "protocol_condition"),
        condition_trial=keys.count(lab, "condition_trial"),
        delay_s=keys.number(lab, "partner_delay_s"),
        occluded_s=tuple((pair[0], pair[1]) for pair in occluded),
        partners={str(label): str(kind) for label, kind in partners.items()},
        panel=_panel(keys, lab.get("panel", {})),
        consented=_texts(keys, lab.get("consented", {}), "consented"),
        partner_view=None if lab.get("partner_view") is None else _partner_view(keys, lab),
    )


def _partner_view(keys: _Keys, lab: dict[str, Any]) -> dict[str, Any]:
    view = keys.object(lab["partner_view"], "partner_view")
    at = keys.within("partner_view")
    jitter = (
        {}
        if "jitter_s" not in view
        else {
            "jitter_s": at.number(view, "jitter_s"),
            "jitter_distribution": at.text(view, "jitter_distribution"),
        }
    )
    return (
        {"handling": at.text(view, "handling")}
        | {key: _optional_number(at, view, key) for key in ("lag_s", "horizon_s")}
        | jitter
    )


def _panel(keys: _Keys, value: object) -> dict[str, dict[str, str]]:
    """Read the people's panel identifiers: text values, by label and identifier."""
    people = keys.object(value, "panel")
    return {str(label): _texts(keys, ids, f"panel.{label}") for label, ids in people.items()}


def _texts(keys: _Keys, value: object, key: str) -> dict[str, str]:
    """Read an object of texts at ``key``."""
    texts = keys.object(value, key)
    if not all(isinstance(text, str) for text in texts.values()):
        raise keys.error(key, "holds a value that is not a text")
    return {str(name): str(text) for name, text in texts.items()}


def _perturbation(keys: _Keys, value: object) -> PerturbationRecord:
    change = keys.object(value)
    return PerturbationRecord(
        sample=keys.count(change, "sample"),
        time_s=keys.number(change, "time_s"),
        player=keys.text(change, "player"),
        change=keys.text(change, "change", empty=True),
    )


@dataclass(frozen=True)
class AnswerRecord:
    """One answer a person gave after a trial: the question, its text and kind, the value."""

    label: str
    question: str
    text: str
    kind: str
    value: object
    after: str
    utc: str | None


@dataclass(frozen=True)
class AnswersRecord:
    """The answers given after a trial (``trial-NN_answers.json``), in the order asked."""

    trial: int
    block: str
    condition: str
    answers: tuple[AnswerRecord, ...]

    def of(self, label: str) -> tuple[AnswerRecord, ...]:
        """Return the answers ``label`` gave."""
        return tuple(answer for answer in self.answers if answer.label == label)


def read_answers_record(path: str | Path) -> AnswersRecord:
    """Read the answers given after a trial; questions in the order asked (trial's, block's).

    Raises
    ------
    InputError
        A file that is not a JSON object with an ``answers`` object, or whose keys have the
        wrong types (the error names the file and the key).
    """
    path = Path(path)
    keys = _Keys(path, "")
    recorded = keys.object(parse_json(read_sidecar_text(path), path))
    given = recorded.get("answers")
    if not isinstance(given, dict):
        raise InputError(path, "not the answers of a trial (no 'answers' object)")
    after_trial = [str(q) for q in recorded.get("after_trial", []) or []]
    after_block = [str(q) for q in recorded.get("after_block", []) or []]
    questions = keys.object(recorded.get("questions", {}), "questions")
    answers = []
    for label, by_question in given.items():
        mine = keys.within(f"answers.{label}").object(by_question)
        for qid in dict.fromkeys([*after_trial, *after_block, *mine]):
            answer = mine.get(qid)
            if not isinstance(answer, dict):
                continue
            question = questions.get(qid, {})
            question = question if isinstance(question, dict) else {}
            utc = answer.get("utc")
            answers.append(AnswerRecord(
                label=str(label), question=str(qid), text=str(question.get("text", "")),
                kind=str(question.get("kind", "")), value=answer.get("value"),
                after="trial" if qid in after_trial else "block",
                utc=utc if isinstance(utc, str) else None,
            ))  # fmt: skip
    return AnswersRecord(
        trial=keys.count(recorded, "trial"),
        block=str(recorded.get("block", "")),
        condition=str(recorded.get("condition", "")),
        answers=tuple(answers),
    )


@dataclass(frozen=True)
class _Keys:
    """Checks of a JSON object's keys whose errors name the file and the key's path."""

    path: Path
    prefix: str

    def within(self, key: str) -> _Keys:
        return _Keys(self.path, f"{self.prefix}.{key}" if self.prefix else key)

    def error(self, key: str, problem: str) -> InputError:
        return InputError(self.path, f"{self.within(key).prefix}: {problem}")

    def object(self, value: object, key: str = "") -> dict[str, Any]:
        if not isinstance(value, dict):
            where = self.within(key).prefix if key else self.prefix or "the file"
            raise InputError(self.path, f"{where}: not a JSON object")
        return value

    def text(self, obj: dict[str, Any], key: str, empty: bool = False) -> str:
        value = obj.get(key)
        if not isinstance(value, str) or not (value or empty):
            raise self.error(key, f"{value!r} is not a text")
        return value

    def optional_text(self, obj: dict[str, Any], key: str) -> str | None:
        value = obj.get(key)
        if value is not None and not isinstance(value, str):
            raise self.error(key, f"{value!r} is not a text")
        return value

    def count(self, obj: dict[str, Any], key: str) -> int:
        value = obj.get(key)
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise self.error(key, f"{value!r} is not a whole number (0 or more)")
        return value

    def number(self, obj: dict[str, Any], key: str) -> float:
        value = obj.get(key)
        if not _is_number(value):
            raise self.error(key, f"{value!r} is not a finite number")
        return value  # type: ignore[return-value]


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
