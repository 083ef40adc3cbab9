"""How a pilot's virtual participants answer questions: by rule, person or computer at a rate.

A rule (`AnswerRule`) is given per question id (``lab pilot --answer QUESTION=RULE``):
``random`` (an option, a point or ``"pilot"``, drawn from the stand-in's seed), ``first`` (the
first option, point 1, ``"pilot"``), ``value:TEXT`` (TEXT itself, which must answer the
question), or ``detect:P`` for a person-or-computer question
(`mirror_avatar.lab.design.guesses.asks_identification`): the stand-in names the partners'
true kind of motion (`right_guesses`, from the protocol's schedule, which the stand-in's page
never sees) with probability P and the other kind otherwise, so that an identification study
can be piloted, and powered, with a set detection rate (docs/METHODS.md, section 15).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.guesses import MOTION_OF, asks_identification, guess_of, motion_kind
from mirror_avatar.lab.design.protocol import Protocol

RULES = ("random", "first", "value", "detect")
"""The kinds of rule."""

KINDS = ("person", "avatar")
"""The two guesses a person-or-computer answer makes."""


@dataclass(frozen=True)
class AnswerRule:
    """How a virtual participant answers a question (see the module docstring).

    ``kind`` is one of `RULES`; ``value`` the answer's text (``value``) or the detection rate
    (``detect``, in [0, 1]).
    """

    kind: str = "random"
    value: str = ""

    @classmethod
    def parse(cls, text: str) -> AnswerRule:
        """Read ``random``, ``first``, ``value:TEXT`` or ``detect:P``."""
        kind, _, value = text.partition(":")
        valued = kind in ("value", "detect")
        if kind not in RULES or valued != bool(value) or (kind == "detect" and not _rate(value)):
            raise InputError(
                "--answer",
                f"{text!r} is not a rule: give random, first, value:TEXT or detect:P (P from 0 "
                "to 1)",
            )
        return cls(kind, value)

    def answer(
        self, question: Mapping[str, Any], rng: np.random.Generator, right: str | None = None
    ) -> str | int:
        """Return the answer to ``question`` (as a page shows it: kind, options, points).

        ``right``: the right guess about the trial's partners (``person`` or ``avatar``; None
        when they are of both kinds), which ``detect`` names with its probability.
        """
        kind = question["kind"]
        if self.kind == "value":
            return int(self.value) if kind == "likert" and self.value.isdigit() else self.value
        if kind == "choice":
            options = list(question["options"])
            if self.kind == "detect":
                return detected(options, float(self.value), right, rng)
            return options[0] if self.kind == "first" else options[rng.integers(len(options))]
        if kind == "likert":
            return 1 if self.kind == "first" else int(rng.integers(1, int(question["points"]) + 1))
        return "pilot"


def _rate(text: str) -> bool:
    try:
        return 0.0 <= float(text) <= 1.0
    except ValueError:
        return False


def detected(options: list[str], rate: float, right: str | None, rng: np.random.Generator) -> str:
    """Return the option naming ``right`` with probability ``rate``, else the other kind's.

    One uniform draw decides; with ``right`` None (partners of both kinds) an option is drawn
    at random.
    """
    naming = {guess_of(option): option for option in options}
    if right is None:
        return options[rng.integers(len(options))]
    other = KINDS[1 - KINDS.index(right)]
    return naming[right] if rng.random() < rate else naming[other]


def check_rules(protocol: Protocol, rules: Mapping[str, AnswerRule]) -> None:
    """Refuse a ``detect`` rule for a question that is not a person-or-computer choice.

    Raises
    ------
    InputError
        ``--answer: ID=detect:P: ...`` naming the question and what it lacks.
    """
    for qid, rule in rules.items():
        if rule.kind != "detect":
            continue
        question = protocol.questions.get(qid)
        said = f"{qid}=detect:{rule.value}"
        if question is None:
            raise InputError("--answer", f"{said}: the protocol asks no question {qid!r}")
        kinds = {guess_of(option) for option in question.options}
        if not asks_identification(question.text, question.kind) or not set(KINDS) <= kinds:
            raise InputError(
                "--answer",
                f"{said}: question {qid!r} is not a person-or-computer choice whose options "
                "name a person and a computer (give random, first or value:TEXT)",
            )


def right_guesses(protocol: Protocol, participant: int, label: str) -> dict[int, str | None]:
    """Return the right guess about person ``label``'s partners in each of their trials.

    Keys are the run's trial numbers (from 1, as the server numbers them); a value is
    ``person`` or ``avatar`` (`mirror_avatar.lab.design.guesses.MOTION_OF` of the partners'
    kinds, a recording being a person's motion), or None when the partners the person sees
    are of both kinds or the person does not play. The partners are those of the condition's
    plan as participant ``participant``'s schedule fills its person-or-avatar slots.
    """
    right: dict[int, str | None] = {}
    for step in protocol.schedule(participant):
        plan = protocol.blocks[step.block].conditions[step.condition].plan(step.persons, 0)
        labels = [slot.label for slot in plan.slots]
        kinds: set[str] = set()
        if label in labels:
            seen = plan.neighbours(labels.index(label))
            kinds = {MOTION_OF[motion_kind(plan.slots[j].kind, plan.slots[j].spec)] for j in seen}
        guess = next(iter(kinds)) if len(kinds) == 1 else None
        right |= {len(right) + 1 + t: guess for t in range(plan.trials)}
    return right
