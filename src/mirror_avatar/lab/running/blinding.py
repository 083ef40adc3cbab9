"""Double blind: what the console sees of a participant's run whose partner kinds are hidden.

A protocol with ``blind = "double"`` hides from the researcher's console and its API, until the
run is exported, whether a person or the avatar fills each ``person-or-avatar`` slot. Such a
label (`hidden_labels`) is hidden everywhere in the run, also in conditions where the same label
is a plain person, since the difference would tell. `blind_status` rewrites a run's status
(`mirror_avatar.lab.running.study.ParticipantRun.status`): what only a person's slot has (its
connection, round trips, inputs held and lost, answers, a drop) or only an avatar's (its spec, the
policy it plays, a perturbation) is left out for those labels, their kind reads ``"hidden"``, and
events naming them are left out; which pages are connected is said for every person of the protocol,
whether they play now or not. The files on disk keep the truth, and the export writes it.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any

from mirror_avatar.lab.design.protocol import Protocol
from mirror_avatar.lab.running.runner import LabSession
from mirror_avatar.lab.running.study import ParticipantRun

HIDDEN = "hidden"
"""The kind the console is told of a hidden slot."""

HIDDEN_TEXT = "hidden until export"
"""What the console is told in place of a text naming a hidden label."""

SLOT_KEYS = ("index", "label", "role", "colour")
"""What the console is told of a hidden slot, besides its kind."""

PER_LABEL = ("held", "lost", "dropped", "answers")
"""A trial row's tables by label (a person's only), without the hidden labels."""


def hidden_labels(protocol: Protocol) -> frozenset[str]:
    """Return the labels whose kind the console must not see (none unless double blind)."""
    if protocol.blind != "double":
        return frozenset()
    return frozenset(
        player.label
        for block in protocol.blocks
        for condition in block.conditions
        for player in condition.players
        if player.kind == "person-or-avatar"
    )


def hidden_of(session: LabSession) -> frozenset[str]:
    """Return the labels whose kind the console must not see in a session (`hidden_labels`)."""
    schedule = session.schedule
    return hidden_labels(schedule.protocol) if isinstance(schedule, ParticipantRun) else frozenset()


def unjoined(session: LabSession) -> str | None:
    """Say whose page has not joined, of every person of a double-blind run, or None.

    Every person's page must be there, not only those playing now: naming only the latter
    would tell who fills a hidden slot.
    """
    missing = [person.label for person in session.everyone() if not person.connected]
    return f"not joined yet: {', '.join(missing)} (start anyway with force)" if missing else None


def console_status(session: LabSession, status: dict[str, Any]) -> dict[str, Any]:
    """Return a session's status as the console may see it: blinded for a double-blind run."""
    hidden = hidden_of(session)
    if not hidden:
        return status
    pages = {person.label: person.connected for person in session.everyone()}
    return blind_status(status, hidden, pages)


def blind_status(
    status: dict[str, Any], hidden: frozenset[str], pages: dict[str, bool]
) -> dict[str, Any]:
    """Return a run's status without anything telling the kind of a hidden label.

    Parameters
    ----------
    status
        The run's status, with its links.
    hidden
        The hidden labels (`hidden_labels`).
    pages
        Per person of the protocol, whether their page is connected.
    """
    names = re.compile(r"\b(" + "|".join(map(re.escape, sorted(hidden))) + r")\b")

    def told(text: str | None) -> str | None:
        return HIDDEN_TEXT if text is not None and names.search(text) else text

    slots = [
        {key: slot[key] for key in SLOT_KEYS} | {"kind": HIDDEN}
        if slot["label"] in hidden
        else slot
        for slot in status["slots"]
    ]
    plan = status["plan"] | {
        "slots": [
            {"label": slot["label"], "kind": HIDDEN} if slot["label"] in hidden else slot
            for slot in status["plan"]["slots"]
        ]
    }
    trials = [_blind_row(row, hidden, told) for row in status["trials"]]
    study = status["study"] | {
        "waiting": _without(status["study"]["waiting"], hidden),
        "unanswered": _drop(status["study"]["unanswered"], hidden),
        "pages": pages,
        "blind": "double",
    }
    return status | {
        "plan": plan,
        "slots": slots,
        "trials": trials,
        "study": study,
        "events": [event for event in status["events"] if not names.search(event)],
        "error": told(status["error"]),
    }


def _blind_row(row: dict[str, Any], hidden: frozenset[str], told: Any) -> dict[str, Any]:
    """Return a trial's row with the hidden labels' kinds and person-only tables left out."""
    partners = {
        label: HIDDEN if label in hidden else kind for label, kind in row["partners"].items()
    }
    return (
        row
        | {key: _drop(row[key], hidden) for key in PER_LABEL}
        | {"partners": partners, "end_reason": told(row["end_reason"]), "files": []}
    )


def _drop(table: dict[str, Any], hidden: frozenset[str]) -> dict[str, Any]:
    return {label: value for label, value in table.items() if label not in hidden}


def _without(labels: Iterable[str], hidden: frozenset[str]) -> list[str]:
    return [label for label in labels if label not in hidden]
