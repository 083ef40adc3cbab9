"""The person-or-computer question: which answer guesses the partner's kind, and how surely.

A protocol asks it as a choice question (``kind = "choice"``) whose text names both a person and
a machine ("Was your partner a person or a computer?"); the answer's words say the guess
(`PERSON_WORDS`, `MACHINE_WORDS`). Its confidence is the Likert question asked with it whose id
or text speaks of confidence ("How confident are you?"). A guess is right when it names whose
motion the partners showed (`MOTION_OF`): a person's recorded trial replayed is a person's. Both
rules read only what every copy
of the answers keeps (the question's text and kind and the answer), so run folders and BIDS
``_beh.tsv`` files give the same guesses.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from mirror_avatar.files.trial_record import KIND_NAMES, AnswerRecord
from mirror_avatar.specs import replays_recording

PERSON_WORDS = frozenset({"person", "human", "people", "someone", "somebody", "participant"})
"""Words of an answer or a question naming a person."""

MACHINE_WORDS = frozenset(
    {"computer", "avatar", "machine", "robot", "program", "algorithm", "bot", "ai", "agent"}
)
"""Words of an answer or a question naming a computer player."""

MOTION_OF = {"person": "person", "recording": "person", "avatar": "avatar"}
"""The right guess about partners of each kind (`motion_kind`).

**Choice**: a recording replayed is a person's motion, so "a person" is right about it, as in a
Turing test of motion; the lab cannot tell a recording of a person from one of a computer
player, so replay only people's recordings where answers are scored.
"""


def _words(text: str) -> set[str]:
    return set(re.findall(r"[a-z]+", text.lower()))


def asks_identification(text: str, kind: str) -> bool:
    """Whether a question of ``text`` and ``kind`` asks person or computer (module docstring)."""
    words = _words(text)
    return kind == "choice" and bool(words & PERSON_WORDS) and bool(words & MACHINE_WORDS)


def is_identification(answer: AnswerRecord) -> bool:
    """Whether ``answer`` answers a person-or-computer question (`asks_identification`)."""
    return asks_identification(answer.text, answer.kind)


def motion_kind(kind: str, spec: str | None) -> str:
    """Name a slot's kind as the study's tables do: ``person``, ``avatar`` or ``recording``.

    ``kind``: the slot's (``human`` or ``avatar``); ``spec``: its avatar's SPEC. **Choice**: an
    avatar slot that replays a recorded trial file (`mirror_avatar.specs.replays_recording`) is
    a ``recording``, a person's motion that nobody plays live; a person-or-computer guess about
    it is right when it says a person (`MOTION_OF`).
    """
    if spec is not None and kind == "avatar" and replays_recording(spec):
        return "recording"
    return KIND_NAMES[kind]


def guess_of(value: object) -> str | None:
    """Return ``"person"`` or ``"avatar"`` as an answer's words say, None when they do not."""
    words = _words(value) if isinstance(value, str) else set()
    person, machine = bool(words & PERSON_WORDS), bool(words & MACHINE_WORDS)
    if person == machine:
        return None
    return "person" if person else "avatar"


def guess(answers: Iterable[AnswerRecord]) -> tuple[str | None, float] | None:
    """Return a person's guess of their partner's kind and its confidence, None if not asked.

    The confidence is the Likert point of the confidence question (NaN when none was asked).
    """
    given = list(answers)
    asked = next((a for a in given if is_identification(a)), None)
    if asked is None:
        return None
    points = [a for a in given if a.kind == "likert" and isinstance(a.value, int)]
    confidence = next(
        (float(a.value) for a in points if "confiden" in f"{a.question} {a.text}".lower()),  # type: ignore[arg-type]
        float("nan"),
    )
    return guess_of(asked.value), confidence
